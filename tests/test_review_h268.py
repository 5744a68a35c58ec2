"""Review h268 of 8aad659 (interrupts during imports): a Ctrl-C that ends a render, after an import that failed
of itself and that tlm caught (numba's ImportError: tlm runs on numpy), said "restart the Python process" in
every later call; a signal handler's raise of an Exception (``RuntimeError``) that cut numba's import was not
noticed (the next call: ``module 'numba' has no attribute 'core'``); a cached kernel whose bytes read whole but
whose compiled code does not load (``LLVM bitcode parsing error``) was never removed (the same error in every
call, every process); an interrupt that a handler raised as a cached kernel loaded, with its files damaged,
was taken for the damage and swallowed."""

from __future__ import annotations

import contextlib
import io
import pickle
import pickletools
import signal
import sys
import types

import pytest

import tlm.whole_imports as whole
from tests._subproc import probe_copy
from tlm.whole_imports import imports_whole

POSIX = pytest.mark.skipif(not hasattr(signal, "SIGUSR1"), reason="POSIX signals")


@pytest.fixture
def packages(tmp_path, monkeypatch):
    """``make(name, tail)``: a package ``name`` in ``tmp_path`` whose ``__init__`` imports its submodule ``sub``,
    then runs ``tail``; the modules removed at the end, the notes of half imports the test's own."""
    monkeypatch.setattr(whole, "_LEFT_HALF", {})
    monkeypatch.setattr(whole, "_HALF_RUN", {})
    monkeypatch.syspath_prepend(str(tmp_path))
    made = []

    def make(name: str, tail: str) -> None:
        (tmp_path / name).mkdir()
        (tmp_path / name / "sub.py").write_text("X = 1\n")
        (tmp_path / name / "__init__.py").write_text(f"import signal\nfrom {name} import sub\n{tail}\n")
        made.append(name)

    yield make
    for name in made:
        for module in (name, f"{name}.sub"):
            sys.modules.pop(module, None)


def test_a_ctrl_c_in_a_render_after_an_import_that_failed_of_itself_leaves_the_next_call_working(packages):
    """numba's import fails of itself after some of its submodules (an ImportError: llvmlite too old), tlm
    catches it and runs on numpy (tlm.kernels.engine.numba_available); a Ctrl-C then ends the render, after
    every import. Before: the next call, and every one after it, raised "an exception (KeyboardInterrupt)
    interrupted the import of ... restart the Python process" (a restart does the same again)."""
    packages("tlm_h268_broken", "raise ImportError('stand-in: llvmlite is too old')")

    @imports_whole
    def call(render: bool) -> str:
        if render:
            with contextlib.suppress(ImportError):  # (as numba_available: the numpy kernels then)
                __import__("tlm_h268_broken")
            signal.raise_signal(signal.SIGINT)  # (a Ctrl-C in the render: no import under way)
        return "ran"

    with pytest.raises(KeyboardInterrupt):
        call(True)
    assert "tlm_h268_broken.sub" in sys.modules and "tlm_h268_broken" not in sys.modules
    assert call(False) == "ran"
    assert call(False) == "ran"


@POSIX
def test_an_exception_a_signal_handler_raised_that_cut_an_import_is_said_by_the_next_call(packages):
    """A SIGUSR1 whose handler raises a RuntimeError (an Exception, not a KeyboardInterrupt) cuts a package's
    import after its first submodule: the next call says to restart, naming the exception. A RuntimeError of
    the package's own code leaves no such error. Before: the next call ran on (with numba: ``module 'numba'
    has no attribute 'core'``, /tmp/h268/pA.py)."""
    packages("tlm_h268_own", "raise RuntimeError('its own')")
    packages("tlm_h268_cut", "signal.raise_signal(signal.SIGUSR1)")

    def timeout(signum, frame):
        raise RuntimeError("a handler's")

    before = signal.signal(signal.SIGUSR1, timeout)

    @imports_whole
    def call(name: str | None) -> str:
        if name:
            __import__(name)
        return "ran"

    try:
        with pytest.raises(RuntimeError, match="its own"):
            call("tlm_h268_own")
        assert "tlm_h268_own.sub" in sys.modules and call(None) == "ran"
        with pytest.raises(RuntimeError, match="a handler's"):
            call("tlm_h268_cut")
        assert "tlm_h268_cut.sub" in sys.modules and "tlm_h268_cut" not in sys.modules
        for _ in range(2):
            with pytest.raises(RuntimeError, match=r"^an exception \(RuntimeError\) interrupted the import of "
                                                   r"tlm_h268_cut in an earlier call .*: restart the Python process"):
                call(None)
    finally:
        signal.signal(signal.SIGUSR1, before)


