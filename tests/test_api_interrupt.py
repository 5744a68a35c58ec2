"""Ctrl-C during the first API call of a process, while numba (and the other layers tlm
imports on first use) is being imported: the interrupt is held until the import is whole,
then raised, so that every later call of the process works (a half-finished import is not
undone by Python: numba left half imported failed every later render with ``module 'numba'
has no attribute 'core'``). Each test runs a fresh Python process, where a hook on the
import system sends SIGINT at the moment a named module is first looked for: a moment of
the first call chosen exactly, not by a timer."""

from __future__ import annotations

import signal
import sys
import textwrap
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from tests.helpers_interrupt import CLI_RUN, run_script, signalled_call
from tlm import api
from tlm.whole_imports import imports_whole

pytest.importorskip("numba")


HOOK = textwrap.dedent("""
    import json, os, signal, sys

    TARGET, TIMES = sys.argv[1], int(sys.argv[2])
    seen = []
    # (as an interactive Python or a notebook's kernel has it: a test runner started in the
    # background of a shell passes SIGINT on ignored, and Python then leaves it ignored)
    signal.signal(signal.SIGINT, signal.default_int_handler)

    class Hook:  # SIGINT (TIMES of them) when TARGET is first looked for, from inside its import
        def find_spec(self, name, path=None, target=None):
            if name == TARGET and not seen:
                seen.append(name)
                for _ in range(TIMES):
                    signal.raise_signal(signal.SIGINT)
            return None

    sys.meta_path.insert(0, Hook())
    import tlm

    SMALL = {"mode": "reflect", "resolution": [16, 16], "render.spp": 1, "render.light_samples": 1}
    report = {"numba_before": "numba" in sys.modules}
""")

RENDER = HOOK + textwrap.dedent("""
    cfg = tlm.load_config("cornell", SMALL)
    try:
        tlm.render_image(cfg)
        report["first"] = "finished"
    except KeyboardInterrupt:
        report["first"] = "interrupted"
    report["target_whole"] = TARGET in sys.modules
    report["seen"] = bool(seen)
    for call in ("second", "third"):
        try:
            res = tlm.render_image(cfg)
            report[call] = float(res.composite.sum())
        except BaseException as e:
            report[call] = f"{type(e).__name__}: {e}"
    print(json.dumps(report))
""")


_run = run_script


# moments of numba's import, early to late, and of tlm's own compiled modules after it
@pytest.mark.parametrize("target", [
    "numba.core.types",
    pytest.param("numba.core.typing.templates", marks=pytest.mark.slow),
    pytest.param("numba.np.arraymath", marks=pytest.mark.slow),
    pytest.param("tlm.kernels._jit_bsp", marks=pytest.mark.slow),
])
def test_a_ctrl_c_during_the_first_renders_imports_leaves_the_process_working(target, tmp_path):
    out = _run(RENDER, target, "1", cwd=tmp_path, cache=tmp_path / "cache")
    assert out["numba_before"] is False  # (else the first call imports no numba: the test would test nothing)
    assert out["seen"] is True
    assert out["first"] == "interrupted"  # the Ctrl-C still stops the call ...
    assert out["target_whole"] is True  # ... once the import it came in is complete
    assert isinstance(out["second"], float), out["second"]  # and every later call works, with one image
    assert out["third"] == out["second"]


def test_a_second_ctrl_c_during_the_import_says_to_restart(tmp_path):
    """Two Ctrl-C in one import: the second goes through (the user insists), the import is left
    half done, and the next call says in one line that the process must be restarted, rather
    than an AttributeError deep in numba."""
    out = _run(RENDER, "numba.core.types", "2", cwd=tmp_path, cache=tmp_path / "cache")
    assert out["first"] == "interrupted" and out["target_whole"] is False
    for call in ("second", "third"):
        assert out[call].startswith("RuntimeError: a Ctrl-C (pressed twice) interrupted the import of numba"), out
        assert "restart the Python process" in out[call] and "\n" not in out[call]


SWEEP = HOOK + textwrap.dedent("""
    from pathlib import Path
    Path("s.yaml").write_text("base: {scene: cornell, mode: reflect, resolution: [16, 16], "
                              "render: {spp: 1, light_samples: 1}}\\ngrid:\\n  arch.pipelines: [1, 2]\\n")
    try:
        tlm.run_sweep("s.yaml", "sw", jobs=1)
        report["first"] = "finished"
    except KeyboardInterrupt:
        report["first"] = "interrupted"
    report["target_whole"] = TARGET in sys.modules
    outcome = tlm.run_sweep("s.yaml", "sw", jobs=1)
    report["second"] = [[r["status"], r["error"]] for r in outcome.rows]
    print(json.dumps(report))
""")


@pytest.mark.slow
def test_a_sweep_in_this_process_interrupted_during_its_imports_runs_again(tmp_path):
    out = _run(SWEEP, "numba.core.types", "1", cwd=tmp_path, cache=tmp_path / "cache")
    assert out["numba_before"] is False
    assert out["first"] == "interrupted" and out["target_whole"] is True
    assert [status for status, _ in out["second"]] == ["ok", "ok"], out["second"]


