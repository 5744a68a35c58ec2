"""An interrupted ``tlm sweep`` says how many of its points it finished and kept in its folder, and that the
same command goes on (h450). Before, its line was a bare ``tlm: interrupted`` (``tlm: terminated (SIGTERM)``),
though the points done were kept and a rerun resumed them: the user was not told. The numbers are the rows
in the folder's ``sweep.jsonl``, those of an earlier run counted; a point that failed is counted and said."""

from __future__ import annotations

import os
import signal

import pytest

import tlm.experiments.sweep as sweep_mod
from tlm.cli import main

from .test_signals import rows, sweep_file

SAID = {signal.SIGINT: "tlm: interrupted", signal.SIGTERM: "tlm: terminated (SIGTERM)"}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _sweep(path, out) -> int:
    return main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-report", "--no-progress"])


def _signalled_at(monkeypatch, point: int, sig: int, fails: tuple[int, ...] = ()) -> list:
    """Each point the sweep runs (in this process: --jobs 1) counted; the ``point``-th (from 1) is signalled as
    it begins (its interrupt raised there: it does not finish), those in ``fails`` fail."""
    real, began = sweep_mod.run_point, []

    def run_point(task):
        began.append(task.hash)
        if len(began) == point:
            os.kill(os.getpid(), sig)
        if len(began) in fails:
            raise RuntimeError("a stand-in failure")
        return real(task)

    monkeypatch.setattr(sweep_mod, "run_point", run_point)
    return began


def _last(capsys) -> str:
    return capsys.readouterr().err.strip().splitlines()[-1]


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_the_line_counts_the_points_kept_those_of_an_earlier_run_too(sig, tmp_path, monkeypatch, capsys):
    path, out = sweep_file(tmp_path, n=5), tmp_path / "o"
    _signalled_at(monkeypatch, 3, sig)
    assert _sweep(path, out) == 128 + sig
    line = f"{SAID[sig]} with 2 of 5 points finished and kept in {out}; run the same command to go on"
    assert _last(capsys) == line
    assert len(rows(out)) == 2
    _signalled_at(monkeypatch, 2, sig)  # (the rerun: one more point, then the signal)
    assert _sweep(path, out) == 128 + sig
    assert _last(capsys) == line.replace("with 2 of 5", "with 3 of 5")
    assert len(rows(out)) == 3 and {r["status"] for r in rows(out)} == {"ok"}
    monkeypatch.undo()
    assert _sweep(path, out) == 0  # (the same command goes on: the two points left)
    assert "5 points: 2 ok, 0 failed, 3 skipped" in capsys.readouterr().out


def test_a_sweep_interrupted_before_any_point_finished_says_so(tmp_path, monkeypatch, capsys):
    path, out = sweep_file(tmp_path, n=3), tmp_path / "o"
    _signalled_at(monkeypatch, 1, signal.SIGINT)
    assert _sweep(path, out) == 130
    assert capsys.readouterr().err.strip() == "tlm: interrupted before any point finished"
    assert rows(out) == []


def test_the_line_says_how_many_of_the_points_kept_failed(tmp_path, monkeypatch, capsys):
    path, out = sweep_file(tmp_path, n=5), tmp_path / "o"
    _signalled_at(monkeypatch, 4, signal.SIGTERM, fails=(2,))
    assert _sweep(path, out) == 143
    assert _last(capsys) == (f"tlm: terminated (SIGTERM) with 3 of 5 points finished (1 failed, to run again) and "
                             f"kept in {out}; run the same command to go on")
    assert sorted(r["status"] for r in rows(out)) == ["failed", "ok", "ok"]


def test_a_sweep_interrupted_as_its_workers_start_counts_the_points_an_earlier_run_kept(tmp_path, monkeypatch,
                                                                                        capsys):
    """Before the sweep claimed its folder (its executor starting): its rows are the earlier run's."""
    path, out = sweep_file(tmp_path, n=4), tmp_path / "o"
    _signalled_at(monkeypatch, 3, signal.SIGINT)
    assert _sweep(path, out) == 130
    capsys.readouterr()
    monkeypatch.undo()
    real = sweep_mod.open_executor

    def open_executor(*a, **k):
        os.kill(os.getpid(), signal.SIGTERM)
        return real(*a, **k)

    monkeypatch.setattr(sweep_mod, "open_executor", open_executor)
    assert _sweep(path, out) == 143
    assert _last(capsys) == (f"tlm: terminated (SIGTERM) with 2 of 4 points finished and kept in {out}; "
                             "run the same command to go on")
    assert len(rows(out)) == 2
