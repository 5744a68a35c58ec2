"""Sweeps: points from grid x zip, executors, resume after a kill, failed points, the shared render."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pandas as pd
import pytest
import yaml

import tlm.experiments.run as run_mod
import tlm.experiments.sweep as sweep_mod
import tlm.fingerprint as fingerprint
from tlm.arch.costs import DEFAULT_PATH
from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments.frames import cache_dir, cached_render
from tlm.experiments.sweep import run_sweep
from tlm.experiments.sweep_file import config_hash, expand, load_sweep, point_inputs
from tlm.experiments.sweep_rows import RAN_COLUMNS, utilization

from .scenes import sphere_scene

REPO = Path(__file__).resolve().parents[1]
RUN_POINT = sweep_mod.run_point
BASE = {"scene": "cornell", "mode": "rcast", "resolution": [24, 16], "render": {"light_samples": 1},
        "arch": {"frames": 2, "trace": False, "packet_size": 32}}
HOST = ("seconds.functional", "seconds.simulate", "seconds.one_off", "seconds.write")


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py) every test here has its own
    return cache


def sweep_file(tmp_path: Path, name: str = "sweep.yaml", **body) -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump({"base": BASE, **body}, sort_keys=False))
    return path


def jsonl(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


def without_host(rows: list[dict]) -> list[dict]:
    """The rows less what differs with the process that ran a point: host seconds, and who ran it (RAN_COLUMNS)."""
    return [{k: v for k, v in r.items() if k not in HOST and k not in RAN_COLUMNS} for r in rows]


# ---------------------------------------------------------------- the sweep file


@pytest.mark.slow
def test_points_are_the_grid_product_times_zip_in_order(tmp_path):
    assert expand({"a": [1, 2], "b": ["x", "y"]}, {"c": [7, 8], "d": [0, 1]}) == [
        {"a": a, "b": b, "c": c, "d": d} for a in (1, 2) for b in ("x", "y") for c, d in ((7, 0), (8, 1))]
    assert expand({}, {"c": [7, 8]}) == [{"c": 7}, {"c": 8}]
    assert expand({"a": [1, 2]}, {}) == [{"a": 1}, {"a": 2}]

    (tmp_path / "run.yaml").write_text(yaml.safe_dump(BASE))
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({
        "base": "run.yaml", "set": {"arch.frames": 3, "render.reflect_depth": 2},
        "grid": {"arch.fifo_depth": [1, 16], "arch.page_miss_cycles": [0, 12]},
        "zip": {"seed": [0, 1, 2], "bsp.levels": [3, 4, 5]},
    }, sort_keys=False))
    sw = load_sweep(path)
    assert sw.factors == ["arch.fifo_depth", "arch.page_miss_cycles", "seed", "bsp.levels"]
    assert len(sw.points) == 2 * 2 * 3
    assert [p.index for p in sw.points] == list(range(12))
    assert [(p.factors["arch.fifo_depth"], p.factors["arch.page_miss_cycles"], p.factors["seed"])
            for p in sw.points[:4]] == [(1, 0, 0), (1, 0, 1), (1, 0, 2), (1, 12, 0)]
    for p in sw.points:
        c = p.config
        assert c["arch"]["fifo_depth"] == p.factors["arch.fifo_depth"]
        assert c["bsp"]["levels"] == p.factors["bsp.levels"] and c["seed"] == p.factors["seed"]
        assert c["arch"]["frames"] == 3 and c["render"]["reflect_depth"] == 2  # set
        assert c["arch"]["packet_size"] == 32 and c["resolution"] == [24, 16]  # the base file
        assert c["render"]["batch"] == 4  # a default
        # (the key holds arch.trace as true, whatever the point runs with: h209)
        assert c["arch"]["trace"] is False
        keyed = {**c, "arch": {**c["arch"], "trace": True}}
        assert p.hash == config_hash(keyed, point_inputs(config_from_dict(c), sw.folder, "test")) and len(p.hash) == 16
        assert p.hash != config_hash(keyed)  # the input files are part of the key
    assert len({p.hash for p in sw.points}) == 12
    assert sw.folder == tmp_path.resolve()


@pytest.mark.parametrize("body, key", [
    ({"grids": {"seed": [0, 1]}}, "grids"),
    ({"zip": {"seed": [0, 1], "arch.fifo_depth": [1, 2, 3]}}, "zip"),
    ({"grid": {"arch.fifo_dept": [1, 2]}}, "arch.fifo_dept"),
    ({"grid": {"arch.fifo_depth": [16, 0]}}, "arch.fifo_depth"),
    ({"grid": {"arch.fifo_depth": [16, 1.5]}}, "arch.fifo_depth: 1.5 is not an int"),
    ({"zip": {"arch.clock_hz": ["fast"]}}, "arch.clock_hz: fast is not a number"),
    ({"grid": {"arch.fifo_depth": 16}}, "grid.arch.fifo_depth"),
    ({"grid": {"arch.fifo_depth": []}}, "grid.arch.fifo_depth"),
    ({"grid": {"mode": ["rcast", "raytrace"]}}, "mode"),
    ({"set": {"arch.fifo_depth": 4}, "grid": {"arch": [{"fifo_depth": 2}]}}, "grid.arch"),
    ({"grid": {"scene": ["cornell", "cornel"]}}, "scene"),
    ({"zip": {"arch.programs": ["missing.yaml"]}}, "arch.programs"),
    ({"base": "missing.yaml", "grid": {"seed": [0]}}, "base"),
    ({"description": "no factors"}, "grid"),
    # render.threads changes no result: its points would be one run with other labels
    ({"grid": {"render.threads": [1, 2], "arch.pipelines": [1, 2]}}, "differ only in render.threads (render"),
    ({"zip": {"render": [{"threads": 1}, {"threads": 2}]}}, "points 0 and 1 differ only in render"),
])
def test_bad_sweep_files_exit_2_and_write_nothing(tmp_path, capsys, body, key):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, **body}))
    assert main(["sweep", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tlm: error:")
    assert str(path) in err[0] and key in err[0]
    assert not (tmp_path / "o").exists()


def test_a_sweep_file_with_a_key_given_twice_exits_2(tmp_path, capsys):
    """Two ``grid:`` sections: PyYAML would keep the second and sweep half the points."""
    path = tmp_path / "twice.yaml"
    path.write_text(yaml.safe_dump({"base": BASE}) + "grid: {seed: [0, 1]}\ngrid: {arch.fifo_depth: [1, 2]}\n")
    assert main(["sweep", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and "duplicate key 'grid'" in err[0], err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("args, key", [(["--jobs", "0"], "--jobs"), (["--dask", "nowhere"], "--dask")])
def test_bad_executor_options_exit_2(tmp_path, capsys, args, key):
    path = sweep_file(tmp_path, grid={"seed": [0]})
    assert main(["sweep", str(path), "--out", str(tmp_path / "o"), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"tlm: error: {key}:")
    assert not (tmp_path / "o").exists()


# ---------------------------------------------------------------- running


@pytest.mark.slow
def test_local_pool_and_dask_give_identical_rows(tmp_path, monkeypatch):
    path = sweep_file(tmp_path, grid={"arch.pipelines": [1, 2], "arch.page_miss_cycles": [0, 48]},
                      zip={"seed": [0, 1]})
    local = run_sweep(path, tmp_path / "local", jobs=2)
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache2"))  # each renders its own two frames
    dask = run_sweep(path, tmp_path / "dask", jobs=2, dask="local")
    assert (local.ok, local.failed, local.skipped, local.renders) == (8, 0, 0, 2)
    assert (dask.ok, dask.failed, dask.skipped, dask.renders) == (8, 0, 0, 2)
    assert without_host(local.rows) == without_host(dask.rows)
    for out in ("local", "dask"):
        assert without_host(jsonl(tmp_path / out / "sweep.jsonl")) == without_host(local.rows)
    assert [r["point"] for r in local.rows] == list(range(8))
    assert all(r["status"] == "ok" and r["error"] is None for r in local.rows)
    assert {r["cycles.throughput"] for r in local.rows if r["arch.page_miss_cycles"] == 0} != \
        {r["cycles.throughput"] for r in local.rows if r["arch.page_miss_cycles"] == 48}


HANG = """
import gc, sys
from contextlib import ExitStack