def _cache_entry(tmp_path, data: bytes | None = None):
    """A stand-in for numba's ``Cache`` of one of tlm's files (its locator tlm's): an index ``probe.nbi`` and
    its data file ``probe.1.nbc``, both read whole by pickle (the data ``data`` where given)."""
    nc = pytest.importorskip("tlm.kernels._numba_cache")
    index, entry = tmp_path / "probe.nbi", tmp_path / "probe.1.nbc"
    index.write_bytes(pickle.dumps("0.68.1", protocol=-1) + pickle.dumps(("stamp", {"key": entry.name}), -1))
    entry.write_bytes(data if data is not None else pickle.dumps((b"ELF", b"BC\xc0\xde"), protocol=-1))

    class Locator(nc._PackageStamp):
        pass

    cache = types.SimpleNamespace(
        _impl=types.SimpleNamespace(locator=Locator()), _name="probe",
        _cache_file=types.SimpleNamespace(_index_path=str(index), _load_index=lambda: {"key": entry.name}),
        _index_key=lambda sig, codegen: "key")
    context = types.SimpleNamespace(codegen=lambda: None)
    return nc, cache, context, (index, entry)


def test_a_cached_kernel_whose_compiled_code_does_not_load_is_removed(tmp_path, monkeypatch, capsys):
    """The files read whole by pickle, but numba cannot load the code in them (bytes zeroed inside its LLVM
    bitcode): the files are removed and the kernel compiled again. Before: raised, in every call of every
    process (``RuntimeError: LLVM bitcode parsing error``), the files left. What a package left half
    imported raises (``module 'tlm_h268_half' has no attribute 'core'`` where ``tlm_h268_half.core`` is
    imported: a numba cut half-way, as its contexts are refreshed) still removes nothing."""
    nc, cache, context, files = _cache_entry(tmp_path)
    monkeypatch.setitem(sys.modules, "tlm_h268_half", types.ModuleType("tlm_h268_half"))
    monkeypatch.setitem(sys.modules, "tlm_h268_half.core", types.ModuleType("tlm_h268_half.core"))

    def half(self, sig, target_context):
        return sys.modules["tlm_h268_half"].core

    def load(self, sig, target_context):
        raise RuntimeError("LLVM bitcode parsing error\nInvalid encoding")

    with pytest.raises(AttributeError, match="no attribute 'core'"):
        nc._damage_safe(half)(cache, "sig", context)
    assert all(f.exists() for f in files) and nc._bytes_whole(cache._cache_file)
    assert nc._damage_safe(load)(cache, "sig", context) is None
    assert not any(f.exists() for f in files)
    assert "damaged" in capsys.readouterr().err


@POSIX
def test_an_interrupt_a_handler_raised_as_a_kernel_loaded_is_not_taken_for_damage(tmp_path):
    """A timeout's handler raises a RuntimeError as a cached kernel is loaded, its data file damaged (cut
    off): the RuntimeError goes on (the call stops, as the user asked). Before: it was taken for the
    damage's, the files removed and the call ran on, the timeout lost."""
    whole_data = pickle.dumps((b"ELF", b"BC\xc0\xde"), protocol=-1)
    nc, cache, context, files = _cache_entry(tmp_path, whole_data[:-3])
    assert not nc._bytes_whole(cache._cache_file)

    def timeout(signum, frame):
        raise RuntimeError("timed out")

    def load(self, sig, target_context):
        signal.raise_signal(signal.SIGUSR1)

    before = signal.signal(signal.SIGUSR1, timeout)
    try:
        with pytest.raises(RuntimeError, match="timed out"):
            nc._damage_safe(load)(cache, "sig", context)
    finally:
        signal.signal(signal.SIGUSR1, before)
    assert all(f.exists() for f in files)


PROBE = """from tlm.kernels._numba_cache import njit


@njit(cache=True)
def probe(a, b):
    return a * 10.0 + b
"""


@pytest.mark.slow
def test_a_cached_kernel_zeroed_inside_its_bitcode_is_removed_and_compiled_again(tmp_path):
    """A real cache entry, its data file zeroed inside the LLVM bitcode it holds (its pickle still reads
    whole): a warning naming it, the right answer, the entry written again. Before: ``RuntimeError: LLVM
    bitcode parsing error`` in every process."""
    pytest.importorskip("numba")
    root, run_copy = probe_copy(tmp_path, PROBE, {"TLM_CACHE": str(tmp_path / "cache")})
    assert run_copy().stdout.strip() == "12.0"
    (data,) = (root / "tlm" / "kernels" / "__pycache__").glob("_jit_probe.probe-*.nbc")
    raw = bytearray(data.read_bytes())
    (start, size), = [(pos, len(arg)) for op, arg, pos in pickletools.genops(io.BytesIO(bytes(raw)))
                      if isinstance(arg, bytes) and arg.startswith(b"BC\xc0\xde")]
    at = raw.index(b"BC\xc0\xde", start)  # (the bitcode's first 64 bytes zeroed: the pickle reads whole)
    assert at + 64 < start + size
    raw[at: at + 64] = bytes(64)
    data.write_bytes(bytes(raw))
    done = run_copy()
    assert done.stdout.strip() == "12.0"
    assert str(data) in done.stderr and "damaged" in done.stderr and "compiled again" in done.stderr, done.stderr
    assert data.read_bytes() != bytes(raw) and run_copy().stderr == ""
