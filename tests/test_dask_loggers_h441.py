"""distributed's loggers between test files (h441): a Dask sweep ended by a signal leaves them silenced for
:data:`tlm.experiments.executors_quiet.QUIET_GRACE` seconds, by design (its event loop thread narrates the closed
connections after tlm's one line), and a daemon timer puts them back. tests/test_review_h373.py's interrupted sweep
left that grace pending for the next tests of its process, and tests/test_review_h386.py's ``levels`` fixture took
the silence (level 51) as distributed's own levels: two of its tests failed when both files ran in one process
(CI's ``-n 2 --dist loadfile``: when both landed on one worker). Now h373's test ends its grace, and h386's fixture
ends any grace left pending before it reads the levels."""

from __future__ import annotations

import logging
import subprocess
import sys
from pathlib import Path

import pytest

import tlm.experiments.executors as executors
from tests import test_review_h386 as h386
from tests.test_review_h386 import NAMES, levels  # noqa: F401  (h386's fixture, requested below)

pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[1]
H373 = "tests/test_review_h373.py::test_an_interrupt_as_the_executor_closes_writes_the_events_once"


class Kept:
    """threading.Timer as :meth:`tlm.experiments.executors_quiet.Quiet.after` starts one, never started."""

    daemon = False

    def __init__(self, *args, **kwargs) -> None:
        pass

    def start(self) -> None:
        pass


@pytest.fixture
def left_pending(monkeypatch):
    """A signalled sweep's grace left pending, as an earlier test's interrupted sweep leaves it: distributed's
    loggers silenced, their timer (kept here, never fired) not yet run. Yields their levels before the signal."""
    import distributed  # noqa: F401  (its import sets its loggers' levels)

    monkeypatch.setattr(executors.threading, "Timer", Kept)
    before = {n: logging.getLogger(n).level for n in NAMES}
    executors._Quiet().after(KeyboardInterrupt)
    assert not logging.getLogger("distributed.batched").isEnabledFor(logging.CRITICAL)
    yield before
    executors._put_back_left()
    for n, level in before.items():
        logging.getLogger(n).setLevel(level)


def test_h386s_levels_are_distributed_s_own_not_an_earlier_sweeps_silence(left_pending, levels):  # noqa: F811
    """h386's ``levels``, entered within an earlier signal's grace, start from the levels before that signal
    (``distributed`` at INFO, as it sets it), not the silence; its tests then pass."""
    start, _ = levels
    assert start == {**left_pending, "distributed": logging.INFO}
    assert logging.getLogger("distributed.batched").isEnabledFor(logging.INFO)
    h386.test_a_second_signal_within_the_grace_keeps_its_own_whole_grace(levels)


def test_h386s_hushed_sweep_passes_within_an_earlier_sweeps_grace(left_pending, levels):  # noqa: F811
    h386.test_a_sweep_hushed_within_a_grace_stays_hushed_when_its_timer_puts_the_others_back(levels)


@pytest.mark.slow
@pytest.mark.parametrize("order", [[H373, "tests/test_review_h386.py"], ["tests/test_review_h386.py", H373]])
def test_h373_and_h386_pass_in_one_process_in_either_order(order):
    """The order CI's ``--dist loadfile`` gave them on one worker, and the other."""
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *order],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
