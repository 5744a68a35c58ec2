"""Findings of the Python API probe h258: a timeout's SIGALRM (a handler that raises KeyboardInterrupt, as
notebooks' timeouts do) cut numba's import in a first call and left the process broken, and tlm then removed
valid numba cache files as "damaged"; an interrupt no signal tlm holds raises is noticed (the next call says to
restart); ``out=""`` named as given; a report's missing folder said "not found"; a ``base`` that is no folder."""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

import tlm
import tlm.whole_imports as whole
from tests._subproc import probe_copy
from tests.helpers_interrupt import signalled_call
from tlm.errors import InputError
from tlm.whole_imports import imports_whole

POSIX = pytest.mark.skipif(not hasattr(signal, "SIGALRM"), reason="POSIX signals")


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt("alarm")


@POSIX
def test_a_timeouts_sigalrm_during_an_import_is_held_to_its_end(tmp_path, monkeypatch):
    """Before: SIGALRM went to its handler at once, inside the import: the KeyboardInterrupt cut it short
    (numba: ``module 'numba' has no attribute 'core'`` in every later call)."""
    assert signal.SIGALRM in whole.HELD
    before = signal.signal(signal.SIGALRM, _raise_interrupt)
    try:
        call, reached = signalled_call(tmp_path, monkeypatch, signal.SIGALRM, "tlm_test_alarm_import")
        with pytest.raises(KeyboardInterrupt):
            call(True)
        assert sys.modules["tlm_test_alarm_import"].WHOLE is True and reached == [True]
        assert signal.getsignal(signal.SIGALRM) is _raise_interrupt  # (put back)
    finally:
        sys.modules.pop("tlm_test_alarm_import", None)
        signal.signal(signal.SIGALRM, before)


