"""h414: a sweep row's point (its folder, its config.resolved.yaml, its results) is found by one method,
:meth:`tlm.report.collect.Sweep.run_of`, made once per sweep, which every section uses (six of them built their own
map of the sweep's runs by folder name, each its own way)."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import yaml

from tlm.report import collect
from tlm.report.collect import Run, Sweep
from tlm.report.sweeps import named_rows

REPORT = Path(collect.__file__).parent


def _point(folder: Path, h: str, n: int, results: bool = True) -> None:
    point = folder / "points" / h
    point.mkdir(parents=True)
    if results:
        (point / "results.json").write_text(json.dumps({
            "scene": {"name": "cornell", "source": None}, "timing": None, "mode": "rcast", "fps": float(n),
            "factors": {"arch.pipelines": n}}), encoding="utf-8")
    (point / "config.resolved.yaml").write_text(yaml.safe_dump({"scene": "cornell", "mode": "rcast",
                                                                "arch": {"pipelines": n, "tag": h}}))


def _sweep(folder: Path, hashes: list[str], listed: bool = True, gone: tuple = (), earlier: tuple = ()) -> None:
    """A sweep folder of a point per hash (``gone``: its results.json not there), and the points of an earlier
    sweep into the folder (``earlier``: a row and a folder each, not in sweep.yaml); ``listed``: sweep.yaml lists
    its points (a sweep.yaml that lists none: every row is the sweep's)."""
    folder.mkdir(parents=True)
    spec = {"grid": {"arch.pipelines": [2 ** i for i in range(len(hashes))]}}
    if listed:
        spec["points"] = [{"point": i, "hash": h} for i, h in enumerate(hashes)]
    (folder / "sweep.yaml").write_text(yaml.safe_dump(spec))
    rows = []
    for i, h in enumerate([*earlier, *hashes]):
        _point(folder, h, 2 ** i, h not in gone)
        rows.append({"point": i, "hash": h, "status": "ok", "scene": "cornell", "mode": "rcast",
                     "arch.pipelines": 2 ** i, "fps": float(2 ** i)})
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))


def _read(*folders: Path) -> list[Sweep]:
    return collect.read(list(folders)).sweeps


def test_a_row_gives_its_points_run_and_config(tmp_path):
    _sweep(tmp_path / "sw", ["ha", "hb"])
    (sw,) = _read(tmp_path / "sw")
    for row in sw.rows:
        run = sw.run_of(row)
        assert run is not None and run.path == tmp_path / "sw" / "points" / row["hash"]
        assert run.config["arch"]["tag"] == row["hash"]  # (its config.resolved.yaml)
    assert [sw.run_of(r) for r in sw.rows] == sw.runs
    assert sw.run_of({"point": 0}) is None and sw.run_of({"hash": "nope"}) is None and sw.run_of(None) is None


def test_a_row_whose_folder_is_gone_has_no_run(tmp_path):
    _sweep(tmp_path / "sw", ["ha", "hb", "hc"], gone=("hb",))
    shutil.rmtree(tmp_path / "sw" / "points" / "hc")  # (its folder gone after the sweep)
    (sw,) = _read(tmp_path / "sw")
    assert [r["status"] for r in sw.rows] == ["ok", "missing", "missing"]
    assert [sw.run_of(r) is not None for r in sw.rows] == [True, False, False]


def test_a_row_of_another_sweep_has_no_run_in_this_one(tmp_path):
    _sweep(tmp_path / "a", ["ha", "hb"], earlier=("old",))  # (an earlier sweep's point, still in a/points/)
    _sweep(tmp_path / "b", ["hx"])
    a, b = sorted(_read(tmp_path / "a", tmp_path / "b"), key=lambda s: s.path.name)
    assert [r["hash"] for r in a.rows] == ["ha", "hb"]
    assert a.run_of({"hash": "old", "status": "ok"}) is None  # (its folder is there: not this sweep's point)
    assert a.run_of(b.rows[0]) is None and b.run_of(b.rows[0]).path == tmp_path / "b" / "points" / "hx"
    assert b.run_of(a.rows[0]) is None


def test_an_older_sweep_yaml_that_lists_no_points(tmp_path):
    _sweep(tmp_path / "sw", ["ha", "hb"], listed=False, earlier=("old",))
    (sw,) = _read(tmp_path / "sw")
    assert [r["hash"] for r in sw.rows] == ["old", "ha", "hb"]  # (every row the sweep's)
    assert [sw.run_of(r).config["arch"]["tag"] for r in sw.rows] == ["old", "ha", "hb"]


def test_the_lookup_is_made_once_per_sweep_and_again_for_other_runs(tmp_path):
    runs = [Run(tmp_path / "points" / h, h, "sweep-point", {"scene": {"name": "s"}}, {"h": h}) for h in "ab"]
    sw = Sweep(tmp_path, {}, [{"hash": "a"}, {"hash": "b"}, {"hash": "c"}], runs[:1])
    assert sw.run_of(sw.rows[0]) is runs[0] and sw.run_of(sw.rows[1]) is None
    made = sw._by_name[1]
    assert sw.run_of(sw.rows[0]) is runs[0] and sw._by_name[1] is made  # (the same map: not made again)
    sw.runs.append(runs[1])  # (a changed list: looked up again)
    assert sw.run_of(sw.rows[1]) is runs[1]
    sw.runs = [runs[1]]
    assert sw.run_of(sw.rows[0]) is None and sw.run_of(sw.rows[1]) is runs[1]
    other = Sweep(tmp_path, {}, sw.rows, runs)
    assert other == Sweep(tmp_path, {}, sw.rows, runs) and "_by_name" not in repr(other)


def test_named_rows_name_a_points_scene_from_its_run(tmp_path):
    _sweep(tmp_path / "sw", ["ha", "hb"], gone=("hb",))
    (sw,) = _read(tmp_path / "sw")
    sw.runs[0].named = "thesis/cornell"
    assert [r["scene"] for r in named_rows(sw)] == ["thesis/cornell", "cornell"]


def test_no_section_makes_its_own_lookup():
    """Each report module finds a row's point by Sweep.run_of (collect.py alone maps the runs by folder name)."""
    own = re.compile(r"\.path\.name\s*:\s*\w+(\.config)?\s+for\s+\w+\s+in\s+\w+\.runs")
    found = [p.name for p in REPORT.glob("*.py") if p.name != "collect.py" and own.search(p.read_text("utf-8"))]
    assert found == []
