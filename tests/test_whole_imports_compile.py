"""A Ctrl-C while numba or llvmlite runs Python code in an API call (a compile, a load from numba's
cache) is held until the main thread is back out of it (:func:`tlm.whole_imports._uncuttable`,
``"compile"``): llvmlite hands an LLVM object to a new owner in a C call and records it on the
next line (``link_modules``' ``src.detach()``), and a KeyboardInterrupt raised as the C call
returns left the object to be disposed of twice, a segfault (or "free(): double free") later in
the process: SIGINTs at random moments of numba compiles crashed about one process in two of 150."""

from __future__ import annotations

import os
import signal

import pytest

from tlm.whole_imports import imports_whole

llvmlite = pytest.importorskip("llvmlite")

# a step of llvmlite's: a signal arrives in its C call (raised here), then the line that records the handover
STEP = """
import signal
def step(reached):
    signal.raise_signal(signal.SIGINT)
    reached.append("recorded")
"""


def _llvmlite_step():
    """``step(reached)``, a function whose code is llvmlite's as Python sees it (its file in llvmlite's folder)."""
    ns: dict = {}
    exec(compile(STEP, os.path.join(os.path.dirname(llvmlite.__file__), "binding", "_tlm_test_step.py"), "exec"), ns)
    return ns["step"]


def test_a_ctrl_c_in_llvmlites_code_is_held_until_it_returns():
    before = signal.signal(signal.SIGINT, signal.default_int_handler)  # (a test runner's worker may ignore it)
    try:
        step, reached = _llvmlite_step(), []

        @imports_whole
        def call() -> None:
            step(reached)
            reached.append("back in tlm")

        with pytest.raises(KeyboardInterrupt):
            call()
        assert reached[:1] == ["recorded"], reached  # (not cut between the C call and the line after it)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler

        reached.clear()
        with pytest.raises(KeyboardInterrupt):  # (outside an API call: not held, as before)
            step(reached)
        assert reached == []
    finally:
        signal.signal(signal.SIGINT, before)
