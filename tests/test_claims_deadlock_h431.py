"""A claim left open (a ``claimed`` context entered and never left: a frame of a traceback kept in a cycle, an
``ExitStack`` never closed) is let go by the garbage collector, whose close of its generator runs its ``finally``,
which takes the process's claims' lock (:data:`tlm.claims._CLAIMS_LOCK`). The collector runs in whatever thread
allocates: one that held that lock itself, taking a claim (:func:`tlm.claims._take_claim`), waited for it for ever,
and every later claim of the process with it (a hung pytest worker, h431). The lock is reentrant now: the
collector's close, in the thread that holds it, goes through, and the claim left open is dropped."""

from __future__ import annotations

import gc
import threading
from contextlib import contextmanager

from tlm import claims

HANG = 60.0  # seconds: only a hang takes this long (the claim itself takes milliseconds)


@contextmanager
def _collector_off():
    """The collector off in the block (it runs where the test says), the earlier tests' garbage collected first."""
    enabled = gc.isenabled()
    gc.collect()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _joined(work) -> threading.Thread:
    """``work`` run in a thread of its own, waited for until :data:`HANG` (a hang leaves it alive)."""
    thread = threading.Thread(target=work, daemon=True)
    thread.start()
    thread.join(HANG)
    return thread


def _left_open(out) -> None:
    """A claim of ``out`` entered and never left, reachable only through a cycle (the collector's to free)."""
    cm = claims.claimed(out)
    cm.__enter__()
    cycle = {"claim": cm}
    cycle["self"] = cycle


def test_a_claim_left_open_collected_while_this_thread_takes_another_is_dropped_not_a_hang(tmp_path, monkeypatch):
    # (a lock of this test's own: a hang of the old code holds it for ever, not the one the later tests use)
    monkeypatch.setattr(claims, "_CLAIMS_LOCK", claims._CLAIMS_LOCK)  # (put back after)
    monkeypatch.setattr(claims, "_CLAIMS", {})
    claims._forget_claims()  # (a new lock, as a forked child's)
    real = claims._take_claim
    collected = []

    def take_claim(*args):
        if not collected:  # (an allocation in there set the collector off: here, at once)
            collected.append(gc.collect())
        return real(*args)

    done = []

    def second() -> None:
        with claims.claimed(tmp_path / "b"):
            done.append(sorted(claims._CLAIMS))

    with _collector_off():
        _left_open(tmp_path / "a")
        assert (tmp_path / ".a.tlm-running").exists()
        monkeypatch.setattr(claims, "_take_claim", take_claim)
        thread = _joined(second)
    assert not thread.is_alive(), "a claim taken while the collector let go of another waited for ever"
    assert collected and collected[0] > 0
    assert done == [[str((tmp_path / "b").resolve())]]  # (the claim left open dropped, by the collector)
    assert not (tmp_path / ".a.tlm-running").exists() and not (tmp_path / ".b.tlm-running").exists()
    assert claims._CLAIMS == {}


def test_a_write_left_open_collected_while_this_thread_writes_another_is_dropped_not_a_hang(tmp_path, monkeypatch):
    """The same of :func:`tlm.storage.write_atomic`: its ``finally`` takes :data:`tlm.storage_live._LIVE_LOCK`, which
    :func:`tlm.storage._temporary_file` holds as it allocates (a plain lock: the same hang; reentrant now)."""
    from pathlib import Path

    from tlm import storage, storage_live

    monkeypatch.setattr(storage_live, "_LIVE_LOCK", storage_live._LIVE_LOCK)  # (put back after)
    storage_live._forget_live()  # (a new lock of the module's kind, as a forked child's: a hang holds it alone)
    real = Path.with_name
    collected = []

    def with_name(self, name):  # (called by _temporary_file under the lock: the collector set off there)
        if not collected and threading.current_thread() is not threading.main_thread():
            collected.append(gc.collect())
        return real(self, name)

    done = []

    def second() -> None:
        with storage.write_atomic(tmp_path / "b.txt") as f:
            f.write("x")
        done.append(True)

    with _collector_off():
        cm = storage.write_atomic(tmp_path / "a.txt")
        cm.__enter__()
        cycle = {"write": cm}
        cycle["self"] = cycle
        del cm, cycle
        monkeypatch.setattr(Path, "with_name", with_name)
        thread = _joined(second)
    assert not thread.is_alive(), "a write while the collector let go of another waited for ever"
    assert collected and collected[0] > 0 and done == [True]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.txt"]  # (the write left open: its temporary file gone)
