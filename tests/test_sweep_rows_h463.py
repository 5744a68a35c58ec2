"""h463: a point with two rows in a sweep's ``sweep.jsonl`` is read once, its later row, by every reader of the file
(:func:`tlm.experiments.sweep_rows.one_row_each`, the rule of an interrupted sweep's count, :func:`rows_kept`):
``tlm report`` (:mod:`tlm.report.collect`: it listed the point twice, ``s #0`` and ``s #0 (2)``, and counted a
point not run as run), ``tlm scaling`` (a point fitted twice) and its out-of-date check. Two runs of one sweep
sharing its folder each append a row for a point both ran, and both killed (kill -9) leave the two rows; so does a
rerun cut short of a tlm of before cfdaf21, which appended after the earlier run's failed row.

And a signal while ``tlm sweep`` reads its sweep file and the points done before, before it claimed the folder,
says that no point ran and nothing was written (a bare ``tlm: interrupted`` before)."""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import pytest

import tlm.experiments.sweep as sweep_mod
from tlm.cli import main
from tlm.experiments import scaling
from tlm.experiments.scaling_dated import sweep_points
from tlm.experiments.sweep_rows import one_row_each, rows_kept
from tlm.report.collect import read

from .test_signals import rows, sweep_file

SAID = {signal.SIGINT: "tlm: interrupted", signal.SIGTERM: "tlm: terminated (SIGTERM)"}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _sweep(path: Path, out: Path) -> int:
    return main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-report", "--no-progress"])


def _lines(out: Path, rows_: list[dict]) -> None:
    (out / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows_), encoding="utf-8")


def test_each_point_once_its_last_row_where_its_first_was():
    a1, b, a2 = {"hash": "a", "status": "failed"}, {"hash": "b", "status": "ok"}, {"hash": "a", "status": "ok"}
    damaged = [{"hash": ["a"]}, {"hash": None}, {"hash": ["a"]}]  # (no hash's text: each kept, for its reader)
    assert one_row_each([a1, b, damaged[0], a2, *damaged[1:]]) == [a2, b, *damaged]
    pairs = [(1, a1), (2, b), (3, a2)]  # (read_jsonl's (line, row))
    assert one_row_each(pairs, lambda t: t[1]) == [(3, a2), (2, b)]


@pytest.fixture
def doubled(tmp_path) -> Path:
    """A sweep of 3 points as two runs of it sharing its folder, both killed, leave it: point 0's row twice (each
    run's), point 1's once, point 2 run by neither."""
    path, out = sweep_file(tmp_path, n=3), tmp_path / "s"
    assert _sweep(path, out) == 0
    done = rows(out)
    _lines(out, [done[0], done[1], {**done[0], "pid": 1}])
    return out


def test_the_report_reads_a_point_of_two_rows_once(doubled):
    inputs = read([doubled])
    sweep = inputs.sweeps[0]
    assert [r["point"] for r in sweep.rows] == [0, 1] and sweep.rows[0]["pid"] == 1  # (the later row)
    assert [r.label for r in inputs.runs] == ["s #0", "s #1"]  # ('s #0 (2)' too before)
    assert sweep.unfinished.startswith("; 1 of its 3 points not run yet")


def test_scaling_fits_a_point_of_two_rows_once(doubled):
    notes: list[str] = []
    records = scaling.collect(doubled, notes)
    assert sorted(r["hash"] for r in records) == sorted({r["hash"] for r in rows(doubled)})
    assert any("2 of its 3 points have a row" in n for n in notes), notes
    assert len(rows_kept(doubled, [r["hash"] for r in rows(doubled)])) == 2


def test_a_point_whose_later_row_failed_is_not_finished_for_every_reader(doubled):
    # (its earlier row ok, its folder's results.json there: the later run of it failed, and its row says so)
    first = rows(doubled)[0]
    _lines(doubled, [first, {**first, "status": "failed", "error": "RuntimeError: a stand-in failure"}])
    assert sweep_points(doubled)[1] == []  # (scaling's out-of-date check: it counted the point finished)
    assert [r["status"] for r in read([doubled]).sweeps[0].rows] == ["failed"]
    with pytest.raises(Exception, match="has no finished point"):
        scaling.collect(doubled)


def _signalled_in(monkeypatch, name: str, sig: int, call: int = 1) -> None:
    """The sweep module's ``name`` (a step of its reading, before it claims its folder) signals on its ``call``-th
    call, once it returned."""
    real, calls = getattr(sweep_mod, name), []

    def step(*args, **kwargs):
        got = real(*args, **kwargs)
        calls.append(1)
        if len(calls) == call:
            os.kill(os.getpid(), sig)
        return got

    monkeypatch.setattr(sweep_mod, name, step)


@pytest.mark.parametrize(("sig", "step"), [(signal.SIGINT, "load_sweep"), (signal.SIGTERM, "load_sweep"),
                                           (signal.SIGINT, "open_executor")],
                         ids=["SIGINT", "SIGTERM", "workers-starting"])
def test_a_signal_while_the_sweep_file_is_read_says_nothing_was_written(sig, step, tmp_path, monkeypatch, capsys):
    # (its workers starting, the folder not claimed yet: 'before any point finished' before, true, but not that the
    # folder was not even made)
    path, out = sweep_file(tmp_path, n=3), tmp_path / "o"
    _signalled_in(monkeypatch, step, sig)
    assert _sweep(path, out) == 128 + sig
    assert capsys.readouterr().err.strip().splitlines()[-1] == f"{SAID[sig]} before any point ran: nothing was written"
    assert not out.exists()


def test_a_signal_while_a_rerun_reads_the_points_done_leaves_the_folder_as_it_was(tmp_path, monkeypatch, capsys):
    path, out = sweep_file(tmp_path, n=3), tmp_path / "o"
    assert _sweep(path, out) == 0
    before = {p: (p.stat().st_ino, p.stat().st_mtime_ns) for p in out.rglob("*")}
    capsys.readouterr()
    _signalled_in(monkeypatch, "point_done", signal.SIGINT, call=2)
    assert _sweep(path, out) == 128 + signal.SIGINT
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert line == "tlm: interrupted before any point ran: nothing was written"
    assert {p: (p.stat().st_ino, p.stat().st_mtime_ns) for p in out.rglob("*")} == before
