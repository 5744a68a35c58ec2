"""h317: the OBJ reader's fast path refuses a malformed number as the per-line reader does (it blanked the
statement's letter everywhere in a block: ``f 1 2 3f4`` read a quad, ``v -1.01v0.5 0 1`` three numbers; and
``int()`` read ``3_0`` as 30); a sweep's (a granularity study's) ``base:`` takes a scene file as ``tlm run``
does, ``{scene: FILE}``, with its note; ``tlm sweep`` says its points' warnings after its summary line, each
with how many points recorded it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tlm.cli import main
from tlm.cli_tables import POINT_WARNINGS_SHOWN, print_point_warnings
from tlm.errors import InputError
from tlm.experiments.granularity import load_granularity
from tlm.scenes.objfile import parse_obj

ROOT = Path(__file__).resolve().parents[1]
BOX = ROOT / "scenes" / "meshes" / "CornellBox-Original.obj"


@pytest.mark.parametrize(("extra", "said"), [
    ("f 1 2 3f4", "cannot read the face corner '3f4' (indices are integers)"),
    ("f 1 2 3f", "cannot read the face corner '3f' (indices are integers)"),
    ("f 1 2 3_0", "cannot read the face corner '3_0' (indices are integers)"),
    ("f 1 2 3 -", "cannot read the face corner '-' (indices are integers)"),
    ("v -1.01v0.5 0.00 0.99", "cannot read '-1.01v0.5' as a number in a 'v' statement"),
    ("v 1_0 2 3", "cannot read '1_0' as a number in a 'v' statement"),
])
def test_a_malformed_number_is_refused_naming_its_line(extra, said):
    data = BOX.read_bytes().rstrip(b"\n") + b"\n"  # (its faces use negative indices: -4 -3 -2 -1)
    line = data.count(b"\n") + 1
    with pytest.raises(InputError) as e:
        parse_obj(data + extra.encode() + b"\n", "box.obj", "box")
    assert str(e.value) == f"box.obj: line {line}: {said}"


def _scene_base(tmp_path: Path) -> None:
    for name in ("CornellBox-Original.obj", "CornellBox-Original.mtl"):
        (tmp_path / name).write_bytes((BOX.parent / name).read_bytes())
    (tmp_path / "box.yaml").write_text("geometry: {mesh: CornellBox-Original.obj}\n"
                                       "camera: {eye: [0.0, 1.0, 3.9], target: [0.0, 1.0, 0.0], up: [0.0, 1.0, 0.0], "
                                       "vfov: 39.3}\nresolution: [8, 8]\nphotons: 100\n")


NOTE = ("tlm: note: {src}: base: box.yaml is a scene file: taking it as a config of that scene at the default "
        "settings, the sweep's or study's own settings over them (a config would say `scene: box.yaml`; see "
        "'tlm params')\n")


def test_a_sweeps_base_may_be_a_scene_file(tmp_path, capsys):
    _scene_base(tmp_path)
    spec = tmp_path / "sw.yaml"
    spec.write_text("base: box.yaml\nset: {mode: rcast, render.spp: 1}\ngrid:\n  seed: [1, 2]\n")
    assert main(["sweep", str(spec), "--dry-run", "--json", "--out", str(tmp_path / "o")]) == 0
    out, err = capsys.readouterr()
    assert err == NOTE.format(src=spec), err
    assert json.loads(out)["points"] == 2


def test_a_granularity_studys_base_may_be_a_scene_file(tmp_path, capsys):
    _scene_base(tmp_path)
    spec = tmp_path / "gr.yaml"
    spec.write_text("base: box.yaml\npacket_sizes: [16, 64]\n")
    cfg, sizes, folder = load_granularity(spec)
    assert cfg.scene == str((tmp_path / "box.yaml").resolve()) and sizes == [16, 64] and folder == tmp_path.resolve()
    assert capsys.readouterr().err == NOTE.format(src=spec)


def _points(tmp_path: Path, warnings: list[list[str] | None]) -> list[dict]:
    """Rows of ok points whose results.json record ``warnings`` (None: no results.json that reads)."""
    rows = []
    for i, lines in enumerate(warnings):
        folder = tmp_path / "points" / f"h{i}"
        folder.mkdir(parents=True)
        (folder / "results.json").write_text("{not json" if lines is None else json.dumps({"warnings": lines}))
        rows.append({"point": i, "hash": f"h{i}", "status": "ok"})
    return rows


def test_the_points_warnings_are_said_with_how_many_points_recorded_each(tmp_path, capsys):
    rows = _points(tmp_path, [["a texture", "said before"], ["a texture"], ["a  texture", "coarse"], None])
    rows.append({"point": 4, "hash": "h0", "status": "ok"})  # (a point of the same hash: its record again)
    rows.append({"point": 5, "hash": "gone", "status": "failed"})
    print_point_warnings(rows, tmp_path, ["said before"])
    assert capsys.readouterr().err == ("tlm: warning: 4 of 6 points: a texture\n"
                                       "tlm: warning: 1 of 6 points: coarse\n")


def test_past_five_distinct_warnings_the_rest_are_counted(tmp_path, capsys):
    lines = [f"w{chr(97 + k)}" for k in range(POINT_WARNINGS_SHOWN + 3)]  # (wa, wb, ...: w0, w1 would be one)
    print_point_warnings(_points(tmp_path, [lines, lines[:1]]), tmp_path, [])
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "tlm: warning: 2 of 2 points: wa" and err[1:POINT_WARNINGS_SHOWN] == [
        f"tlm: warning: 1 of 2 points: w{chr(97 + k)}" for k in range(1, POINT_WARNINGS_SHOWN)]
    assert err[POINT_WARNINGS_SHOWN:] == [
        f"tlm: warning: and 3 more warnings of the points (each point's {tmp_path / 'points'}/HASH/results.json "
        "lists its own; the sweep's report shows them all)"]


@pytest.mark.slow
def test_tlm_sweep_says_a_warning_all_its_points_recorded_resumed_too(tmp_path, capsys):
    _scene_base(tmp_path)
    mtl = tmp_path / "CornellBox-Original.mtl"
    mtl.write_text(mtl.read_text().replace("newmtl floor\n", "newmtl floor\nmap_Kd wood.png\n"))
    spec = tmp_path / "sw.yaml"
    spec.write_text("base: {scene: box.yaml}\nset: {mode: rcast, render.spp: 1, arch.packet_size: 16}\n"
                    "grid:\n  seed: [1, 2]\n")
    said = ("tlm: warning: 2 of 2 points: 1 material of 'CornellBox-Original.mtl' ('floor') uses what tlm does not "
            "render: map_Kd; it renders with its constant colour")
    for _ in range(2):  # (the second: both points done before, read back)
        assert main(["sweep", str(spec), "--out", str(tmp_path / "o"), "--no-report", "--no-progress"]) == 0
        out, err = capsys.readouterr()
        assert out.startswith("2 points: ") and said in err, (out, err)