if __name__ == "__main__":
    import distributed.utils as du
    from tlm.errors import InputError
    from tlm.experiments import executors
    start = du.LoopRunner._start_unlocked
    def collected(self, *a, **k):  # (what the collector does by chance there: the hang's trigger)
        gc.collect()
        return start(self, *a, **k)
    du.LoopRunner._start_unlocked = collected
    with ExitStack() as stack:
        try:
            executors.open_executor(stack, 1, "nowhere", 1)
        except InputError:
            pass
    with ExitStack() as stack:
        executors.open_executor(stack, 1, "local", 1)
    print("started")
"""


def test_a_failed_dask_address_never_hangs_the_next_cluster(tmp_path):
    """A Client whose address failed is garbage with its loop runner started; collected
    while distributed starts the next cluster's loop (under the lock its __del__ takes),
    it hung the process (seen in the suite: the local-cluster test after the bad-address
    one). The executor collects it first."""
    script = tmp_path / "hang.py"
    script.write_text(HANG)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=120)  # (a hang guard, not a timing)
    assert done.returncode == 0 and done.stdout.strip() == "started", done.stderr[-2000:]


@pytest.mark.slow
def test_a_local_dask_cluster_does_not_need_port_8787(tmp_path, capfd):
    """Another cluster (or anything) on the dashboard's usual port: no warning about it."""
    taken = socket.socket()
    try:
        taken.bind(("", 8787))
        taken.listen()
    except OSError:
        taken.close()
        pytest.skip("port 8787 is in use already, or cannot be bound")
    path = sweep_file(tmp_path, grid={"seed": [0]})
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert main(["sweep", str(path), "--out", str(tmp_path / "o"), "--jobs", "1", "--dask", "local"]) == 0
    finally:
        taken.close()
    err = capfd.readouterr().err
    assert "already in use" not in err and "8787" not in err
    assert not [w for w in caught if "already in use" in str(w.message)]