@POSIX
def test_an_interrupt_no_held_signal_raised_that_cut_an_import_is_said_by_the_next_call(tmp_path, monkeypatch):
    """A SIGUSR1 whose handler raises KeyboardInterrupt (not held) cuts a package's import after its first
    submodule: the next call raises the RuntimeError that says to restart, not an AttributeError deep in the
    package. A package whose import fails of itself (an ImportError) leaves no such error: its calls go on.
    Before: the next call ran on, with the package half imported."""
    monkeypatch.setattr(whole, "_LEFT_HALF", {})
    monkeypatch.setattr(whole, "_HALF_RUN", {}, raising=False)
    for name, tail in (("tlm_h263_fails", "raise ImportError('a missing dependency')"),
                       ("tlm_h263_cut", "signal.raise_signal(signal.SIGUSR1)")):
        (tmp_path / name).mkdir()
        (tmp_path / name / "sub.py").write_text("X = 1\n")
        (tmp_path / name / "__init__.py").write_text(f"import signal\nfrom {name} import sub\n{tail}\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    before = signal.signal(signal.SIGUSR1, _raise_interrupt)

    @imports_whole
    def call(name: str | None) -> str:
        if name:
            __import__(name)
        return "ran"

    try:
        with pytest.raises(ImportError):
            call("tlm_h263_fails")
        assert "tlm_h263_fails.sub" in sys.modules and call(None) == "ran"
        with pytest.raises(KeyboardInterrupt):
            call("tlm_h263_cut")
        assert "tlm_h263_cut.sub" in sys.modules and "tlm_h263_cut" not in sys.modules
        for _ in range(2):
            with pytest.raises(RuntimeError, match=r"^an exception \(KeyboardInterrupt\) interrupted the import of "
                                                   r"tlm_h263_cut in an earlier call .*: restart the Python process"):
                call(None)
    finally:
        signal.signal(signal.SIGUSR1, before)
        for name in ("tlm_h263_fails.sub", "tlm_h263_cut.sub"):
            sys.modules.pop(name, None)


def test_a_module_an_interrupt_left_half_run_is_said_by_the_next_call(tmp_path, monkeypatch):
    """A module left in ``sys.modules`` with its spec still initializing (what Python's import leaves
    where an interrupt lands in its own bookkeeping: ``partially initialized module 'yaml' has no attribute
    'error'`` in every later call): the next call says to restart. Here the module stands in for that state
    itself. Before: the next call ran on."""
    monkeypatch.setattr(whole, "_LEFT_HALF", {})
    monkeypatch.setattr(whole, "_HALF_RUN", {}, raising=False)
    (tmp_path / "tlm_h263_half.py").write_text(
        "import importlib.util, sys\n"
        "spec = importlib.util.spec_from_loader('tlm_h263_halfrun', loader=None)\n"
        "spec._initializing = True\n"
        "sys.modules['tlm_h263_halfrun'] = importlib.util.module_from_spec(spec)\n"
        "raise KeyboardInterrupt\n")
    monkeypatch.syspath_prepend(str(tmp_path))

    @imports_whole
    def call(name: str | None) -> str:
        if name:
            __import__(name)
        return "ran"

    try:
        with pytest.raises(KeyboardInterrupt):
            call("tlm_h263_half")
        with pytest.raises(RuntimeError, match=r"^an exception \(KeyboardInterrupt\) interrupted the import of "
                                               r"tlm_h263_halfrun .* half run.*restart the Python process"):
            call(None)
        sys.modules.pop("tlm_h263_halfrun")  # (gone: nothing to say)
        assert call(None) == "ran"
    finally:
        sys.modules.pop("tlm_h263_halfrun", None)


PROBE = """from tlm.kernels._numba_cache import njit


@njit(cache=True)
def probe(a, b):
    return a * 10.0 + b
"""

HALF_NUMBA = """import signal, sys
sys.path.insert(0, {root!r})
signal.signal(signal.SIGUSR1, lambda signum, frame: (_ for _ in ()).throw(KeyboardInterrupt()))


class Hook:  # a KeyboardInterrupt in numba's import, when numba.core.types is first looked for
    def find_spec(self, name, path=None, target=None):
        if name == "numba.core.types" and not getattr(self, "done", False):
            self.done = True
            signal.raise_signal(signal.SIGUSR1)


sys.meta_path.insert(0, Hook())
try:
    import numba  # noqa: F401
except KeyboardInterrupt:
    pass
try:
    from tlm.kernels._jit_probe import probe
    print(probe(1.0, 2.0))
except Exception as e:
    print(type(e).__name__, e)
"""


@pytest.mark.slow
def test_a_half_imported_numba_removes_no_cached_file(tmp_path):
    """numba left half imported in a process (no tlm call around it), then a cached kernel called: numba's
    load fails (``module 'numba' has no attribute 'core'``) though the files are whole. Before: the files
    were said damaged and removed."""
    pytest.importorskip("numba")
    root, run_copy = probe_copy(tmp_path, PROBE, {"TLM_CACHE": str(tmp_path / "cache")})
    assert run_copy().stdout.strip() == "12.0"
    cache = root / "tlm" / "kernels" / "__pycache__"
    files = {p: p.read_bytes() for p in cache.glob("_jit_probe.probe-*.nb[ic]")}
    assert len(files) == 2
    done = subprocess.run([sys.executable, "-c", HALF_NUMBA.format(root=str(root))], capture_output=True,
                          text=True, cwd=tmp_path, timeout=300)
    assert "no attribute 'core'" in done.stdout, (done.stdout, done.stderr)
    assert "damaged" not in done.stderr and "removed" not in done.stderr, done.stderr
    assert {p: p.read_bytes() for p in cache.glob("_jit_probe.probe-*.nb[ic]")} == files
    assert run_copy().stdout.strip() == "12.0"


def test_an_empty_out_is_named_as_given(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match=r"^out: '' is the current folder"):
        tlm.run("cornell", "")


def test_a_report_of_a_folder_that_is_not_there_says_not_found(tmp_path):
    with pytest.raises(InputError, match=r"nosuchrun: not found$"):
        tlm.write_report(tmp_path / "nosuchrun")
    assert not (tmp_path / "nosuchrun").exists()


def test_a_base_that_is_no_folder_is_refused(tmp_path):
    (tmp_path / "afile").write_text("x")
    for base, why in (("nosuchdir", "not found"), ("afile", "a file")):
        with pytest.raises(InputError, match=rf"^base: '.*{base}' is not a folder \({why}\)"):
            tlm.load_config({"scene": "cornell"}, base=str(tmp_path / base))
    assert tlm.load_config({"scene": "cornell"}, base=tmp_path).base == tmp_path
