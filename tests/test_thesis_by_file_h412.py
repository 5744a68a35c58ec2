"""h412: ``tlm thesis`` and ``tlm calibrate`` tell a thesis scene by its file, as the report does (h389).

They chose a scene's table by its file's stem: a user's ``room.yaml`` was printed beside Table II's
numbers (marked not comparable), an unchanged copy ``myring.yaml`` of ``thesis/ring`` had no table
(``tlm calibrate`` refused it; the report, which tables a study's scene by the name in its file, then
left it out too), and two scenes of one stem (``a/x.yaml``, ``b/x.yaml``; the built-in ``ring`` beside
``thesis/ring``) were refused. Now a scene's table is its file's (:func:`tlm.experiments.thesis.scene_keys`):
a copy is that table's, its rows named by the table; a scene of no table has no thesis value in its
rows and says so, one named as a table's saying which it is not; two of one stem are two rows.
"""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.thesis import THESIS, calibrate, load_study, scene_keys
from tlm.report.collect import read
from tlm.report.tables import collect_sources
from tlm.scenes.loader import scenes_dir

TINY = {"seed": 0, "resolution": [8, 8], "render": {"light_samples": 1, "spp": 1}, "photons": {"count": 500},
        "arch": {"trace": False}}


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    """A user's scenes: proj/room.yaml (the thesis's room with its light moved), myring.yaml (the thesis's
    ring, byte for byte), bunny.yaml (no table), a/x.yaml and b/x.yaml (one stem, two scenes)."""
    root = scenes_dir()
    for sub in ("proj", "a", "b"):
        (tmp_path / sub).mkdir()
    room = (root / "thesis" / "room.yaml").read_text(encoding="utf-8")
    moved = room.replace("extends: ../room.yaml", f"extends: {root / 'room.yaml'}").replace(
        "corner: [2.2, 2.599, 3.3]", "corner: [2.25, 2.599, 3.3]")
    assert moved.count("2.25, 2.599") == 1 and str(root) in moved
    (tmp_path / "proj" / "room.yaml").write_text(moved, encoding="utf-8")
    shutil.copy(root / "thesis" / "ring.yaml", tmp_path / "myring.yaml")
    ring = (root / "ring.yaml").read_text(encoding="utf-8")
    (tmp_path / "bunny.yaml").write_text(ring.replace("name: ring", "name: bunny"), encoding="utf-8")
    (tmp_path / "a" / "x.yaml").write_text(ring.replace("name: ring", "name: xa"), encoding="utf-8")
    (tmp_path / "b" / "x.yaml").write_text(ring.replace("name: ring", "name: xb"), encoding="utf-8")
    return tmp_path


def _study(folder: Path, scenes: list[str], modes=("rcast",)) -> Path:
    path = folder / "study.yaml"
    path.write_text(yaml.safe_dump({"base": TINY, "scenes": scenes, "modes": list(modes)}), encoding="utf-8")
    return path