def test_utilization_averages_the_pipelines_of_a_kind():
    def unit(busy, stalled, elapsed=100):
        return {"busy": busy, "stalled": stalled, "idle": elapsed - busy - stalled, "elapsed": elapsed}

    units = {"pipe0.vertex": unit(50, 10), "pipe0.traversal": unit(60, 20), "pipe1.traversal": unit(20, 40),
             "mem0": unit(90, 0), "xbar": unit(5, 0)}
    assert utilization(units) == {
        "busy.vertex": 0.5, "busy.traversal": 0.4,
        "stall.vertex": 0.1, "stall.traversal": 0.3,
        "idle.vertex": 0.4, "idle.traversal": 0.3,
    }


@pytest.mark.slow
def test_rows_folders_and_the_csv(tmp_path):
    path = sweep_file(tmp_path, set={"arch.trace": True}, grid={"arch.page_miss_cycles": [0, 12, 48]})
    done = run_sweep(path, tmp_path / "o", jobs=1)
    out = tmp_path / "o"
    table = pd.read_csv(out / "sweep.csv", dtype={"hash": str})
    assert len(table) == 3 and list(table["point"]) == [0, 1, 2]
    assert list(table.columns[:5]) == ["point", "hash", "status", "error", "arch.page_miss_cycles"]
    for pm in ("vertex", "traversal", "intersection", "fragment"):
        assert {f"cycles.{pm}", f"busy.{pm}", f"stall.{pm}", f"idle.{pm}"} <= set(table.columns)
        total = table[f"busy.{pm}"] + table[f"stall.{pm}"] + table[f"idle.{pm}"]
        assert ((total - 1.0).abs() < 1e-5).all()
    for col in ("cycles.throughput", "cycles.latency", "fps", "simpy_events", "functional_cached", *HOST):
        assert col in table.columns
    assert list(table["scene"]) == ["cornell"] * 3 and list(table["mode"]) == ["rcast"] * 3
    # the base's stream (2 frames) is too short for a steady-state TThru: each row says so
    assert BASE["arch"]["frames"] == 2 and list(table["throughput_steady"]) == [False] * 3
    assert pd.read_json(out / "sweep.jsonl", lines=True).shape[0] == 3
    resolved = yaml.safe_load((out / "sweep.yaml").read_text())
    assert [p["hash"] for p in resolved["points"]] == list(table["hash"])
    # a point's folder: what tlm run writes for the same config
    row = done.rows[1]
    folder = out / "points" / row["hash"]
    assert sorted(p.name for p in folder.iterdir()) == ["config.resolved.yaml", "results.json", "trace.json"]
    res = json.loads((folder / "results.json").read_text())
    assert res["factors"] == {"arch.page_miss_cycles": 12}
    assert res["work"]["rcast"]["primary_rays"] == 4 * 24 * 16 and res["scene"]["triangles"] == 2604  # spp 4
    cfg = tmp_path / "run.yaml"
    cfg.write_text(yaml.safe_dump(yaml.safe_load((folder / "config.resolved.yaml").read_text())))
    assert main(["run", str(cfg), "--out", str(tmp_path / "run")]) == 0
    alone = json.loads((tmp_path / "run" / "results.json").read_text())
    assert res["cycles"] == alone["cycles"] and res["fps"] == alone["fps"]
    assert res["work"] == alone["work"] and res["scene"] == alone["scene"]
    assert res["timing"].keys() == alone["timing"].keys()
    assert row["cycles.throughput"] == alone["cycles"]["throughput"]


