"""h471: two runs of one sweep sharing its folder (the folder claim lets them cooperate) write its ``sweep.jsonl``
under one lock (:func:`tlm.experiments.sweep_rows.rows_held`). One run's rewrite of the file (an atomic rename) left
the other appending to the file it replaced (its handle, open for the whole sweep): its rows vanished from
``sweep.jsonl`` till it ended, and for good where it was killed. Each point's rows are now appended to the file the
path names then (:class:`~tlm.experiments.sweep_rows.Appender`), and a rewrite keeps the rows of the points the other
run finished since this one read the folder."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

import tlm.experiments.sweep as sweep_mod
from tlm.cli import main
from tlm.experiments import sweep_rows

from .test_signals import rows, sweep_file


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _sweep(path: Path, out: Path) -> int:
    return main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-report", "--no-progress"])


def _hashes(out: Path) -> list[str]:
    text = (out / "sweep.jsonl").read_text(encoding="utf-8")
    return [json.loads(line)["hash"] for line in text.splitlines(keepends=True) if line.endswith("\n")]


def _calls(monkeypatch, before) -> None:
    """``before(n)`` ahead of the sweep's n-th point run (in this process: --jobs 1)."""
    real, n = sweep_mod.run_point, []

    def run_point(task):
        n.append(1)
        before(len(n))
        return real(task)

    monkeypatch.setattr(sweep_mod, "run_point", run_point)


def test_a_row_appended_after_another_runs_rewrite_is_in_the_file(tmp_path, monkeypatch):
    path, out = sweep_file(tmp_path, n=3), tmp_path / "s"
    seen: list[list[str]] = []

    def before(n: int) -> None:
        if n == 2:  # (the other run rewrites the file, as it does when it starts: point 0's row, sorted)
            sweep_rows.write_rows(out, [json.loads((out / "sweep.jsonl").read_text().splitlines()[0])])
        if n == 3:
            seen.append(_hashes(out))

    _calls(monkeypatch, before)
    assert _sweep(path, out) == 0
    done = [r["hash"] for r in rows(out)]
    assert seen == [done[:2]]  # (point 1's row appended to the file the rewrite replaced before: [point 0's])


def test_a_runs_rewrite_keeps_the_rows_the_other_run_appended(tmp_path, monkeypatch):
    # another run of the sweep finishes point 2 (its folder, its row) as this one starts: after this one read the
    # folder, before it rewrote sweep.jsonl with the rows of the points it found done
    path, out = sweep_file(tmp_path, n=3), tmp_path / "s"
    assert _sweep(path, out) == 0
    done = rows(out)
    h2 = done[2]["hash"]
    shutil.move(out / "points" / h2, tmp_path / "p2")
    (out / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in done[:2]))
    real_open, seen = sweep_mod.open_executor, []

    def open_executor(*args, **kwargs):  # (this run has read the folder: point 2 to run)
        pool = real_open(*args, **kwargs)
        shutil.move(tmp_path / "p2", out / "points" / h2)
        with (out / "sweep.jsonl").open("a") as f:
            f.write(json.dumps(done[2]) + "\n")
        return pool

    monkeypatch.setattr(sweep_mod, "open_executor", open_executor)
    _calls(monkeypatch, lambda n: seen.append(_hashes(out)))
    assert _sweep(path, out) == 0
    assert seen == [[r["hash"] for r in done]]  # (its rewrite had dropped point 2's row: points 0 and 1 only)


def test_a_row_kept_only_of_this_sweeps_point_finished(tmp_path):
    # (another sweep's row, one of another index, a failed one, an ok one whose folder is gone: not kept)
    out = tmp_path / "s"
    (out / "points" / "a").mkdir(parents=True)
    (out / "points" / "a" / "results.json").write_text("{}")
    (out / "points" / "c").mkdir()
    lines = [{"point": 0, "hash": "a", "status": "ok"}, {"point": 5, "hash": "b", "status": "ok"},
             {"point": 1, "hash": "c", "status": "failed"}, {"point": 2, "hash": "d", "status": "ok"},
             {"point": 3, "hash": "x", "status": "ok"}]
    (out / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in lines))
    mine = [{"point": 4, "hash": "e", "status": "ok"}]
    kept = sweep_rows.others_rows(out, mine, {"a": 0, "b": 1, "c": 1, "d": 2, "e": 4})
    assert [r["hash"] for r in kept] == ["a"]


def test_an_append_cuts_off_a_row_left_half_written(tmp_path):
    # (by another run killed while appending: the row after it was joined to it, one damaged line, before)
    out = tmp_path / "s"
    out.mkdir()
    (out / "sweep.jsonl").write_text('{"point": 0, "hash": "a"}\n' + "x" * 70000)
    with sweep_rows.Appender(out) as f:
        f.write('{"point": 1, "hash": "b"}\n')
        f.flush()
        f.write('{"point": 2, "hash": "c"}\n')
        f.flush()
    assert _hashes(out) == ["a", "b", "c"]
    (out / "sweep.jsonl").write_text("x" * 10)
    with sweep_rows.Appender(out) as f:
        f.write('{"point": 1, "hash": "b"}\n')
        f.flush()
    assert _hashes(out) == ["b"]


class _Saved:
    """A reference compute's saved rounds (``reference_resume.Partial``) as an interrupt leaves them: 24 rounds."""

    off, saved = False, 0

    def __init__(self, path: Path):
        self.path = path

    def kept(self) -> int:
        return 24

    def others(self) -> int:
        return 0


def test_a_signal_while_the_sweep_computes_its_reference_says_the_rounds_kept(tmp_path, monkeypatch, capsys):
    # (review of d2b0547: before the folder is claimed, no row there, it said 'nothing was written', the cache
    # holding the compute's rounds; 'before any point finished' before that, not a word of them either)
    from tlm.experiments import reference_resume

    path, out, saved = sweep_file(tmp_path, n=3), tmp_path / "o", _Saved(tmp_path / "k.partial.npz")

    def computing(*args, **kwargs):
        with reference_resume.marked(saved):
            raise KeyboardInterrupt

    monkeypatch.setattr(sweep_mod, "sweep_references", computing)
    code = main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-report", "--no-progress", "--reference"])
    assert code == 130
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        f"tlm: interrupted while computing the reference: its 24 rounds are kept in {saved.path}; run the same "
        "command to resume from round 24")