def _thesis(folder: Path, scenes: list[str], capsys) -> tuple[Path, list[dict], dict, str]:
    out = folder / "out"
    assert main(["thesis", str(_study(folder, scenes)), "--out", str(out), "--no-progress", "--no-report"]) == 0
    with open(out / "thesis_comparison.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    return out, rows, json.loads((out / "thesis_summary.json").read_text()), capsys.readouterr().out


def test_the_keys_of_a_study_s_scenes(folder):
    """Its table where its file is a table's scene, else its stem, a number added where that is taken."""
    keys = scene_keys(["ring", "thesis/ring", "a/x.yaml", "b/x.yaml", "proj/room.yaml"], folder,
                      str(folder / "study.yaml"))
    assert keys == {"ring": ("ring-2", None), "thesis/ring": ("ring", "ring"), "a/x.yaml": ("x", None),
                    "b/x.yaml": ("x-2", None), "proj/room.yaml": ("room", None)}


def test_a_copy_of_the_thesis_s_ring_under_another_name_is_table_i(folder, capsys, cache):
    out, rows, summary, printed = _thesis(folder, ["myring.yaml"], capsys)
    assert {r["scene"] for r in rows} == {"ring"} and (out / "ring" / "rcast" / "results.json").is_file()
    by_metric = {r["metric"]: r for r in rows}
    assert float(by_metric["TTrav"]["thesis"]) == THESIS["ring"]["TTrav"][0]
    assert by_metric["TTrav"]["comparable"] == "False" and "the scene" not in by_metric["TTrav"]["not_comparable"]
    assert summary["scenes"] == {"ring": "myring.yaml"} and summary["no_table"] == {}
    assert not any("the scene" in w for w in summary["not_comparable"]["ring"])
    assert any(line.startswith("myring.yaml rcast") and "( 0.378)" in line for line in printed.splitlines())
    # the report of the study tables it under Table I too, its cells behind it
    notes: list[str] = []
    sources = collect_sources(read([out]), notes)
    assert set(sources) == {"ring"} and sources["ring"][0].runs, notes
    assert not any("no table" in n for n in notes), notes


def test_a_users_room_is_not_set_beside_table_ii(folder, capsys, cache):
    out, rows, summary, printed = _thesis(folder, ["proj/room.yaml", "thesis/ring"], capsys)
    mine = [r for r in rows if r["scene"] == "room"]
    assert len(mine) == 6 and all(r["thesis"] == "" and r["rel_error"] == "" for r in mine)
    assert all(r["comparable"] == "False" and r["not_comparable"].startswith(
        f"the scene {folder / 'proj' / 'room.yaml'} (the thesis's is thesis/room)") for r in mine)
    assert summary["not_comparable"]["room"][0].startswith("the scene ")
    assert summary["no_table"] == {"room": "proj/room.yaml has no table in the thesis (not the thesis's room "
                                           "scene, thesis/room: told by its file): its rows have no thesis value"}
    assert summary["no_table"]["room"] in printed.splitlines()
    assert "proj/room.yaml is the scene " in summary["median_withheld"]  # (the printed median line too)
    notes: list[str] = []
    assert set(collect_sources(read([out]), notes)) == {"ring"}
    assert any("has no table in the thesis (not the thesis's Room scene, thesis/room)" in n for n in notes), notes


def test_a_scene_without_a_table_says_so(folder, capsys, cache):
    _, rows, summary, printed = _thesis(folder, ["bunny.yaml"], capsys)
    assert all(r["thesis"] == "" and r["comparable"] == "" for r in rows)
    assert "bunny.yaml has no table in the thesis: its rows have no thesis value" in printed.splitlines()
    assert summary["not_comparable"] == {} and summary["median_abs_rel_error_held_out"] is None


def test_two_scenes_of_one_stem_are_two_rows(folder, capsys, cache):
    out, rows, summary, _ = _thesis(folder, ["a/x.yaml", "b/x.yaml"], capsys)
    assert [r["scene"] for r in rows] == ["x"] * 6 + ["x-2"] * 6
    assert summary["scenes"] == {"x": "a/x.yaml", "x-2": "b/x.yaml"}
    sources = {json.loads((out / k / "rcast" / "results.json").read_text())["scene"]["source"] for k in ("x", "x-2")}
    assert sources == {str(folder / "a" / "x.yaml"), str(folder / "b" / "x.yaml")}


def test_a_copy_beside_the_thesis_s_own_file_is_refused(folder):
    with pytest.raises(InputError) as err:
        load_study(_study(folder, ["myring.yaml", "thesis/ring"]))
    assert ("scenes: 'myring.yaml' and 'thesis/ring' are both the thesis's ring scene (by the bytes of their "
            "files): list one of them") in str(err.value)


def test_calibrate_fits_no_table_to_a_users_room(folder):
    with pytest.raises(InputError) as err:
        calibrate(_study(folder, ["proj/room.yaml", "thesis/ring"]))
    assert ("['proj/room.yaml'] have no thesis table to calibrate against (a scene is a table's by its file, not "
            "its name: 'proj/room.yaml' is not the thesis's room scene, thesis/room)") in str(err.value)


def test_calibrate_fits_a_copy_of_the_thesis_s_ring_to_table_i(folder, cache):
    _, report = calibrate(_study(folder, ["myring.yaml", "cornell"]), iterations=1)
    assert set(report["cells"]) == {"ring", "cornell"}
    assert report["cells"]["ring"]["TTrav"]["thesis"] == THESIS["ring"]["TTrav"][0]
    assert not any(w.startswith("the scene ") for ws in report["not_comparable"].values() for w in ws)
