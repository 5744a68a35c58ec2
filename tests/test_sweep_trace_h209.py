"""A sweep's points keep the timing model's trace and write ``trace.json`` only where the sweep asks for it
(``arch.trace: true`` in its base, a base config file, ``set``, a factor or ``tlm sweep --set``): a default
sweep simulates every point with the trace off and writes none (h209). A point's hash holds ``arch.trace`` as
true whatever it runs with (a default sweep's hashes are HEAD's), so asking for a trace, or no longer, runs
again only the points done without the trace.json they now ask for; ``--dry-run`` counts them so. Each point's
``config.resolved.yaml`` records the ``arch.trace`` it ran with."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml

import tlm.arch.model as model
from tlm import claims
from tlm.cli import main
from tlm.config import config_from_dict, to_dict
from tlm.errors import InputError
from tlm.experiments.sweep import run_sweep
from tlm.experiments.sweep_file import config_hash, load_sweep, point_inputs
from tlm.experiments.sweep_plan import plan_sweep

# no arch.trace: tlm run's default (true) is not a sweep's
BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 1, "packet_size": 32}}
GRID = {"arch.fifo_depth": [1, 16]}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _sweep(folder: Path, name: str = "s.yaml", base=BASE, grid=GRID, **more) -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump({"base": base, **more, "grid": grid}, sort_keys=False))
    return path


def _arch(config: dict, **changes) -> dict:
    return {**config, "arch": {**config["arch"], **changes}}


def _ran(out: Path) -> dict[str, tuple[bool, bool, int]]:
    """Each point folder: (its config.resolved.yaml's arch.trace, whether trace.json is there, results.json's mtime)."""
    return {p.name: (yaml.safe_load((p / "config.resolved.yaml").read_text())["arch"]["trace"],
                     (p / "trace.json").is_file(), (p / "results.json").stat().st_mtime_ns)
            for p in sorted((out / "points").iterdir())}


@pytest.fixture
def traced(monkeypatch) -> list[bool]:
    """The arch.trace of every simulation run in this process (the sweeps below run their points in it)."""
    seen: list[bool] = []
    real = model.simulate

    def spy(functional, programs, arch, *args, **kwargs):
        seen.append(arch.trace)
        return real(functional, programs, arch, *args, **kwargs)

    monkeypatch.setattr(model, "simulate", spy)
    return seen


def test_a_default_sweep_simulates_without_the_trace_and_writes_no_trace_json(tmp_path, traced):
    out = tmp_path / "out"
    done = run_sweep(_sweep(tmp_path), out, jobs=1)
    assert done.ok == 2 and done.failed == 0
    assert traced == [False, False]  # (the timing model kept no trace: faster too)
    ran = _ran(out)
    assert len(ran) == 2 and all(trace is False and not written for trace, written, _ in ran.values())
    assert not list(out.rglob("trace.json"))


@pytest.mark.slow
@pytest.mark.parametrize("how", ["base", "base file", "set", "set section", "--set", "factor"])
def test_a_sweep_that_asks_for_arch_trace_writes_trace_json(tmp_path, traced, how):
    """Each way of asking for a trace: the points of a default sweep into the folder before (their hashes
    the same) run again, with the trace, and write trace.json."""
    out = tmp_path / "out"
    assert run_sweep(_sweep(tmp_path, "default.yaml"), out, jobs=1).ok == 2
    before = _ran(out)
    path, overrides = tmp_path / "s.yaml", []
    if how == "base":
        path = _sweep(tmp_path, base=_arch(BASE, trace=True))
    elif how == "base file":
        (tmp_path / "run.yaml").write_text(yaml.safe_dump(_arch(BASE, trace=True)))
        path = _sweep(tmp_path, base="run.yaml")
    elif how == "set":
        path = _sweep(tmp_path, set={"arch.trace": True})
    elif how == "set section":
        path = _sweep(tmp_path, set={"arch": {"trace": True}})
    elif how == "--set":
        path, overrides = _sweep(tmp_path), ["arch.trace=true"]
    else:
        path = _sweep(tmp_path, grid={"arch.trace": [True], "arch.fifo_depth": [1, 16]})
    done = run_sweep(path, out, jobs=1, overrides=overrides)
    assert (done.skipped, done.ok) == (0, 2) and traced == [False, False, True, True]
    ran = _ran(out)
    assert set(ran) == set(before) and all(trace is True and written for trace, written, _ in ran.values())


def test_a_factor_over_arch_trace_traces_its_points_of_true_alone(tmp_path):
    """``grid: {arch.trace: [false, true]}``: two points each (their hashes as HEAD's: the value each runs with),
    a trace for those of true; a factor over the ``arch`` section that names it for some values only: those."""
    sweep = load_sweep(_sweep(tmp_path, grid={"arch.trace": [False, True], "arch.fifo_depth": [1, 16]}))
    assert [p.config["arch"]["trace"] for p in sweep.points] == [False, False, True, True]
    assert len({p.hash for p in sweep.points}) == 4
    for p in sweep.points:  # (tlm run's resolved config of the point, its arch.trace the factor's)
        cfg = config_from_dict(p.config, "point")
        assert p.hash == config_hash(to_dict(cfg), point_inputs(cfg, tmp_path, "point"), tmp_path)
    mixed = load_sweep(_sweep(tmp_path, name="m.yaml", grid={"arch": [{"fifo_depth": 1}, {"fifo_depth": 1,
                                                                                          "trace": True}]}))
    assert [p.config["arch"]["trace"] for p in mixed.points] == [False, True]
    assert len({p.hash for p in mixed.points}) == 2


def test_a_default_sweeps_point_hashes_are_heads_and_arch_trace_changes_none(tmp_path, monkeypatch):
    """A default sweep's point hash is HEAD's (its resolved config with tlm run's arch.trace, true, keyed by
    config_hash); a sweep that writes arch.trace, true or false, in its base, ``set`` or a ``--set`` has the
    same hashes (HEAD's of arch.trace false differed), each point's config the arch.trace it runs with."""
    monkeypatch.chdir(tmp_path)
    default = load_sweep(_sweep(tmp_path))
    assert [p.config["arch"]["trace"] for p in default.points] == [False, False]
    for p in default.points:
        cfg = config_from_dict(_arch(p.config, trace=True), "point")  # (as tlm run resolves it: trace true)
        assert p.hash == config_hash(to_dict(cfg), point_inputs(cfg, tmp_path, "point"), tmp_path)
    hashes = [p.hash for p in default.points]
    for name, body, overrides, trace in [
            ("f.yaml", {"set": {"arch.trace": False}}, [], False),
            ("t.yaml", {"set": {"arch.trace": True}}, [], True),
            ("b.yaml", {"base": _arch(BASE, trace=False)}, [], False),
            ("o.yaml", {}, ["arch.trace=true"], True),
            ("n.yaml", {}, ["arch.trace=false"], False)]:
        sweep = load_sweep(_sweep(tmp_path, name, **body), overrides)
        assert [p.hash for p in sweep.points] == hashes, name
        assert [p.config["arch"]["trace"] for p in sweep.points] == [trace, trace], name


@pytest.mark.slow
def test_asking_for_a_trace_runs_again_only_the_points_done_without_one(tmp_path, traced, capsys):
    out = tmp_path / "out"
    traced_sweep = _sweep(tmp_path, "t.yaml", set={"arch.trace": True})
    assert run_sweep(traced_sweep, out, jobs=1).ok == 2
    first = _ran(out)
    assert all(written for _, written, _ in first.values())
    # no trace asked, one point more: the two done (with a trace they no longer ask for) are skipped
    more = {"arch.fifo_depth": [1, 16, 256]}
    done = run_sweep(_sweep(tmp_path, "d.yaml", grid=more), out, jobs=1)
    assert (done.skipped, done.ok) == (2, 1) and traced == [True, True, False]
    second = _ran(out)
    assert {h: second[h] for h in first} == first  # (not run again: their trace.json kept)
    (new,) = set(second) - set(first)
    assert second[new][:2] == (False, False)
    # arch.trace: false written: the same points, all done
    done = run_sweep(_sweep(tmp_path, "f.yaml", grid=more, set={"arch.trace": False}), out, jobs=1)
    assert (done.skipped, done.ok) == (3, 0) and _ran(out) == second
    # a trace asked again (--set): the dry run and the sweep run the one point done without its trace.json
    sweep = _sweep(tmp_path, "d.yaml", grid=more)
    assert main(["sweep", str(sweep), "--out", str(out), "--set", "arch.trace=true", "--dry-run", "--json"]) == 0
    plan = yaml.safe_load(capsys.readouterr().out)
    assert {k: plan[k] for k in ("points", "done", "to_run", "replaced", "kept", "untraced")} == {
        "points": 3, "done": 2, "to_run": 1, "replaced": 0, "kept": 1, "untraced": 1}  # (kept until replaced)
    assert main(["sweep", str(sweep), "--out", str(out), "--set", "arch.trace=true", "--dry-run"]) == 0
    assert ("1 point folder of points done without the trace.json they ask for (arch.trace) run again, each kept "
            "until its new folder replaces it" in capsys.readouterr().out)
    done = run_sweep(sweep, out, jobs=1, overrides=["arch.trace=true"])
    assert (done.skipped, done.ok) == (2, 1) and traced[3:] == [True]
    third = _ran(out)
    assert {h: third[h] for h in first} == first and third[new][:2] == (True, True)


# --- h218: a review's findings (--reference with a trace, an interrupted traced rerun, a traced and an untraced
# sweep into one folder at once)

PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "photons": {"count": 1500},
        "render": {"light_samples": 1}, "estimate": {"final_gather": 0}, "arch": {"frames": 1, "packet_size": 32},
        "reference": {"photons": 1500, "k_nearest": 20, "min_rounds": 4, "max_rounds": 64, "spp": 2,
                      "tolerance": 0.5}}


def _errors(out: Path) -> dict[str, bool | None]:
    return {p.name: (json.loads((p / "results.json").read_text()).get("error") or {}).get("available")
            for p in (out / "points").iterdir()}


@pytest.mark.slow
def test_reference_computes_what_points_run_again_for_their_trace_need(tmp_path, cache):
    """--reference decides a point done as the sweep does (point_done): after the reference cache is pruned, a
    rerun that asks for a trace runs its points again and computes the reference they are measured against, as
    its dry run says (before, it computed none and the points came back without their error)."""
    out = tmp_path / "out"
    sweep = _sweep(tmp_path, base=PMAP)
    assert run_sweep(sweep, out, jobs=1, reference=True).ok == 2
    assert set(_errors(out).values()) == {True}
    shutil.rmtree(cache / "references")  # (a tlm cache prune)
    plan = plan_sweep(sweep, out, jobs=1, overrides=["arch.trace=true"], reference=True)
    assert [r.action for r in plan.references] == ["compute"] and plan.untraced == 2
    said: list[str] = []
    done = run_sweep(sweep, out, jobs=1, reference=True, overrides=["arch.trace=true"], say=said.append,
                     warn=said.append)
    assert done.ok == 2 and any("computing reference 1 of 1" in line for line in said), said
    assert set(_errors(out).values()) == {True}, said
    assert not any("no photon-map error" in line for line in said), said
    assert all(written for _, written, _ in _ran(out).values())


def test_an_interrupt_while_points_run_again_for_their_trace_loses_no_point_done(tmp_path, monkeypatch):
    """Asking for a trace runs again the points done without one; each stays (with a user's file in it) until its
    new folder replaces it, so an interrupt meanwhile loses none, and the file is carried into the new folder."""
    out = tmp_path / "out"
    sweep = _sweep(tmp_path, grid={"arch.fifo_depth": [1, 2, 4, 8]})
    assert run_sweep(sweep, out, jobs=1).ok == 4
    before = _ran(out)
    for h in before:
        (out / "points" / h / "notes.md").write_text(f"mine {h}")
    real, calls = model.simulate, []

    def stopped(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(model, "simulate", stopped)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(sweep, out, jobs=1, overrides=["arch.trace=true"])
    after = _ran(out)
    assert set(after) == set(before)  # (every point done is still there: one of them now with its trace)
    assert sorted(written for _, written, _ in after.values()) == [False, False, False, True]
    assert {h: after[h] for h in after if not after[h][1]} == {h: before[h] for h in after if not after[h][1]}
    assert all((out / "points" / h / "notes.md").read_text() == f"mine {h}" for h in before)
    rows = [json.loads(line) for line in (out / "sweep.jsonl").read_text().splitlines()]
    assert sorted(r["hash"] for r in rows) == sorted(before)  # (the rows of the sweep cut short: every point's)
    monkeypatch.setattr(model, "simulate", real)
    done = run_sweep(sweep, out, jobs=1)  # (the trace given up: all done)
    assert (done.skipped, done.ok, done.failed) == (4, 0, 0)


def test_a_point_that_fails_to_run_again_for_its_trace_keeps_its_results(tmp_path, monkeypatch):
    """A point done without a trace that fails as it runs again for one: its folder keeps its results, and its
    error.json, the whole message its row points to (traceback and all), is written beside them (h224). A later
    sweep still runs it again for its trace; the folder that then replaces it holds no error.json (not carried
    over as a user's file), the user's own file is."""
    out = tmp_path / "out"
    sweep = _sweep(tmp_path)
    assert run_sweep(sweep, out, jobs=1).ok == 2
    before = _ran(out)
    for h in before:
        (out / "points" / h / "notes.md").write_text(f"mine {h}")
    real = model.simulate

    message = "no memory for the trace; " + "; ".join(f"unit{i} blocked" for i in range(200))  # (cut in its row)

    def fails(*args, **kwargs):
        raise RuntimeError(message)

    monkeypatch.setattr(model, "simulate", fails)
    done = run_sweep(sweep, out, jobs=1, overrides=["arch.trace=true"])
    assert (done.ok, done.failed) == (0, 2)
    assert all("no memory for the trace" in str(r["error"]) for r in done.rows), done.rows
    assert _ran(out) == before
    rows = [json.loads(line) for line in (out / "sweep.jsonl").read_text().splitlines()]
    for row in rows:  # (where the row says the whole message is)
        where = row["error"].rsplit("the whole message: ", 1)[1].rstrip(")")
        error = json.loads((out / where).read_text())
        assert error["hash"] == row["hash"] and error["message"] == message
        assert "Traceback" in error["traceback"] and "RuntimeError" in error["traceback"]
    plan = plan_sweep(sweep, out, overrides=["arch.trace=true"])
    assert (plan.to_run, plan.untraced) == (2, 2)  # (still to run again for its trace)
    monkeypatch.setattr(model, "simulate", real)
    again = run_sweep(sweep, out, jobs=1, overrides=["arch.trace=true"])
    assert (again.skipped, again.ok, again.failed) == (0, 2, 0)
    assert not list(out.rglob("error.json"))
    assert all(written for _, written, _ in _ran(out).values())
    assert all((out / "points" / h / "notes.md").read_text() == f"mine {h}" for h in before)


def test_a_remote_worker_s_point_run_again_is_not_taken_for_the_old_folder(tmp_path):
    """A remote Dask worker's record (sweep._seen_here): a point run again keeps its old folder, whose
    results.json is not the worker's; a worker that wrote where this machine does not see has its ok record
    failed all the same (h224). The worker's own results.json (a shared disk) is taken; an error.json of an
    earlier try is replaced by the worker's error."""
    from types import SimpleNamespace

    from tlm.experiments.sweep import _seen_here

    out = tmp_path / "out"
    assert run_sweep(_sweep(tmp_path), out, jobs=1).ok == 2
    folder = sorted((out / "points").iterdir())[0]
    task = SimpleNamespace(out=str(folder), hash=folder.name, factors={}, config={})
    old = json.loads((folder / "results.json").read_text())
    new = {**old, "host_seconds": {**old["host_seconds"], "write": old["host_seconds"]["write"] + 1.0}}
    remote = {"status": "ok", "results": new, "worker": "tcp://10.0.0.9:1234"}
    seen = _seen_here(remote, task)
    assert seen["status"] == "failed" and "does not see" in seen["error"]["message"], seen
    assert json.loads((folder / "results.json").read_text()) == old  # (the old results kept)
    assert json.loads((folder / "error.json").read_text())["type"] == "PathNotOnWorker"
    shared = {"status": "ok", "results": old, "worker": "tcp://10.0.0.9:1234"}
    assert _seen_here(shared, task) is shared  # (the worker's own file, seen here)
    error = {"type": "RuntimeError", "message": "no memory (on tcp://10.0.0.9:1234)", "stage": "simulate",
             "traceback": "Traceback ..."}
    assert _seen_here({"status": "failed", "error": error}, task)["status"] == "failed"
    assert json.loads((folder / "error.json").read_text()) == {"hash": folder.name, "factors": {}, **error}


def test_a_traced_and_an_untraced_sweep_of_the_same_points_do_not_share_a_folder(tmp_path):
    """Their points' hashes are one (arch.trace keyed as true), but each would replace the other's points: the
    sweep's identity, which the folder's claim compares (tlm.claims.sharing), tells them apart, so the second is
    refused while the first runs there."""
    plain, traced = _sweep(tmp_path, "d.yaml"), _sweep(tmp_path, "t.yaml", set={"arch.trace": True})
    assert [p.hash for p in load_sweep(plain).points] == [p.hash for p in load_sweep(traced).points]
    assert load_sweep(plain).identity() != load_sweep(traced).identity()
    assert load_sweep(plain).identity() == load_sweep(plain, ["arch.trace=false"]).identity()
    assert load_sweep(traced).identity() == load_sweep(plain, ["arch.trace=true"]).identity()
    out = tmp_path / "out"
    assert run_sweep(plain, out, jobs=1).ok == 2
    running = load_sweep(plain, ["arch.trace=true"]).identity()  # (a traced sweep of them, running into the folder)
    with claims.sharing(out, running, "sweep"), pytest.raises(InputError, match="another sweep of other points"):
        run_sweep(plain, out, jobs=1)
