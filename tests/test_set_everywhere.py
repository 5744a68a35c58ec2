"""``--set KEY=VALUE`` on ``tlm sweep`` and the study commands that run configs (``thesis``,
``granularity``, ``error-vs-cost``, ``extreme``), as ``tlm run --set`` takes it; and a sweep factor's
null value in ``sweep.csv``.

Only ``tlm run`` and ``tlm reference`` took ``--set``: a sweep at another resolution meant a copy of
its file. Now each applies it to its base config (a sweep's: after its ``set:``, before its
factors), refuses one of a key the file sets itself (a factor, a study's scenes or modes, a packet
size, a case's own key: it would win or lose unsaid), and gives a bad key or value ``tlm run``'s own
line (``FILE, with --set: KEY: ...``, exit 2, nothing written). A sweep point's hash holds the
override (a rerun with another one runs its points again), ``sweep.yaml`` lists it, and a study's
``provenance.json`` (and each run folder's ``results.json``) too.

``sweep.csv`` wrote a null factor value (``bsp.levels: [null, 4]``) as an empty cell, as it writes a
value the row does not have: now ``null``, as the sweep file and ``sweep.jsonl`` write it.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
import yaml

from tests.helpers_yaml import yaml_file as _file
from tlm.cli import main
from tlm.experiments.sweep_file import Point
from tlm.experiments.sweep_rows import point_row, write_rows

FAST = {"resolution": [8, 8], "render": {"light_samples": 1, "spp": 1}, "arch": {"frames": 1, "trace": False}}
SWEEP = {"base": {"scene": "cornell", "mode": "rcast", **FAST}, "grid": {"bsp.levels": [None, 4]}}


pytestmark = pytest.mark.usefixtures("cache")  # a cache folder of the test's own (tests/conftest.py)


def _csv(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _refused(capsys, argv: list[str], out: Path) -> str:
    """The one line of a command refused as bad input (exit 2), which wrote nothing."""
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert not out.exists()
    return err[-1]


# -- sweep.csv: a factor's null -------------------------------------------------------------


def test_a_null_factor_value_is_written_null_in_the_csv_and_a_missing_value_stays_empty(tmp_path):
    config = {"scene": "cornell", "mode": "rcast"}
    ok = {"status": "ok", "results": {"cycles": {"throughput": 5}, "fps": None, "timing": {"simpy_events": 1,
          "units": {}}, "functional": {"cached": False}, "host_seconds": {"functional": 0.1, "simulate": 0.1}}}
    failed = {"status": "failed", "error": {"type": "X", "message": "y", "stage": "simulate"}}
    rows = [point_row(Point(0, {"bsp.levels": None, "render.threads": None}, config, "h0"), ok),
            point_row(Point(1, {"bsp.levels": 4, "render.threads": 1}, config, "h1"), failed)]
    write_rows(tmp_path, rows)  # (as a sweep writes them: each row knows its factors)
    table = _csv(tmp_path / "sweep.csv")
    assert [(r["bsp.levels"], r["render.threads"]) for r in table] == [("null", "null"), ("4", "1")]
    assert table[0]["fps"] == "" and table[1]["fps"] == ""  # (null, and not in the row: both empty, as before)
    assert table[0]["error"] == "" and table[1]["cycles.throughput"] == ""
    jsonl = [json.loads(line) for line in (tmp_path / "sweep.jsonl").read_text().splitlines()]
    assert jsonl[0]["bsp.levels"] is None and jsonl[0]["render.threads"] is None  # (the JSONL's null as it was)
    write_rows(tmp_path, [], ["bsp.levels"])  # (no row: the factors named, as a sweep cut short at once)
    assert (tmp_path / "sweep.csv").read_text().startswith("point,hash,status,error,bsp.levels,scene,mode,")


# -- tlm sweep --set ------------------------------------------------------------------------


def test_sweep_set_is_refused_for_a_factor_and_its_sections_with_one_line(tmp_path, capsys):
    path = _file(tmp_path, "sw.yaml", {**SWEEP, "zip": {"arch.fifo_depth": [4, 8]}})
    out = tmp_path / "out"
    for given, named in (("bsp.levels=3", "bsp.levels is a factor of the sweep (grid.bsp.levels)"),
                         ("bsp={levels: 3}", "bsp holds bsp.levels, a factor of the sweep (grid.bsp.levels)"),
                         ("arch.fifo_depth=2", "arch.fifo_depth is a factor of the sweep (zip.arch.fifo_depth)")):
        line = _refused(capsys, ["sweep", str(path), "--out", str(out), "--jobs", "1", "--set", given], out)
        assert line.startswith(f"tlm: error: {path}: --set {given}: {named}"), line


def test_sweep_set_of_a_bad_key_or_value_is_tlm_runs_line(tmp_path, capsys):
    path = _file(tmp_path, "sw.yaml", SWEEP)
    run = _file(tmp_path, "run.yaml", SWEEP["base"])
    out = tmp_path / "out"
    for given, said in (("render.bogus=1", "render.bogus: unknown key"),
                        ("render.spp=two", "render.spp: two is not an integer")):
        line = _refused(capsys, ["sweep", str(path), "--out", str(out), "--set", given], out)
        assert line == f"tlm: error: {path}, with --set: {said}"
        assert _refused(capsys, ["run", str(run), "--out", str(out), "--set", given], out) == \
            f"tlm: error: {run}, with --set: {said}"
    assert _refused(capsys, ["sweep", str(path), "--out", str(out), "--set", "render.spp"], out) == \
        "tlm: error: --set: 'render.spp' is not of the form dotted.key=value"


def test_the_api_takes_the_overrides_as_set_strings(tmp_path):
    import tlm

    path = _file(tmp_path, "sw.yaml", SWEEP)
    out = tmp_path / "out"
    for given in ("resolution=[10, 10]", {"resolution": [10, 10]}):
        with pytest.raises(tlm.InputError, match=r"^overrides: .*: overrides are a list of dotted.key=value strings"):
            tlm.run_sweep(path, out, overrides=given)
    # (named as the command line names it, --set, or as the argument, overrides: tlm.api_common.argument_names)
    with pytest.raises(tlm.InputError, match=r": (--set|overrides) bsp.levels=3: bsp.levels is a factor of the sweep"):
        tlm.sweep(path, out, overrides=["bsp.levels=3"])
    with pytest.raises(tlm.InputError, match=r", with --set: render.bogus: unknown key$"):
        tlm.thesis("thesis", out, overrides=["render.bogus=1"])
    assert not out.exists()


@pytest.mark.slow
def test_sweep_set_is_in_every_point_its_hash_and_sweep_yaml(tmp_path, capsys):
    path = _file(tmp_path, "sw.yaml", SWEEP)
    out = tmp_path / "out"

    def sweep(*given: str) -> tuple[str, dict, list[dict]]:
        argv = ["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-progress", "--no-report"]
        assert main([*argv, *(a for g in given for a in ("--set", g))]) == 0
        said = capsys.readouterr().out
        return said, yaml.safe_load((out / "sweep.yaml").read_text()), _csv(out / "sweep.csv")

    said, spec, rows = sweep("resolution=[12, 12]")
    assert "2 points: 2 ok, 0 failed, 0 skipped" in said and spec["overrides"] == ["resolution=[12, 12]"]
    first = {r["hash"] for r in rows}
    for h in first:  # the resolved config of every point holds the override, its results the render it made
        assert yaml.safe_load((out / "points" / h / "config.resolved.yaml").read_text())["resolution"] == [12, 12]
        assert json.loads((out / "points" / h / "results.json").read_text())["scene"]["resolution"] == [12, 12]
    assert [r["bsp.levels"] for r in rows] == ["null", "4"]  # (the factor's null, as the file writes it)

    said, spec, rows = sweep("resolution=[10, 10]")  # another --set into the folder: other points, run again
    assert "2 points: 2 ok, 0 failed, 0 skipped" in said and spec["overrides"] == ["resolution=[10, 10]"]
    assert not first & {r["hash"] for r in rows}
    for r in rows:
        assert json.loads((out / "points" / r["hash"] / "results.json").read_text())["scene"]["resolution"] == [10, 10]
    said, _, again = sweep("resolution=[10, 10]")  # the same: done before
    assert "2 points: 0 ok, 0 failed, 2 skipped" in said and again == rows
    said, spec, rows = sweep()  # none: the file's own points, sweep.yaml without overrides
    assert "0 skipped" in said and "overrides" not in spec
    assert yaml.safe_load((out / "points" / rows[0]["hash"] / "config.resolved.yaml").read_text())["resolution"] \
        == [8, 8]


@pytest.mark.slow
def test_sweep_set_wins_over_the_files_set_and_names_the_scene_it_gives(tmp_path, capsys):
    path = _file(tmp_path, "sw.yaml", {**SWEEP, "set": {"scene": "thesis/ring", "arch.fifo_depth": 2}})
    out = tmp_path / "out"
    argv = ["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-progress", "--no-report"]
    assert main([*argv, "--set", "arch.fifo_depth=3", "--set", "scene=cornell"]) == 0
    rows = _csv(out / "sweep.csv")
    assert [r["scene"] for r in rows] == ["cornell", "cornell"]  # (not the file's set: scene)
    config = yaml.safe_load((out / "points" / rows[0]["hash"] / "config.resolved.yaml").read_text())
    assert config["arch"]["fifo_depth"] == 3 and config["scene"] == "cornell"


# -- the studies ----------------------------------------------------------------------------


def test_study_set_is_refused_where_the_study_sets_the_key(tmp_path, capsys):
    thesis = _file(tmp_path, "th.yaml", {"base": FAST, "scenes": ["cornell"], "modes": ["rcast"]})
    gran = _file(tmp_path, "gr.yaml", {"base": {"scene": "cornell", "mode": "rcast", **FAST}, "packet_sizes": [1, 16]})
    evc = _file(tmp_path, "evc.yaml", {"base": {"scene": "cornell", **FAST},
                                       "points": [{"photons.count": [300], "estimate.filter": ["disk", "mvoxel"]}]})
    cases = _file(tmp_path, "ex.yaml", {"base": FAST, "cases": [
        {"name": "a", "category": "c", "expect": "runs", "config": {"scene": "cornell", "arch": {"fifo_depth": 2}},
         "checks": ["finite"]}]})
    out = tmp_path / "out"
    for argv, named in (
            (["thesis", str(thesis), "--set", "scene=cornell"], f"{thesis}: --set scene=cornell: scene is set by "
                                                                 "the study's scenes"),
            (["thesis", str(thesis), "--set", "mode=pmap"], f"{thesis}: --set mode=pmap: mode is set by the study's "
                                                             "modes"),
            (["granularity", str(gran), "--set", "arch.packet_size=4"], f"{gran}: --set arch.packet_size=4: "
                                                                         "arch.packet_size is set by the study's "
                                                                         "packet_sizes"),
            (["error-vs-cost", str(evc), "--set", "estimate.filter=knn"], f"{evc}: --set estimate.filter=knn: "
                                                                           "estimate.filter is varied by the study's "
                                                                           "points (points[0].estimate.filter)"),
            (["error-vs-cost", str(evc), "--set", "mode=rcast"], f"{evc}: --set mode=rcast: 'rcast': error-vs-cost "
                                                                  "measures the photon map"),
            (["extreme", str(cases), "--set", "arch={fifo_depth: 4}"], f"{cases}: --set arch={{fifo_depth: 4}}: arch "
                                                                        "holds arch.fifo_depth, set by the case 'a' "
                                                                        "(cases[0].config.arch.fifo_depth)"),
            (["extreme", str(cases), "--set", "scene=ring"], f"{cases}: --set scene=ring: scene is set by the case "
                                                              "'a'"),
    ):
        line = _refused(capsys, [*argv, "--out", str(out)], out)
        assert line.startswith(f"tlm: error: {named}"), line
    for command, path in (("thesis", thesis), ("granularity", gran), ("error-vs-cost", evc), ("extreme", cases)):
        line = _refused(capsys, [command, str(path), "--out", str(out), "--set", "render.bogus=1"], out)
        assert line == f"tlm: error: {path}, with --set: render.bogus: unknown key"


@pytest.mark.slow
def test_thesis_and_granularity_run_their_base_with_the_set(tmp_path, capsys):
    thesis = _file(tmp_path, "th.yaml", {"base": FAST, "scenes": ["cornell"], "modes": ["rcast"]})
    assert main(["thesis", str(thesis), "--out", str(tmp_path / "t"), "--no-progress", "--no-report",
                 "--set", "resolution=[10, 10]"]) == 0
    results = json.loads((tmp_path / "t" / "cornell" / "rcast" / "results.json").read_text())
    assert results["scene"]["resolution"] == [10, 10]
    assert results["overrides"] == ["resolution=[10, 10]"]  # (the user's alone: the cell's own scene, mode apart)
    assert json.loads((tmp_path / "t" / "provenance.json").read_text())["overrides"] == ["resolution=[10, 10]"]

    gran = _file(tmp_path, "gr.yaml", {"base": {"scene": "cornell", "mode": "rcast", **FAST}, "packet_sizes": [1, 16]})
    assert main(["granularity", str(gran), "--out", str(tmp_path / "g"), "--no-report",
                 "--set", "arch.fifo_depth=3"]) == 0
    assert yaml.safe_load((tmp_path / "g" / "config.resolved.yaml").read_text())["arch"]["fifo_depth"] == 3
    assert json.loads((tmp_path / "g" / "provenance.json").read_text())["overrides"] == ["arch.fifo_depth=3"]
    capsys.readouterr()


@pytest.mark.slow
def test_error_vs_cost_and_extreme_run_their_base_with_the_set(tmp_path, capsys):
    evc = _file(tmp_path, "evc.yaml", {
        "base": {"scene": "cornell", "resolution": [8, 8], "estimate": {"final_gather": 0},
                 "reference": {"photons": 800, "k_nearest": 20, "tolerance": 0.9, "min_rounds": 2, "max_rounds": 4,
                               "spp": 1}},
        "points": [{"photons.count": [300], "estimate.filter": ["disk", "mvoxel"]}]})
    assert main(["error-vs-cost", str(evc), "--out", str(tmp_path / "v"), "--truth-spp", "0", "--no-report",
                 "--set", "resolution=[6, 6]"]) == 0
    assert yaml.safe_load((tmp_path / "v" / "config.resolved.yaml").read_text())["resolution"] == [6, 6]
    assert json.loads((tmp_path / "v" / "provenance.json").read_text())["overrides"] == ["resolution=[6, 6]"]

    cases = _file(tmp_path, "ex.yaml", {"base": {"resolution": [8, 8], "arch": {"frames": 1}}, "cases": [
        {"name": "a", "category": "c", "expect": "runs", "config": {"scene": "cornell", "mode": "rcast"},
         "checks": ["finite"]},
        {"name": "bad", "category": "c", "expect": "an error", "config": {"scene": "cornell", "resolution": [0, 8]},
         "checks": [{"error": "must be positive"}]}]})
    assert main(["extreme", str(cases), "--out", str(tmp_path / "e"), "--no-report",
                 "--set", "render.spp=1", "--set", "arch.fifo_depth=3"]) == 0
    results = json.loads((tmp_path / "e" / "cases" / "a" / "results.json").read_text())
    assert results["overrides"] == ["render.spp=1", "arch.fifo_depth=3"]
    config = yaml.safe_load((tmp_path / "e" / "cases" / "a" / "config.resolved.yaml").read_text())
    assert (config["render"]["spp"], config["arch"]["fifo_depth"]) == (1, 3)
    assert json.loads((tmp_path / "e" / "provenance.json").read_text())["overrides"] == ["render.spp=1",
                                                                                            "arch.fifo_depth=3"]
    capsys.readouterr()
