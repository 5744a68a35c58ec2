"""Review of h380 (distributed's narrating loggers hushed for a Dask sweep client's life; h386): a sweep signalled
within an earlier signalled sweep's QUIET_GRACE keeps distributed's loggers silenced for its own whole grace (the
earlier signal's timer put them back, part of the way through it), and a sweep hushed within a grace keeps its
narrating loggers below WARNING when that timer puts the others back mid-sweep."""

from __future__ import annotations

import logging

import pytest

import tlm.experiments.executors as executors

pytest.importorskip("distributed")

NAMES = ["distributed", "distributed.batched", "distributed.client", "distributed.core", "distributed.comm",
         "distributed.comm.tcp", "distributed.scheduler"]


class Timers:
    """threading.Timer as _Quiet.after starts one: each kept, not started, for the test to fire."""

    def __init__(self) -> None:
        self.made: list[tuple] = []

    def __call__(self, interval, function, args=None, kwargs=None):
        test = self

        class Timer:
            daemon = False

            def start(self) -> None:
                test.made.append((function, tuple(args or ()), dict(kwargs or {})))

        return Timer()

    def fire(self, i: int) -> None:
        function, args, kwargs = self.made[i]
        function(*args, **kwargs)


@pytest.fixture
def levels(monkeypatch):
    """distributed's loggers at INFO (its own config's) as the test starts, put back after it; no timer left. A
    grace an earlier test in the process left pending (an interrupted sweep's: its loggers silenced, a real timer
    to put them back) ends first, as its timer's end would: its silence is not these tests' starting levels."""
    import distributed  # noqa: F401  (its import sets its loggers' levels)

    executors._put_back_left()
    kept = {n: logging.getLogger(n).level for n in NAMES}
    logging.getLogger("distributed").setLevel(logging.INFO)
    timers = Timers()
    monkeypatch.setattr(executors.threading, "Timer", timers)
    yield {n: logging.getLogger(n).level for n in NAMES}, timers
    executors._put_back_left()
    for n, level in kept.items():
        logging.getLogger(n).setLevel(level)


def silent(name: str = "distributed.batched") -> bool:
    return not logging.getLogger(name).isEnabledFor(logging.CRITICAL)


def test_a_second_signal_within_the_grace_keeps_its_own_whole_grace(levels):
    """Two sweeps signalled one within the other's grace: the first signal's timer, firing part of the way
    through the second's grace, put every logger back then (the second cluster's closed connections narrated
    after its line); the second's timer puts them back, as they were before either."""
    before, timers = levels
    executors._Quiet().after(KeyboardInterrupt)  # (the first sweep, signalled)
    second = executors._Quiet()
    second.hush()
    second.now()
    second.after(KeyboardInterrupt)  # (the second, within the first's grace)
    assert len(timers.made) == 2 and silent()
    timers.fire(0)  # (the first's grace over: the second's is not)
    assert silent() and silent("distributed") and silent("distributed.scheduler")
    timers.fire(1)
    assert {n: logging.getLogger(n).level for n in NAMES} == before


def test_a_sweep_hushed_within_a_grace_stays_hushed_when_its_timer_puts_the_others_back(levels):
    """A sweep started within a signalled one's grace: the grace's timer, firing mid-sweep, puts back the loggers
    left silenced, but not the narrating ones it hushed (INFO would reach the user again, before the sweep's
    line on a lost scheduler); the sweep puts those back after."""
    before, timers = levels
    executors._Quiet().after(KeyboardInterrupt)
    sweep = executors._Quiet()
    sweep.hush()
    timers.fire(0)  # (mid-sweep)
    assert logging.getLogger("distributed").level == logging.INFO  # (the others: back)
    for name in ("distributed.batched", "distributed.core", "distributed.comm.tcp", "distributed.client"):
        assert not logging.getLogger(name).isEnabledFor(logging.INFO), name
    assert logging.getLogger("distributed.batched").isEnabledFor(logging.WARNING)
    sweep.restore()
    assert {n: logging.getLogger(n).level for n in NAMES} == before


def test_a_sweep_that_cannot_reach_its_scheduler_puts_the_hushed_levels_back(levels, monkeypatch, tmp_path):
    """Hushed before the client connects, a sweep whose client cannot reach the scheduler (an InputError from
    open_executor) leaves every level as it was (a notebook's next cell)."""
    from contextlib import ExitStack

    from tlm.errors import InputError

    before, _ = levels

    def unreachable(*args, **kwargs):
        raise OSError("Timed out trying to connect")

    monkeypatch.setattr(executors, "answers", lambda address: None)
    monkeypatch.setattr(executors, "_client", unreachable)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match="cannot reach the Dask scheduler"), ExitStack() as stack:
        executors.open_executor(stack, 1, "tcp://127.0.0.1:1", 1)
    assert {n: logging.getLogger(n).level for n in NAMES} == before