@pytest.mark.slow
def test_points_that_differ_only_in_arch_render_once(tmp_path, monkeypatch):
    calls = []
    render = run_mod.render
    monkeypatch.setattr(run_mod, "render", lambda *a, **k: calls.append(1) or render(*a, **k))
    path = sweep_file(tmp_path, grid={"seed": [0, 1], "arch.fifo_depth": [1, 16, 256]})
    done = run_sweep(path, tmp_path / "o", jobs=1)
    assert len(calls) == 2 and done.renders == 2
    for seed in (0, 1):
        flags = [r["functional_cached"] for r in done.rows if r["seed"] == seed]
        assert flags == [False, True, True]
    # two worker processes: still one render per frame, whichever worker gets it
    again = run_sweep(sweep_file(tmp_path, "s2.yaml", grid={"seed": [2, 3], "arch.fifo_depth": [1, 16, 256]}),
                      tmp_path / "o2", jobs=2)
    assert again.renders == 2
    assert sorted(r["functional_cached"] for r in again.rows) == [False] * 2 + [True] * 4


@pytest.mark.slow
def test_a_failing_point_is_recorded_and_the_sweep_goes_on(tmp_path, capsys):
    # 50 SimPy events cannot finish a frame: the model raises MaxEventsReached (a Deadlock) at simulate time
    path = sweep_file(tmp_path, grid={"arch.fifo_depth": [1, 16]}, zip={"arch.max_events": [50, 10**8]})
    out = tmp_path / "o"
    assert main(["sweep", str(path), "--out", str(out), "--jobs", "2"]) == 1
    printed = capsys.readouterr().out
    assert "2 ok, 2 failed, 0 skipped" in printed and printed.count("MaxEventsReached") == 2
    rows = pd.read_csv(out / "sweep.csv", dtype={"hash": str})
    assert list(rows["status"]) == ["failed", "ok", "failed", "ok"]
    failed = rows[rows["status"] == "failed"]
    assert failed["error"].str.startswith("MaxEventsReached: stopped at arch.max_events = 50 events").all()
    assert failed["cycles.throughput"].isna().all() and rows["cycles.throughput"].notna().sum() == 2
    for h in failed["hash"]:
        folder = out / "points" / h
        assert sorted(p.name for p in folder.iterdir()) == ["config.resolved.yaml", "error.json"]
        err = json.loads((folder / "error.json").read_text())
        assert err["type"] == "MaxEventsReached" and err["stage"] == "simulate" and "Traceback" in err["traceback"]
    # a rerun skips what is done and retries what failed
    again = run_sweep(path, out, jobs=1)
    assert (again.ok, again.failed, again.skipped) == (0, 2, 2)


def ends_its_worker(task):
    """run_point, but the point of page-miss cost 48 ends its worker process every time, and
    that of 96 the first time only. Local workers import it from this module by name."""
    cycles = task.factors["arch.page_miss_cycles"]
    if cycles in (48, 96):
        time.sleep(0.3)  # another point is under way in the other worker
        once = Path(task.folder) / f"died-{task.hash}"
        if cycles == 48 or not once.exists():
            once.touch()
            os._exit(3)
    return RUN_POINT(task)


