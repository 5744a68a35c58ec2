"""Review of 00d6e71 (h431: the claims' lock reentrant) and b03b276 (h439: ``tlm plots`` claims its --out), h442.

* A claim of ``out`` left open (a ``claimed`` block entered and never left, in a cycle) and let go by the collector
  in the thread that takes ``out`` again, between its look at the claims (:data:`tlm.claims._CLAIMS`) and its count
  of one more holder (Python 3.12 on runs the collector at the eval breaker, right after a call returns: here, the
  ``_CLAIMS.get``): the lock reentrant, the collector's ``finally`` dropped the claim (its count 0, its file removed)
  and the new block counted itself on that dropped entry, holding nothing (another process's run into ``out``
  then went ahead). It looks again now, and takes a claim of its own.
* ``tlm plots --out runs/extreme/plots``: its claim file (and the folder made for it) lay in step extreme's folder
  under --runs, which the step then refused as "not an earlier tlm output"; such an --out is refused before any
  step, as a step's folder itself is (b03b276).
"""

from __future__ import annotations

import gc
import os
from pathlib import Path

import pytest

from tlm import claims
from tlm.errors import InputError
from tlm.report.regenerate import regenerate

REPO = Path(__file__).resolve().parents[1]


class _CollectedAfterLook(dict):
    """The claims, whose first look at ``key`` is followed by a collection (the collector at the eval breaker)."""

    key = ""

    def get(self, key, default=None):
        found = super().get(key, default)
        if key == self.key:
            self.key = ""
            gc.collect()
        return found


def test_a_claim_left_open_let_go_as_the_same_folder_is_claimed_again_leaves_it_claimed(tmp_path, monkeypatch):
    out = tmp_path / "a"
    held = _CollectedAfterLook()
    monkeypatch.setattr(claims, "_CLAIMS", held)
    beside = tmp_path / ".a.tlm-running"
    enabled = gc.isenabled()
    gc.collect()
    gc.disable()  # (the collector runs where this test says)
    try:
        cm = claims.claimed(out)
        cm.__enter__()
        cycle = {"claim": cm}
        cycle["self"] = cycle
        del cm, cycle
        assert beside.exists() and list(held) == [os.fsdecode(out.resolve())]
        held.key = os.fsdecode(out.resolve())
        with claims.claimed(out):
            assert held.key == ""  # (the collection ran, in the look)
            assert beside.exists(), "the folder's claim was dropped under the block that claims it"
            assert list(held) == [os.fsdecode(out.resolve())] and held[os.fsdecode(out.resolve())][3] == 1
            what, holder = claims._held_claim(beside)  # (its lock held, as another process looking sees it)
            assert what == "run" and holder.startswith(f"process {os.getpid()} on this machine")
    finally:
        if enabled:
            gc.enable()
    assert not beside.exists() and dict(held) == {}


@pytest.mark.parametrize("inside", ["extreme/plots", "thesis/x/report"])
def test_plots_out_inside_a_steps_folder_is_refused_before_any_step(tmp_path, inside):
    runs = tmp_path / "runs"
    called = []
    with pytest.raises(InputError) as e:
        regenerate(REPO / "configs", runs, runs / inside, ["extreme"], run_command=called.append,
                   say=lambda line: None)
    step = inside.split("/")[0]
    assert f"lies in step {step}'s folder under --runs" in str(e.value) and str(e.value).startswith("--out: ")
    assert called == [] and not runs.exists() and not claims.holding()


@pytest.mark.parametrize("module", ["claims", "storage_live"])
def test_a_forked_child_gets_a_free_lock_where_another_thread_of_the_parent_held_it(module):
    """The locks reentrant, the fork tests that hold one in the forking thread (tests/test_moved_h334.py,
    tests/test_storage_threads.py) pass without the fork handlers too: the child's thread is that lock's owner. Held
    by another thread of the parent, the child's lock is free only as the handler (``_forget_claims``,
    ``_forget_live``, with ``storage._same_lock``) makes it anew."""
    import threading

    from tlm import storage, storage_live

    if not hasattr(os, "fork"):
        pytest.skip("no fork here")
    mod = claims if module == "claims" else storage_live
    name = "_CLAIMS_LOCK" if module == "claims" else "_LIVE_LOCK"
    taken, done = threading.Event(), threading.Event()

    def hold() -> None:
        with getattr(mod, name):
            taken.set()
            done.wait(60)

    thread = threading.Thread(target=hold, daemon=True)
    thread.start()
    assert taken.wait(60)
    r, w = os.pipe()
    try:
        pid = os.fork()
        if pid == 0:  # pragma: no cover - the child
            ok = getattr(mod, name).acquire(timeout=5) and storage._LIVE_LOCK is storage_live._LIVE_LOCK
            os.write(w, b"1" if ok else b"0")
            os._exit(0)
    finally:
        done.set()
        thread.join(60)
    os.close(w)
    got = os.read(r, 1)
    os.close(r)
    os.waitpid(pid, 0)
    assert got == b"1"
