"""Review of 491c9f0 (h373): a Dask sweep's ``workers.json``.

A ``workers.json`` that is not tlm's (another format, or ``events`` not a list) is replaced by the next sweep's
events, not a crash at the sweep's end after its points ran (``'int' object is not iterable``); ``tlm report`` of
a folder holding one says it could not be read, as of a damaged one, and a kept event whose ``sent_again`` is not
a list is shown without it, not a crash of the report. The events of a sweep interrupted while its executor
closed, after they were written, are not written twice. docs/usage.md's table of a sweep's output folder lists
``workers.json``."""

from __future__ import annotations

import json
import logging
from contextlib import ExitStack
from pathlib import Path
from types import SimpleNamespace

import pytest

from tlm.experiments.sweep_rows import WORKERS_FILE, keep_worker_events
from tlm.report.warnings import worker_events

ROOT = Path(__file__).resolve().parents[1]


def _events(out: Path) -> list[dict]:
    body = json.loads((out / WORKERS_FILE).read_text(encoding="utf-8"))
    assert body["tlm"] == "sweep-workers/1", body
    return body["events"]


def _inputs(out: Path):
    return SimpleNamespace(sweeps=[SimpleNamespace(path=out, label="sw", rows=[{"point": 3, "hash": "abc"}])])


@pytest.mark.parametrize("body", ['{"tlm": "sweep-workers/1", "events": 5}',
                                  '{"tlm": "other/1", "events": [{"event": "x", "line": "foreign"}]}',
                                  '{"events": [{"event": "x", "line": "no format"}]}'])
def test_a_workers_json_not_tlm_s_is_replaced_and_the_report_says_it_cannot_be_read(tmp_path, body):
    out = tmp_path / "sw"
    out.mkdir()
    (out / WORKERS_FILE).write_text(body, encoding="utf-8")
    ((line, whose),) = worker_events(_inputs(out))
    assert line.startswith(f"{out / WORKERS_FILE} could not be read (") and whose == "the sweep sw", line
    keep_worker_events(out, [{"event": "left-out", "worker": "tcp://h:1", "line": "mine"}])
    assert [e["line"] for e in _events(out)] == ["mine"]
    assert not [p for p in out.iterdir() if p.name != WORKERS_FILE]  # (no temporary left)


def test_an_event_whose_points_sent_again_are_not_a_list_is_shown_without_them(tmp_path):
    out = tmp_path / "sw"
    out.mkdir()
    events = [{"event": "left-out", "line": "first", "sent_again": 7, "when": 5},
              {"event": "left-out", "line": "second", "sent_again": [{"hash": "abc", "status": "ok"}, 3]}]
    (out / WORKERS_FILE).write_text(json.dumps({"tlm": "sweep-workers/1", "events": events}), encoding="utf-8")
    assert worker_events(_inputs(out)) == [("first", "the sweep sw"),
                                           ("second; point sent again: #3 (ok)", "the sweep sw")]


def test_usage_lists_workers_json_in_the_sweep_output_folder_table():
    text = (ROOT / "docs" / "usage.md").read_text(encoding="utf-8")
    table = text[text.index("The output folder (default `runs/<sweep file name>`):"):]
    table = table[:table.index("\n\n", table.index("| file |"))]
    assert "| `workers.json` |" in table, table