@pytest.mark.slow
def test_a_point_that_kills_its_worker_fails_and_the_others_run(tmp_path, monkeypatch, capsys):
    """A point that ends its worker (a crash, an OOM kill) breaks the local process pool.
    The pool is replaced; the points in flight run again alone, so that the one whose
    worker dies each time fails with that death, and every other point ends ok: those
    queued, the one running beside it, the one whose worker died once."""
    path = sweep_file(tmp_path, grid={"arch.page_miss_cycles": [0, 12, 48, 96, 120]})
    out = tmp_path / "o"
    monkeypatch.setattr(sweep_mod, "run_point", ends_its_worker)
    assert main(["sweep", str(path), "--out", str(out), "--jobs", "2", "--no-progress"]) == 1
    assert "4 ok, 1 failed, 0 skipped" in capsys.readouterr().out
    rows = pd.read_csv(out / "sweep.csv", dtype={"hash": str})
    assert list(rows["status"]) == ["ok", "ok", "failed", "ok", "ok"]
    assert rows["error"][2].startswith("WorkerDied: its worker process died 2 times running this point")
    assert rows["error"][2].endswith("(exit code 3, exit code 3)")
    assert rows["cycles.throughput"].notna().sum() == 4
    assert (tmp_path / f"died-{rows['hash'][3]}").exists()  # 96 did end its worker once
    err = json.loads((out / "points" / rows["hash"][2] / "error.json").read_text())
    assert err["type"] == "WorkerDied" and err["stage"] == "worker" and "exit code 3" in err["message"]
    assert sorted(p.name for p in (out / "points").iterdir()) == sorted(rows["hash"])
    # a rerun (the crash fixed) runs the failed point only
    monkeypatch.setattr(sweep_mod, "run_point", RUN_POINT)
    fixed = run_sweep(path, out, jobs=2)
    assert (fixed.ok, fixed.failed, fixed.skipped) == (1, 0, 4)
    assert [r["status"] for r in jsonl(out / "sweep.jsonl")] == ["ok"] * 5


@pytest.mark.slow
def test_resume_runs_only_the_missing_points(tmp_path, monkeypatch):
    path = sweep_file(tmp_path, grid={"arch.page_miss_cycles": [0, 12, 48], "arch.fifo_depth": [1, 16]})
    out = tmp_path / "o"
    first = run_sweep(path, out, jobs=2)
    gone = first.rows[3]["hash"]
    shutil.rmtree(out / "points" / gone)
    (out / "sweep.jsonl").write_text((out / "sweep.jsonl").read_text().splitlines(keepends=True)[0])
    ran = []
    point = sweep_mod.run_point
    monkeypatch.setattr(sweep_mod, "run_point", lambda task: ran.append(task.hash) or point(task))
    second = run_sweep(path, out, jobs=1)
    assert ran == [gone]
    assert (second.ok, second.failed, second.skipped, second.renders) == (1, 0, 5, 0)
    assert without_host(jsonl(out / "sweep.jsonl")) == [
        {**r, "functional_cached": True if r["hash"] == gone else r["functional_cached"]}
        for r in without_host(first.rows)]
    # another sweep into the same folder: shared points are found by their hash, the rows
    # are this sweep's
    other = run_sweep(sweep_file(tmp_path, "other.yaml", set={"arch.fifo_depth": 16},
                                 grid={"arch.page_miss_cycles": [12, 24]}), out, jobs=1)
    assert (other.ok, other.skipped) == (1, 1)
    table = pd.read_csv(out / "sweep.csv", dtype={"hash": str})
    assert list(table["arch.page_miss_cycles"]) == [12, 24] and "arch.fifo_depth" not in table.columns
    assert table["hash"][0] == next(r["hash"] for r in first.rows
                                    if (r["arch.page_miss_cycles"], r["arch.fifo_depth"]) == (12, 16))
    assert len(list((out / "points").iterdir())) == 7


