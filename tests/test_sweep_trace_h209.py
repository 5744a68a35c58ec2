"""A sweep's points keep the timing model's trace and write ``trace.json`` only where the sweep asks for it
(``arch.trace: true`` in its base, a base config file, ``set``, a factor or ``tlm sweep --set``): a default
sweep simulates every point with the trace off and writes none (h209). A point's hash holds ``arch.trace`` as
true whatever it runs with (a default sweep's hashes are HEAD's), so asking for a trace, or no longer, runs
again only the points done without the trace.json they now ask for; ``--dry-run`` counts them so. Each point's
``config.resolved.yaml`` records the ``arch.trace`` it ran with."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import tlm.arch.model as model
from tlm.cli import main
from tlm.config import config_from_dict, to_dict
from tlm.experiments.sweep import run_sweep
from tlm.experiments.sweep_file import config_hash, load_sweep, point_inputs

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
    assert {k: plan[k] for k in ("points", "done", "to_run", "replaced", "untraced")} == {
        "points": 3, "done": 2, "to_run": 1, "replaced": 1, "untraced": 1}
    assert main(["sweep", str(sweep), "--out", str(out), "--set", "arch.trace=true", "--dry-run"]) == 0
    assert ("1 point folder of points done without the trace.json they ask for (arch.trace) removed and run again"
            in capsys.readouterr().out)
    done = run_sweep(sweep, out, jobs=1, overrides=["arch.trace=true"])
    assert (done.skipped, done.ok) == (2, 1) and traced[3:] == [True]
    third = _ran(out)
    assert {h: third[h] for h in first} == first and third[new][:2] == (True, True)