def test_an_interrupt_as_the_executor_closes_writes_the_events_once(tmp_path, monkeypatch, cache):
    pytest.importorskip("distributed")
    from distributed import LocalCluster

    import tlm.experiments.executors as executors
    import tlm.experiments.sweep as sweep_mod
    from tests.test_dask_health_h341 import _addresses, _points_fail_on, _sweep

    real = sweep_mod.open_executor

    def interrupted_as_it_closes(stack: ExitStack, *args, **kwargs):
        pool = real(stack, *args, **kwargs)

        def interrupt():
            raise KeyboardInterrupt

        stack.callback(interrupt)  # (runs first as the stack closes: after the sweep kept its workers' events)
        return pool

    monkeypatch.setattr(sweep_mod, "open_executor", interrupted_as_it_closes)
    try:
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp://", host="127.0.0.1",
                          dashboard_address="127.0.0.1:0", scheduler_kwargs={"dashboard": False},
                          silence_logs=logging.CRITICAL) as cluster:
            bad, _ = _addresses(cluster)
            _points_fail_on(monkeypatch, {bad})
            out = tmp_path / "o"
            with pytest.raises(KeyboardInterrupt):
                sweep_mod.run_sweep(_sweep(tmp_path), out, dask=cluster.scheduler_address, warn=lambda line: None)
    finally:  # (the signal left distributed's loggers silenced for its QUIET_GRACE: its end now, as its timer's,
        # not for the tests after this one in the process to take as their levels; h441)
        executors._put_back_left()
    events = _events(out)
    assert [(e["event"], e["worker"]) for e in events] == [("left-out", bad)], events


def test_a_worker_re_admitted_then_left_out_again_has_each_event_once_with_its_own_points():
    """Its first left-out event names the point sent again then, its re-admission follows, and its second left-out
    event names the point sent again since: not both points twice and a second re-admission after it."""
    pytest.importorskip("distributed")
    import tlm.experiments.executors as executors
    from tests.test_dask_health_h341 import GOOD, _Client

    good, bad = "tcp://10.0.0.1:1", "tcp://10.0.0.2:2"
    client = _Client({good: GOOD, bad: {**GOOD, "host": "hostB"}})
    watch = executors.DaskPool(client, "tcp://s:8786", remote=True).watch
    watch.start(refuse=True)

    def fails(point: str) -> bool:
        error = {"type": "OtherInputsOnWorker", "message": "stand-in"}
        return watch.send_again(point, {"status": "failed", "error": error, "ran": {"worker": bad}})

    assert fails("p1")  # (left out, p1 sent again)
    watch._event((0.0, {"action": "remove-worker", "worker": bad}))  # (its nanny restarts it, mended)
    watch.check(list(client.answers))  # (back, answering well: re-admitted)
    assert fails("p2")  # (left out again, p2 sent again)
    events = watch.worker_events({})
    assert [(e["event"], [s["hash"] for s in e.get("sent_again", [])]) for e in events] == [
        ("left-out", ["p1"]), ("re-admitted", []), ("left-out", ["p2"])], events


def test_the_events_are_those_of_the_folder_s_sweep_a_sweep_of_other_points_starts_afresh(tmp_path):
    from tlm.experiments.sweep_rows import forget_worker_events

    out = tmp_path / "sw"
    out.mkdir()
    keep_worker_events(out, [{"event": "left-out", "line": "first"}], "A")
    keep_worker_events(out, [{"event": "left-out", "line": "second"}], "A")  # (a resume: kept after)
    forget_worker_events(out, "A")
    assert [e["line"] for e in _events(out)] == ["first", "second"]
    keep_worker_events(out, [{"event": "left-out", "line": "third"}], "B")  # (another sweep's: replaced)
    assert [e["line"] for e in _events(out)] == ["third"]
    forget_worker_events(out, "A")  # (a sweep of other points into the folder, with no event of its own)
    assert not (out / WORKERS_FILE).exists()


def test_a_sweep_of_other_points_into_the_folder_leaves_no_events_of_the_one_before(tmp_path, cache):
    """Its rows replace the earlier sweep's in sweep.jsonl; the report of the folder told the earlier sweep's
    workers' events as this one's."""
    from tests.test_dask_health_h341 import _sweep
    from tlm.experiments.sweep import load_sweep, run_sweep

    out = tmp_path / "o"
    first = _sweep(tmp_path, 1)
    run_sweep(first, out)
    keep_worker_events(out, [{"event": "left-out", "line": "of the first"}], load_sweep(first).identity())
    run_sweep(first, out)  # (all done: the same sweep, its events kept)
    assert [e["line"] for e in _events(out)] == ["of the first"]
    other = tmp_path / "other"
    other.mkdir()
    run_sweep(_sweep(other, 2), out)  # (another sweep: one more point)
    assert not (out / WORKERS_FILE).exists()