def test_a_point_folder_holding_something_else_is_run_again(tmp_path, monkeypatch):
    """A point's ``results.json`` that parses but is not that point's (emptied to ``{}``,
    another run written into the folder, the results of another point) is run again, as a
    damaged one is, never read as done (it used to end the resume in a KeyError)."""
    path = sweep_file(tmp_path, grid={"arch.page_miss_cycles": [0, 12, 24]})
    out = tmp_path / "o"
    first = run_sweep(path, out, jobs=1)
    h = [r["hash"] for r in first.rows]
    (out / "points" / h[0] / "results.json").write_text("{}\n")
    (out / "points" / h[1] / "results.json").write_text((out / "points" / h[2] / "results.json").read_text())
    ran = []
    point = sweep_mod.run_point
    monkeypatch.setattr(sweep_mod, "run_point", lambda task: ran.append(task.hash) or point(task))
    again = run_sweep(path, out, jobs=1)
    assert sorted(ran) == sorted(h[:2]) and (again.ok, again.failed, again.skipped) == (2, 0, 1)
    assert without_host(jsonl(out / "sweep.jsonl")) == [
        {**r, "functional_cached": r["functional_cached"] or r["hash"] in h[:2]} for r in without_host(first.rows)]


def test_a_changed_sweep_cut_short_leaves_only_its_own_rows(tmp_path, monkeypatch):
    """A rerun into the folder of another sweep, interrupted: ``sweep.jsonl`` and
    ``sweep.csv`` hold the new sweep's finished points only (never the earlier sweep's
    rows beside them), the report says how many points have no row yet, and eq. 5.2's
    fit is told so."""
    from tlm.experiments.scaling import collect
    from tlm.report import build_report

    out = tmp_path / "o"
    first = run_sweep(sweep_file(tmp_path, "a.yaml", grid={"arch.page_miss_cycles": [0, 12, 24]}), out, jobs=1)
    second = sweep_file(tmp_path, "b.yaml", grid={"arch.page_miss_cycles": [12, 36, 48, 60]})
    point = sweep_mod.run_point
    done = []

    def cut(task):
        if len(done) == 2:
            raise KeyboardInterrupt
        done.append(task.hash)
        return point(task)

    monkeypatch.setattr(sweep_mod, "run_point", cut)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(second, out, jobs=1)
    mine = {p.hash: p for p in load_sweep(second).points}
    shared = {r["hash"] for r in first.rows} & set(mine)  # 12: done by the first sweep, skipped
    rows = jsonl(out / "sweep.jsonl")
    assert {r["hash"] for r in rows} == shared | set(done) and len(rows) == 3
    assert set(pd.read_csv(out / "sweep.csv", dtype={"hash": str})["hash"]) <= set(mine)
    report = build_report([out], tmp_path / "rep")
    assert "1 of its 4 points not run yet" in report.read_text()
    notes: list[str] = []
    assert len(collect(out, notes)) == 3 and notes[0] == (
        f"{out}: 3 of its 4 points have a row (the sweep was interrupted or is still running; the same 'tlm sweep' "
        "command finishes it): fitted from those")
    assert len(notes) == 4 and all("too short for a steady state" in n for n in notes[1:])  # (arch.frames: 2)


