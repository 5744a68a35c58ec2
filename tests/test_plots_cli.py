"""tlm plots: --only given more than once, and a step whose exit status 1 is a result."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import tlm.cli
from tlm.arch.units import Deadlock
from tlm.cli import build_parser, main
from tlm.report import regenerate as plots_module
from tlm.report.regenerate import STEPS, regenerate

# a case that differs from its expectation, without rendering: 'tlm extreme' exits 1
EXTREME = {"description": "one case that differs from its expectation",
           "base": {"resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
                    "arch": {"frames": 2, "trace": False}},
           "cases": [{"name": "bad-resolution", "category": "bad input", "expect": "a message it does not give",
                      "config": {"scene": "cornell", "mode": "rcast", "resolution": [0, 16]},
                      "checks": [{"error": "this text is not in the message"}]}]}


def _configs(tmp_path: Path, **files: dict) -> Path:
    folder = tmp_path / "configs"
    folder.mkdir()
    for name, content in files.items():
        (folder / f"{name}.yaml").write_text(yaml.safe_dump(content, sort_keys=False))
    return folder


def _plots(tmp_path: Path, configs: Path, *only: str) -> int:
    return main(["plots", "--configs", str(configs), "--runs", str(tmp_path / "runs"), "--out",
                 str(tmp_path / "plots"), *[a for s in only for a in ("--only", s)]])


def _stale(tmp_path: Path) -> Path:
    """A report left by an earlier 'tlm plots'."""
    (tmp_path / "plots").mkdir()
    (tmp_path / "plots" / "report.html").write_text("stale")
    return tmp_path / "plots" / "report.html"


# ------------------------------------------------------------------ 4: --only given more than once


def test_only_given_twice_runs_both(monkeypatch):
    assert build_parser().parse_args(["plots", "--only", "thesis", "--only", "tlm_granularity"]).only == [
        "thesis", "tlm_granularity"]
    seen = []
    monkeypatch.setattr(tlm.api, "plots", lambda configs, runs, out, only, **kw: seen.append(only) or Path("p"))
    assert main(["plots", "--only", "thesis", "extreme", "--only", "tlm_granularity", "--only", "thesis"]) == 0
    assert seen == [["thesis", "extreme", "tlm_granularity"]]


# ------------------------------------------------------------------ 5: exit status 1 is a result


def test_a_step_that_exits_1_is_said_and_the_rest_and_the_report_still_run(tmp_path, monkeypatch):
    called, said, built = [], [], []

    def run(argv):
        called.append(argv[0])
        return 1 if argv[0] in ("thesis", "granularity") else 0

    monkeypatch.setattr("tlm.report.build_report", lambda dirs, out, *a, **kw: built.append(dirs) or out / "r.html")
    (tmp_path / "extreme").mkdir()
    with pytest.raises(plots_module.StepsFailed) as e:
        regenerate(Path("configs"), tmp_path, tmp_path / "plots", run_command=run, say=said.append)
    assert called == [argv[0] for _, argv in STEPS]  # every step, after the failures too
    assert built == [[tmp_path / "extreme"]]
    assert e.value.steps == ["thesis", "tlm_granularity"] and e.value.page == tmp_path / "plots" / "r.html"
    assert "steps thesis, tlm_granularity reported failures (exit status 1" in str(e.value)
    assert "== thesis: exit status 1 (its results report failures, see above); the other steps and the report " \
           "still run" in said


def test_extreme_that_differs_exits_1_after_writing_the_report(tmp_path, capsys):
    configs = _configs(tmp_path, extreme=EXTREME)
    stale = _stale(tmp_path)
    assert _plots(tmp_path, configs, "extreme") == 1
    out, err = capsys.readouterr()
    assert "FAIL" in out and f"wrote {stale}" in out
    assert "reported failures" not in out and "tlm: error" not in err
    assert err.strip().splitlines()[-1].startswith("tlm: plots: step extreme reported failures (exit status 1")
    assert stale.read_text().startswith("<!DOCTYPE html>")  # the report of this run, not the stale one


def test_a_deadlock_of_a_step_is_a_result(tmp_path, capsys, monkeypatch):
    def deadlock(args):
        raise Deadlock("pipe0.vertex waits for a job")

    monkeypatch.setattr(tlm.cli, "_cmd_run", deadlock)
    configs = _configs(tmp_path, extreme=EXTREME)
    assert _plots(tmp_path, configs, "cornell_pmap", "extreme") == 1
    err = capsys.readouterr().err
    assert "tlm: deadlock: pipe0.vertex waits for a job" in err
    assert "steps cornell_pmap, extreme reported failures" in err
    assert (tmp_path / "plots" / "report.html").is_file()


def test_bad_input_to_a_step_stops_it_naming_the_step(tmp_path, capsys):
    configs = _configs(tmp_path)  # no extreme.yaml
    stale = _stale(tmp_path)
    assert _plots(tmp_path, configs, "extreme") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tlm: error: tlm plots: step extreme stopped on bad input: "), err
    assert "extreme.yaml" in err[0]
    assert stale.read_text() == "stale"


def test_an_internal_error_of_a_step_stops_it(tmp_path, capsys, monkeypatch, cache):
    def bug(args):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(tlm.cli, "_cmd_run", bug)
    configs = _configs(tmp_path, extreme=EXTREME)
    assert _plots(tmp_path, configs, "cornell_pmap", "extreme") == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tlm: internal error: ZeroDivisionError: a bug"), err
    assert not (tmp_path / "runs" / "extreme").exists()  # the steps after it did not run
    assert not (tmp_path / "plots").exists()


@pytest.mark.slow
def test_a_sweep_with_a_failed_point_and_extreme_both_run(tmp_path, capsys, cache):
    """The sweep exits 1 (its N = 2 point deadlocks), extreme runs after it, the report is
    written, and tlm plots exits 1 naming both steps."""
    configs = _configs(tmp_path, extreme=EXTREME, sweep_fifo={
        "base": {"scene": "cornell", "mode": "rcast", "resolution": [16, 16],
                 "render": {"light_samples": 1, "spp": 1}, "arch": {"frames": 2, "trace": False}},
        "zip": {"arch.pipelines": [1, 2], "arch.max_events": [200_000_000, 20]}})
    stale = _stale(tmp_path)
    assert _plots(tmp_path, configs, "sweep_fifo", "extreme") == 1
    out, err = capsys.readouterr()
    assert "1 ok, 1 failed" in out and "1 cases: 0 as expected" in out
    assert "steps sweep_fifo, extreme reported failures" in err
    assert stale.read_text().startswith("<!DOCTYPE html>")
    assert (tmp_path / "runs" / "sweep_fifo" / "sweep.jsonl").is_file()


# ------------------------------------------------------------------ a stopped run's report folder


def test_bad_input_says_the_report_left_in_out_is_an_earlier_one(tmp_path, capsys):
    """A step stopped on bad input writes no report: the report an earlier 'tlm plots' left in
    --out stays as it was (nothing of it is removed), and the one error line says it is that
    earlier one, with its date, not of this run."""
    configs = _configs(tmp_path)  # no extreme.yaml
    stale = _stale(tmp_path)
    assert _plots(tmp_path, configs, "extreme") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tlm: error: tlm plots: step extreme stopped on bad input: "), err
    assert err[0].endswith(f"; no report written: {stale} is the report of an earlier 'tlm plots' (written "
                           f"{_written(stale)}), not of this one"), err[0]
    assert stale.read_text() == "stale"


def _written(page: Path) -> str:
    import datetime

    return datetime.datetime.fromtimestamp(page.stat().st_mtime).isoformat(sep=" ", timespec="seconds")


def test_the_steps_that_ran_before_the_bad_input_are_named(tmp_path):
    def run(argv):
        if argv[0] == "granularity":
            raise plots_module.InputError("a bad packet size", source="g.yaml", key="packet_sizes")
        return 0

    def plots():
        with pytest.raises(plots_module.InputError) as e:
            regenerate(Path("configs"), tmp_path / "runs", tmp_path / "plots", ["thesis", "eq52", "tlm_granularity"],
                       run_command=run, say=lambda line: None)
        return str(e.value)

    (tmp_path / "runs" / "scaling_ring").mkdir(parents=True)  # (eq52 fits the scaling folders there: one)
    (tmp_path / "runs" / "scaling_ring" / "sweep.jsonl").write_text("")  # (a folder without it holds no sweep)
    bad = "tlm plots: step tlm_granularity stopped on bad input: g.yaml: packet_sizes: a bad packet size"
    assert plots() == bad  # (no earlier report: nothing more to say)
    stale = _stale(tmp_path)
    assert plots() == (f"{bad}; no report written: {stale} is the report of an earlier 'tlm plots' (written "
                       f"{_written(stale)}), not of this one; the steps that ran before it (thesis, eq52) have "
                       "rewritten their folders since")


def test_an_internal_error_says_the_report_left_in_out_is_an_earlier_one(tmp_path, capsys, monkeypatch, cache):
    def bug(args):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(tlm.cli, "_cmd_run", bug)
    stale = _stale(tmp_path)
    assert _plots(tmp_path, _configs(tmp_path), "cornell_pmap") == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == (f"tlm: plots: no report written: {stale} is the report of an earlier 'tlm plots' (written "
                      f"{_written(stale)}), not of this one"), err
    assert err[1].startswith("tlm: internal error: ZeroDivisionError: a bug") and len(err) == 2
    assert stale.read_text() == "stale"
