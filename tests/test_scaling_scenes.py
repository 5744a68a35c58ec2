"""tlm scaling: a scene is told by its file, not its name; points without a steady state are
named; a fit says what it was made from, and the report says when its sweep holds other
points since."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.scaling import fit, record
from tlm.report.collect import read
from tlm.report.scaling import scaling_section
from tlm.scenes.loader import scenes_dir


def _config(n: int, scene: str = "cornell") -> dict:
    return {"scene": scene, "mode": "rcast", "seed": 0, "resolution": [16, 16], "render": {"batch": 4},
            "arch": {"pipelines": n, "scheduler": "static", "frames": 5}}


def _results(n: int, source: Path, name: str = "cornell", steady: bool | None = True, work: int = 12000) -> dict:
    """A point's results.json, as much of it as eq. 5.2 reads: the work splits over N pipelines."""
    per = {"traversal": 9000 // n, "intersection": work // n, "fragment": 3000 // n}
    estimate = {} if steady is None else (
        {"steady": True, "frames": 5} if steady else {"steady": False, "frames": 2, "min_frames": 5})
    return {"scene": {"name": name, "source": str(source)},
            "timing": {"pipelines": [per] * n, "throughput_estimate": estimate},
            "cycles": {**per, "vertex": 1000, "latency": 2000 + work // n, "throughput": 1000 + work // n}}


def fake_sweep(folder: Path, points: list[tuple[int, dict, str]], salt: str = "") -> Path:
    """A sweep folder of finished points (N, results.json, the config's scene), without rendering."""
    (folder / "points").mkdir(parents=True, exist_ok=True)
    spec = {"tlm": "sweep/1", "grid": {"arch.pipelines": sorted({n for n, _, _ in points})}, "points": []}
    rows = []
    for i, (n, res, scene) in enumerate(points):
        h = salt + f"{i:016x}"[len(salt):]
        spec["points"].append({"point": i, "hash": h, "factors": {"arch.pipelines": n}})
        rows.append({"point": i, "hash": h, "status": "ok", "error": None, "arch.pipelines": n,
                     "throughput_steady": (res["timing"]["throughput_estimate"] or {}).get("steady")})
        (folder / "points" / h).mkdir()
        (folder / "points" / h / "results.json").write_text(json.dumps({**res, "factors": {"arch.pipelines": n}}))
        (folder / "points" / h / "config.resolved.yaml").write_text(yaml.safe_dump(_config(n, scene)))
    (folder / "sweep.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


BUILTIN = scenes_dir() / "cornell.yaml"


def _mk(folder: Path) -> Path:
    folder.mkdir()
    return folder


def _modified_copy(tmp_path: Path) -> Path:
    """A user's copy of cornell.yaml with one material changed: the same name, another scene."""
    (tmp_path / "mine").mkdir(exist_ok=True)
    copy = tmp_path / "mine" / "cornell.yaml"
    copy.write_text(BUILTIN.read_text().replace("chrome: {type: mirror, reflectance: [0.9, 0.9, 0.9]}",
                                                "chrome: {type: lambertian, albedo: [0.5, 0.5, 0.5]}"))
    assert copy.read_text() != BUILTIN.read_text()
    return copy


# ------------------------------------------------------------------ a scene is its file


def test_two_scene_files_of_one_name_are_fitted_apart_and_named_by_their_files(tmp_path, capsys):
    """A sweep over the built-in cornell and a modified copy of it (both named 'cornell') was
    refused ('the same N ... differ in another key'); now each file is a group of its own,
    named distinctly in the printout, eq52.json, eq52.csv and the figures' files. A copy with
    the built-in's bytes, elsewhere, is the built-in scene: its point joins that group."""
    copy = _modified_copy(tmp_path)
    same = tmp_path / "elsewhere" / "cornell.yaml"
    same.parent.mkdir()
    shutil.copy(BUILTIN, same)
    sw = fake_sweep(tmp_path / "sw", [
        *((n, _results(n, BUILTIN), "cornell") for n in (1, 2, 4)),
        *((n, _results(n, copy, work=20000), "mine/cornell.yaml") for n in (1, 2, 4)),
        (8, _results(8, same), "elsewhere/cornell.yaml")])
    assert main(["scaling", str(sw), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    out = capsys.readouterr().out
    mine = "mine/cornell.yaml"  # (the copy by the path its config gave, as the report names it)
    assert f"  {mine} rcast" in out and f"  {'cornell':{len(mine)}s} rcast" in out  # (one column: the longest)
    meta = json.loads((tmp_path / "eq" / "eq52.json").read_text())
    got = {(f["scene"], f["target"]): (f["scene_file"], f["pipelines"]) for f in meta["fits"]}
    assert got[("cornell", "throughput")] == (str(BUILTIN), [1, 2, 4, 8])
    assert got[(mine, "throughput")] == (str(copy), [1, 2, 4])
    with open(tmp_path / "eq" / "eq52.csv") as fh:
        assert {r["scene"] for r in csv.DictReader(fh)} == {"cornell", mine}
    pngs = sorted(p.name for p in (tmp_path / "eq").glob("scaling_*.png"))
    assert len(pngs) == 2 and "scaling_cornell.png" in pngs


def test_two_different_scenes_of_one_name_are_not_mixed_in_one_fit(tmp_path):
    """N = 1, 2 of the built-in cornell and N = 4, 8 of a modified copy: one fit over N = 1 to 8
    before (the copy's points read as the built-in's); now two groups, and the copy's cannot
    be fitted (no N = 1), the error naming it."""
    copy = _modified_copy(tmp_path)
    recs = [{**record(_results(n, BUILTIN), _config(n)), "sweep": "runs/a"} for n in (1, 2)]
    recs += [{**record(_results(n, copy, work=20000), _config(n, "mine/cornell.yaml")), "sweep": "runs/b"}
             for n in (4, 8)]
    with pytest.raises(InputError, match=r"fitted through N = 1, and the group has N = 4, 8$") as e:
        fit(recs)
    assert str(e.value).startswith("runs/b (mine/cornell.yaml: rcast/static): arch.pipelines: ")
    assert set(fit(recs[:2])) == {("cornell", "rcast", "static", t) for t in ("latency", "throughput")}


def test_the_builtin_ring_and_thesis_ring_are_two_scenes_by_their_builtin_names(tmp_path):
    """Both files are named 'ring': their groups are named by the files as a user names a
    built-in scene ('ring', 'thesis/ring')."""
    ring, thesis_ring = scenes_dir() / "ring.yaml", scenes_dir() / "thesis" / "ring.yaml"
    recs = [{**record(_results(n, src, name="ring"), _config(n, scene)), "sweep": "sw"}
            for src, scene in ((ring, "ring"), (thesis_ring, "thesis/ring")) for n in (1, 2)]
    assert {k[0] for k in fit(recs)} == {"ring", "thesis/ring"}


# ------------------------------------------------------------------ points without a steady state


def test_a_point_without_a_steady_state_is_named_printed_kept_and_reported(tmp_path, capsys):
    sw = fake_sweep(tmp_path / "sw", [(1, _results(1, BUILTIN), "cornell"),
                                      (2, _results(2, BUILTIN, steady=False), "cornell"),
                                      (4, _results(4, BUILTIN, steady=None), "cornell")])  # (None: not recorded)
    assert main(["scaling", str(sw), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    note = (f"{sw}: point 1 (arch.pipelines = 2): its stream of 2 frames was too short for a steady state "
            "(throughput_steady false; a steady window needs at least 5 frames): its TThru and latency are "
            "measured over the whole stream, fill and drain included, and the fit reads them as the steady "
            "state's (raise arch.frames)")
    assert err == [f"tlm: note: {note}"]
    meta = json.loads((tmp_path / "eq" / "eq52.json").read_text())
    assert meta["notes"] == [note]
    assert {tuple(f["pipelines"]) for f in meta["fits"]} == {(1, 2, 4)}  # (kept in the fit)
    notes = scaling_section(read([tmp_path / "eq"]), tmp_path).notes
    assert f"eq: {note}" in notes
    # a sweep over N given to the report is fitted there: the same note
    notes = scaling_section(read([sw]), tmp_path).notes
    assert any(n.startswith("sw #1 (arch.pipelines = 2): its stream of 2 frames was too short") for n in notes), notes


# ------------------------------------------------------------------ what a fit was made from


def test_a_fit_of_a_sweep_run_again_with_other_points_is_out_of_date_in_the_report(tmp_path):
    sw = fake_sweep(tmp_path / "sw", [(n, _results(n, BUILTIN), "cornell") for n in (1, 2, 4)])
    assert main(["scaling", str(sw), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    meta = json.loads((tmp_path / "eq" / "eq52.json").read_text())
    hashes = [f"{i:016x}" for i in range(3)]
    assert meta["fitted_from"] == [{"sweep": "../sw", "planned": hashes, "points": hashes}]
    sec = scaling_section(read([tmp_path / "eq"]), _mk(tmp_path / "r1"))
    assert not any("out of date" in n for n in sec.notes)
    assert not any("out of date" in f.title for f in sec.figures)
    shutil.rmtree(sw)  # the sweep run again into its folder with another base: other points
    fake_sweep(sw, [(n, _results(n, BUILTIN, work=30000), "cornell") for n in (1, 2, 4)], salt="b")
    sec = scaling_section(read([tmp_path / "eq"]), _mk(tmp_path / "r2"))
    (note,) = [n for n in sec.notes if "out of date" in n]
    assert note.startswith(f"eq: out of date: its sweep {sw} now holds other points than it was fitted from (3 of "
                           "its 3 points are new")
    assert all(f.title.endswith("(out of date)") and f.caption.startswith("Out of date") for f in sec.figures)


def test_points_finished_after_the_fit_make_it_out_of_date(tmp_path):
    sw = fake_sweep(tmp_path / "sw", [(n, _results(n, BUILTIN), "cornell") for n in (1, 2, 4)])
    rows = (sw / "sweep.jsonl").read_text().splitlines(keepends=True)
    (sw / "sweep.jsonl").write_text("".join(rows[:2]))  # interrupted: N = 4 not run yet
    assert main(["scaling", str(sw), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    assert scaling_section(read([tmp_path / "eq"]), _mk(tmp_path / "r1")).figures  # (its own notes say it is partial)
    (sw / "sweep.jsonl").write_text("".join(rows))  # the same command finished it
    notes = scaling_section(read([tmp_path / "eq"]), _mk(tmp_path / "r2")).notes
    assert f"eq: out of date: its sweep {sw} has other finished points than it was fitted from (1 finished since); " \
           "run 'tlm scaling' again to fit the sweep as it is" in notes


def test_a_fit_that_does_not_record_its_points_says_so(tmp_path):
    sw = fake_sweep(tmp_path / "sw", [(n, _results(n, BUILTIN), "cornell") for n in (1, 2)])
    assert main(["scaling", str(sw), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    path = tmp_path / "eq" / "eq52.json"
    meta = json.loads(path.read_text())
    path.write_text(json.dumps({k: v for k, v in meta.items() if k != "fitted_from"}))  # (an older tlm's)
    notes = scaling_section(read([tmp_path / "eq"]), _mk(tmp_path / "r")).notes
    assert any("does not record which points it was fitted from" in n for n in notes), notes
    path.write_text(json.dumps({**meta, "fitted_from": [{"sweep": "../sw", "planned": [3], "points": []}]}))
    with pytest.raises(InputError, match=r"eq52\.json: fitted_from\[0\]: 'planned' is \[3\], not a list of texts"):
        read([tmp_path / "eq"])