@pytest.mark.slow
def test_changed_input_files_run_the_points_again(tmp_path):
    """The point key covers the content of the files the config names: the programs table,
    the scene file and the mesh it names. A rerun after a change to one computes the points
    again (and never reports the old results as done)."""
    sphere_scene(tmp_path, n_seg=12, n_rings=6)
    programs = yaml.safe_load(DEFAULT_PATH.read_text())
    (tmp_path / "myprog.yaml").write_text(yaml.safe_dump(programs))
    base = {**BASE, "scene": "furnace.yaml", "arch": {**BASE["arch"], "programs": "myprog.yaml"}}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": base, "grid": {"arch.page_miss_cycles": [0, 48]}}))
    out = tmp_path / "o"

    def again():
        done = run_sweep(path, out, jobs=1)
        assert done.failed == 0 and done.ok + done.skipped == 2
        return done

    first = again()
    assert (first.ok, first.skipped) == (2, 0)
    assert (again().ok, again().skipped) == (0, 2)  # nothing changed: nothing runs

    programs["vertex"]["scale"] *= 2
    (tmp_path / "myprog.yaml").write_text(yaml.safe_dump(programs))
    slower = again()
    assert (slower.ok, slower.skipped, slower.renders) == (2, 0, 0)  # the frame is the same: from the cache
    for old, new in zip(first.rows, slower.rows):
        assert new["hash"] != old["hash"] and new["cycles.vertex"] > old["cycles.vertex"]

    sphere_scene(tmp_path, n_seg=16, n_rings=8)  # the same scene file, another mesh
    finer = again()
    assert (finer.ok, finer.skipped, finer.renders) == (2, 0, 1)
    assert finer.rows[0]["cycles.vertex"] != slower.rows[0]["cycles.vertex"]

    sphere_scene(tmp_path, albedo=0.7, n_seg=16, n_rings=8)  # the same mesh, another material
    grey = again()
    assert (grey.ok, grey.skipped, grey.renders) == (2, 0, 1)
    assert len({r["hash"] for r in first.rows + slower.rows + finer.rows + grey.rows}) == 8


def test_a_resumed_sweep_never_appends_to_a_torn_row(tmp_path, monkeypatch):
    path = sweep_file(tmp_path, grid={"arch.page_miss_cycles": [0, 12, 48]})
    out = tmp_path / "o"
    first = run_sweep(path, out, jobs=1)
    shutil.rmtree(out / "points" / first.rows[2]["hash"])
    lines = (out / "sweep.jsonl").read_text().splitlines(keepends=True)
    (out / "sweep.jsonl").write_text(lines[0] + lines[1][:25])  # killed while writing the second row
    seen = []
    monkeypatch.setattr(sweep_mod, "write_rows", lambda o, rows: seen.append((o / "sweep.jsonl").read_text()))
    done = run_sweep(path, out, jobs=1)
    assert (done.ok, done.skipped) == (1, 2)
    # what a sweep killed before its end leaves: whole rows, the torn one cut off (the rows
    # are also rewritten whole before the points run: the first call, not writing here)
    assert len(seen) == 2 and [json.loads(line)["point"] for line in seen[-1].splitlines()] == [0, 2]