CLI = HOOK + CLI_RUN


def test_tlm_run_interrupted_during_the_import_exits_130_once_it_is_whole(tmp_path):
    out = _run(CLI, "numba.core.types", "1", cwd=tmp_path, cache=tmp_path / "cache")
    assert out["rc"] == 128 + signal.SIGINT and out["out"] is False
    assert out["stderr"].rstrip().endswith("tlm: interrupted")
    assert out["target_whole"] is True


def test_a_ctrl_c_outside_an_import_is_not_held(tmp_path, monkeypatch):
    """In this process: the handler of an API call passes a Ctrl-C outside an import on at
    once, holds one inside an import (a module of tmp_path's) to its end, and is taken down
    when the call ends; off the main thread a call works and installs nothing."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)  # (a test runner's worker may ignore it)
    try:
        call, reached = signalled_call(tmp_path, monkeypatch, signal.SIGINT, "tlm_test_slow_import")
        with pytest.raises(KeyboardInterrupt):
            call(False)
        assert reached == [] and signal.getsignal(signal.SIGINT) is signal.default_int_handler
        with pytest.raises(KeyboardInterrupt):
            call(True)
        assert sys.modules["tlm_test_slow_import"].WHOLE is True and reached == [True]
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        with ThreadPoolExecutor(1) as pool:  # (signal.signal is refused there: the call runs as it is)
            assert pool.submit(api.load_config, {"scene": "cornell"}).result().scene == "cornell"
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        sys.modules.pop("tlm_test_slow_import", None)
        signal.signal(signal.SIGINT, before)


class _SignalsWhenDeleted:
    """A finalizer that sends ``times`` Ctrl-Cs, and notes whether it got past them."""

    def __init__(self, reached: list, times: int):
        self.reached, self.times = reached, times

    def __del__(self):
        for _ in range(self.times):
            signal.raise_signal(signal.SIGINT)
        self.reached.append("past the signals")


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")  # (the second's, dropped: the point)
@pytest.mark.parametrize("times", [1, 2])
def test_a_ctrl_c_in_a_finalizer_is_held_to_its_end_and_a_second_ends_it(times):
    """Python drops an exception raised in a ``__del__`` ("Exception ignored in ..."): a Ctrl-C
    given there (a held one, given back by the watching thread while llvmlite disposes of an
    object, as in about one run in thirty of the arraymath test above) would be lost, and the
    call would run to its end. It is held until the finalizer has returned. A second Ctrl-C
    there goes through (a ``__del__`` that hangs can be stopped: it ends it, Python dropping its
    exception), and the one held is still given once the finalizer has returned."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        reached: list = []

        @imports_whole
        def call() -> None:
            _SignalsWhenDeleted(reached, times)  # (deleted at once: its __del__ sends the Ctrl-Cs)
            reached.append("after the finalizer")
            for _ in range(500):  # (the held Ctrl-C is given back here, or at the latest as the call ends)
                time.sleep(0.01)
            reached.append("end")

        with pytest.raises(KeyboardInterrupt):
            call()
        assert reached == (["past the signals"] if times == 1 else []) + ["after the finalizer"]
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, before)


def _a_frame_gone():
    """The frame of a call that has ended (on no stack now)."""
    return sys._getframe()


def test_a_handler_a_ctrl_c_left_behind_is_replaced(tmp_path, monkeypatch):
    """A Ctrl-C that lands while a call ends can leave its handler installed (before it is put
    back). The next call does not take it for an outer call's: it installs its own, over the
    handler the stale one replaced, so a Ctrl-C in its import is still held to the import's end;
    a call inside another still leaves the holding to the outer one."""
    from tlm.whole_imports import HeldInterrupt

    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        (tmp_path / "tlm_test_late_import.py").write_text(
            "import signal\nsignal.raise_signal(signal.SIGINT)\nWHOLE = True\n")
        monkeypatch.syspath_prepend(str(tmp_path))
        for active in (False, True):  # (ended, or cut off before it could say so)
            stale = HeldInterrupt(signal.default_int_handler, _a_frame_gone())  # (its call's frame: ended)
            stale.active = active
            signal.signal(signal.SIGINT, stale)
            seen = []

            @imports_whole
            def call(seen=seen) -> None:
                seen.append(signal.getsignal(signal.SIGINT))
                import tlm_test_late_import  # noqa: F401

            with pytest.raises(KeyboardInterrupt):
                call()
            assert isinstance(seen[0], HeldInterrupt) and seen[0] is not stale, active
            assert sys.modules.pop("tlm_test_late_import").WHOLE is True
            assert signal.getsignal(signal.SIGINT) is signal.default_int_handler

        inner_seen = []

        @imports_whole
        def inner() -> None:
            inner_seen.append(signal.getsignal(signal.SIGINT))

        @imports_whole
        def outer() -> None:
            inner_seen.append(signal.getsignal(signal.SIGINT))
            inner()

        outer()
        assert isinstance(inner_seen[0], HeldInterrupt) and inner_seen[1] is inner_seen[0]
    finally:
        sys.modules.pop("tlm_test_late_import", None)
        signal.signal(signal.SIGINT, before)
