"""A SIGTERM that a Python handler turns into an exception (as ``tlm``'s command line turns it
into the KeyboardInterrupt that removes what a command half wrote) cuts an import short as a
Ctrl-C does: it is held to the import's end the same way, so numba is never left half
imported. And ``tlm.<name>``, the package's first use, imports :mod:`tlm.api` whole too.

As in tests/test_api_interrupt.py, each process test runs a fresh Python, where a hook on the
import system sends the signal at the moment a named module is first looked for.
"""

from __future__ import annotations

import signal
import sys
import textwrap

import pytest

from tests.helpers_interrupt import CLI_RUN, run_script, signalled_call
from tlm.whole_imports import HeldInterrupt, imports_whole

HOOK = textwrap.dedent("""
    import json, os, signal, sys

    TARGET, SIG, TIMES = sys.argv[1], getattr(signal, sys.argv[2]), int(sys.argv[3])
    seen = []
    signal.signal(signal.SIGINT, signal.default_int_handler)  # (as an interactive Python has it)

    class Terminated(Exception):
        pass

    def terminate(signum, frame):  # a Python handler that turns SIGTERM into an exception
        raise Terminated(signum)

    class Hook:  # SIG (TIMES of them) when TARGET is first looked for, from inside its import
        def find_spec(self, name, path=None, target=None):
            if name == TARGET and not seen:
                seen.append(name)
                for _ in range(TIMES):
                    signal.raise_signal(SIG)
            return None

    sys.meta_path.insert(0, Hook())
    import tlm

    SMALL = {"mode": "reflect", "resolution": [16, 16], "render.spp": 1, "render.light_samples": 1}
    report = {"numba_before": "numba" in sys.modules, "api_before": "tlm.api" in sys.modules}
""")


_run = run_script


FIRST_USE = HOOK + textwrap.dedent("""
    if SIG == signal.SIGTERM:
        signal.signal(signal.SIGTERM, terminate)
    try:
        tlm.load_config  # the first tlm.<name>: imports tlm.api
        report["first"] = "finished"
    except (KeyboardInterrupt, Terminated) as e:
        report["first"] = type(e).__name__
    report["target_whole"] = TARGET in sys.modules
    report["seen"] = bool(seen)
    cfg = tlm.load_config("cornell", SMALL)
    report["second"] = [cfg.scene, cfg.mode]
    report["handlers_back"] = signal.getsignal(SIG) in (signal.default_int_handler, terminate)
    print(json.dumps(report))
""")


@pytest.mark.parametrize(("sig", "stopped"), [("SIGINT", "KeyboardInterrupt"), ("SIGTERM", "Terminated")])
def test_a_signal_during_the_first_use_of_tlm_leaves_tlm_api_whole(sig, stopped, tmp_path):
    """A signal while ``tlm.load_config`` first imports tlm.api (simpy's resources, half-way
    through simpy's own import) still stops that line, once the import is whole. (Cut off,
    it left simpy half imported, and every later use of tlm failed: ``module 'simpy' has no
    attribute 'events'``.)"""
    out = _run(FIRST_USE, "simpy.resources.container", sig, "1", cwd=tmp_path, cache=tmp_path / "cache")
    assert out["api_before"] is False and out["seen"] is True
    assert out["first"] == stopped
    assert out["target_whole"] is True  # (was: cut off, simpy left half imported)
    assert out["second"] == ["cornell", "reflect"] and out["handlers_back"] is True


RENDER = HOOK + textwrap.dedent("""
    signal.signal(signal.SIGTERM, terminate)
    cfg = tlm.load_config("cornell", SMALL)
    try:
        tlm.render_image(cfg)
        report["first"] = "finished"
    except Terminated:
        report["first"] = "terminated"
    report["target_whole"] = TARGET in sys.modules
    for call in ("second", "third"):
        try:
            report[call] = float(tlm.render_image(cfg).composite.sum())
        except BaseException as e:
            report[call] = f"{type(e).__name__}: {e}"
    print(json.dumps(report))
""")


@pytest.mark.slow
def test_a_sigterm_during_the_first_renders_imports_leaves_the_process_working(tmp_path):
    pytest.importorskip("numba")
    out = _run(RENDER, "numba.core.types", "SIGTERM", "1", cwd=tmp_path, cache=tmp_path / "cache")
    assert out["numba_before"] is False
    assert out["first"] == "terminated"  # the handler's exception still stops the call ...
    assert out["target_whole"] is True  # ... once the import it came in is complete
    assert isinstance(out["second"], float), out["second"]  # and every later call works
    assert out["third"] == out["second"]


@pytest.mark.slow
def test_a_second_sigterm_during_the_import_says_to_restart(tmp_path):
    pytest.importorskip("numba")
    out = _run(RENDER, "numba.core.types", "SIGTERM", "2", cwd=tmp_path, cache=tmp_path / "cache")
    assert out["first"] == "terminated" and out["target_whole"] is False
    for call in ("second", "third"):
        assert out[call].startswith("RuntimeError: a second signal (SIGTERM) interrupted the import of numba"), out
        assert "restart the Python process" in out[call]


CLI = HOOK + CLI_RUN


def test_tlm_run_terminated_during_the_import_exits_143_once_it_is_whole(tmp_path):
    pytest.importorskip("numba")
    out = _run(CLI, "numba.core.types", "SIGTERM", "1", cwd=tmp_path, cache=tmp_path / "cache")
    assert out["rc"] == 128 + signal.SIGTERM and out["out"] is False
    assert out["stderr"].rstrip().endswith("tlm: terminated (SIGTERM)")
    assert out["target_whole"] is True


class Terminated(Exception):
    pass


def _terminate(signum, frame):
    raise Terminated(signum)


def test_a_sigterm_a_handler_raises_on_is_held_to_the_imports_end(tmp_path, monkeypatch):
    """In this process: a SIGTERM during an import (a module of tmp_path's) is held to its
    end and then given to the handler; outside an import it goes through at once; the
    handlers are put back when the call ends. A SIGTERM with its default action is left to
    the kernel: nothing is installed for it."""
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _terminate)
    try:
        installed: list = []
        call, reached = signalled_call(tmp_path, monkeypatch, signal.SIGTERM, "tlm_test_term_import", installed)
        with pytest.raises(Terminated):
            call(False)
        assert reached == [] and isinstance(installed[-1], HeldInterrupt)
        with pytest.raises(Terminated):
            call(True)
        assert sys.modules["tlm_test_term_import"].WHOLE is True and reached == [True]
        assert signal.getsignal(signal.SIGTERM) is _terminate
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler

        signal.signal(signal.SIGTERM, signal.SIG_DFL)  # the default: the process ends at once, never held
        sys.modules.pop("tlm_test_term_import")

        @imports_whole
        def plain() -> None:
            installed.append(signal.getsignal(signal.SIGTERM))

        plain()
        assert installed[-1] == signal.SIG_DFL and signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    finally:
        sys.modules.pop("tlm_test_term_import", None)
        for s, h in before.items():
            signal.signal(s, h)