@pytest.mark.slow
def test_a_killed_point_leaves_nothing_half_written(tmp_path, monkeypatch):
    path = sweep_file(tmp_path, grid={"arch.page_miss_cycles": [0, 12, 48, 96]})
    out = tmp_path / "o"
    timing_dict, calls = run_mod.timing_dict, []

    def interrupted(*a):
        calls.append(1)
        if len(calls) == 3:  # inside the third point's folder, after its config was written
            raise KeyboardInterrupt
        return timing_dict(*a)

    monkeypatch.setattr(run_mod, "timing_dict", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(path, out, jobs=1)
    assert len(jsonl(out / "sweep.jsonl")) == 2  # what finished is kept
    assert sorted(p.name for p in (out / "points").iterdir()) == sorted(r["hash"] for r in jsonl(out / "sweep.jsonl"))
    monkeypatch.setattr(run_mod, "timing_dict", timing_dict)
    done = run_sweep(path, out, jobs=1)
    assert (done.ok, done.skipped) == (2, 2)
    assert len(list((out / "points").iterdir())) == 4


def _stat(pid: int) -> list[str] | None:
    """The fields of /proc/<pid>/stat after the command name (state, ppid, ...), or None."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return text[text.rindex(")") + 2:].split()


def _descendants(pid: int) -> set[tuple[int, str]]:
    """The processes below ``pid``, as (pid, start time): a pid reused later is another process."""
    children: dict[int, list[tuple[int, str]]] = {}
    for d in Path("/proc").iterdir():
        fields = _stat(int(d.name)) if d.name.isdigit() else None
        if fields is not None:
            children.setdefault(int(fields[1]), []).append((int(d.name), fields[19]))
    found, todo = set(), [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            found.add(child)
            todo.append(child[0])
    return found


def _running(process: tuple[int, str]) -> bool:
    fields = _stat(process[0])
    return fields is not None and fields[19] == process[1] and fields[0] not in "ZX"


@pytest.mark.slow
def test_resume_after_a_killed_process(tmp_path, monkeypatch):
    """A sweep killed (SIGKILL) with two workers: its processes (the workers, the fork server)
    end soon after it instead of running the queued points, and a rerun resumes."""
    # the points' keys hold the code's hash: computed now, as the killed process did (not at
    # the session's start, before edits to the checkout since)
    monkeypatch.setattr(fingerprint, "_CODE", None)
    path = sweep_file(tmp_path, set={"arch.packet_size": 4}, grid={"arch.page_miss_cycles": list(range(0, 80, 10))})
    out = tmp_path / "o"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    linux = Path("/proc/self/stat").is_file()
    below: set[tuple[int, str]] = set()
    proc = subprocess.Popen([sys.executable, "-m", "tlm", "sweep", str(path), "--out", str(out), "--jobs", "2"],
                            cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            if linux:
                below |= _descendants(proc.pid)
            rows = out / "sweep.jsonl"
            if rows.exists() and rows.read_text().count("\n") >= 2:  # both workers started
                break
            time.sleep(0.01)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait()
    if linux:  # the workers (and with them the fork server and the resource tracker) end
        assert len(below) >= 3
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and any(map(_running, below)):
            time.sleep(0.05)
        assert not [p for p in below if _running(p)]
    # (a point's folder, not the temporary one of a point killed before its rename: it is not done)
    finished = {p.name for p in (out / "points").iterdir()
                if not p.name.startswith(".") and (p / "results.json").is_file()}
    assert 2 <= len(finished) < 8  # the kill came after the first points, before the last
    # what a point killed while writing its folder leaves: a temporary folder of a dead process
    stale = out / "points" / f".0123456789abcdef.tmp-{proc.pid}"
    stale.mkdir(exist_ok=True)
    (stale / "trace.json").write_text("[")
    done = run_sweep(path, out, jobs=1)
    assert done.skipped == len(finished) and done.ok == 8 - len(finished) and done.failed == 0
    assert sorted(p.name for p in (out / "points").iterdir()) == sorted(r["hash"] for r in done.rows)
    assert [r["point"] for r in jsonl(out / "sweep.jsonl")] == list(range(8))


@pytest.mark.slow
def test_photon_map_points_carry_the_image_error(tmp_path, cache):
    sphere_scene(tmp_path)
    base = {"scene": "furnace.yaml", "mode": "pmap", "photons": {"count": 3000},
            "estimate": {"radius_fraction": 0.06},
            "reference": {"photons": 3000, "k_nearest": 40, "tolerance": 0.2, "max_rounds": 4},
            "arch": {"frames": 2, "trace": False, "packet_size": 64}}
    (tmp_path / "run.yaml").write_text(yaml.safe_dump(base))
    assert main(["reference", str(tmp_path / "run.yaml")]) == 0
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": "run.yaml", "grid": {"estimate.filter": ["disk", "mvoxel"],
                                                                 "arch.page_miss_cycles": [0, 48]}},
                                   sort_keys=False))
    done = run_sweep(path, tmp_path / "o", jobs=1)
    assert done.renders == 2 and done.ok == 4
    for r in done.rows:
        assert 0 < r["error.rel_mse"] < 1 and 0 < r["error.rmse"] < 1
    by_filter = {r["estimate.filter"]: r["error.rmse"] for r in done.rows}
    assert by_filter["disk"] != by_filter["mvoxel"]
    # the sidecar kept the error for the points that read the frame from the cache
    assert done.rows[0]["error.rmse"] == done.rows[1]["error.rmse"]


def test_the_cache_sidecar(tmp_path, cache):
    cfg = config_from_dict({**BASE, "mode": "reflect"})
    fresh = cached_render(cfg)
    again = cached_render(cfg)
    assert not fresh.cached and again.cached and fresh.key == again.key
    assert again.summary == json.loads(json.dumps(fresh.summary))
    assert set(fresh.summary["work"]) == {"rcast", "reflect"}
    assert fresh.summary["scene"]["resolution"] == [24, 16] and fresh.summary["error"] is None
    # an entry without its sidecar (written before sidecars existed) is rendered again
    (cache_dir() / f"{fresh.key}.json").unlink()
    assert not cached_render(cfg).cached
    assert cached_render(cfg).cached
