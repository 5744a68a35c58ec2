"""h289: duplicated error plumbing folded. An InputError with a field changed is made by
:meth:`tlm.errors.InputError.replaced` (its line made again from its fields, its class kept), not by
taking another error's line apart by hand; and what tells an exception a signal handler raised is one
function, :func:`tlm.whole_imports.raised_by_handler`, for an import cut short and for the load of a
cached kernel alike. Before: the load of a cached kernel looked at the exception's own traceback only, so
an error that came of a handler's raise (a cleanup's, the raise its context) was taken for the files'
damage and the whole files removed; ``case_named`` made a plain InputError of a subclass."""

from __future__ import annotations

import pickle
import re
import signal
import types
from pathlib import Path

import pytest

import tlm.whole_imports as whole
from tlm.claims import FolderHeld
from tlm.errors import InputError
from tlm.experiments.extreme import case_named
from tlm.experiments.sweep_sets import named

POSIX = pytest.mark.skipif(not hasattr(signal, "SIGUSR1"), reason="POSIX signals")


def test_replaced_makes_the_line_again_from_its_fields():
    e = InputError("must be > 0", source="a\tb.yaml", key="render.spp")
    moved = e.replaced(key="base.render.spp")
    assert str(moved) == str(InputError("must be > 0", source="a\tb.yaml", key="base.render.spp")) \
        == "a\\tb.yaml: base.render.spp: must be > 0"
    assert (moved.message, moved.source, moved.key) == ("must be > 0", "a\tb.yaml", "base.render.spp")
    assert str(e) == "a\\tb.yaml: render.spp: must be > 0" and e.key == "render.spp"  # (the error itself kept)
    assert str(e.replaced(source=None)) == "render.spp: must be > 0"
    assert str(e.replaced(key=None, message="is not a number")) == "a\\tb.yaml: is not a number"
    assert str(e.replaced()) == str(e) and e.replaced() is not e
    assert str(e.under("base")) == "a\\tb.yaml: base.render.spp: must be > 0"


def test_replaced_keeps_the_class_and_its_own_attributes():
    refused = FolderHeld("another run is writing into 'out' (process 1): wait for it to end", key="--out")
    refused.held = ("run", "out", "process 1")
    try:
        raise refused
    except FolderHeld as e:
        moved = e.replaced(key="out")
    assert type(moved) is FolderHeld and isinstance(moved, InputError)  # (exit status 2, as before)
    assert moved.held == ("run", "out", "process 1") and moved.__traceback__ is None
    assert str(moved) == "out: another run is writing into 'out' (process 1): wait for it to end"


def test_a_case_named_error_keeps_its_class_and_its_line_byte_for_byte():
    refused = FolderHeld("is held", source="ext\treme.yaml", key="--out")
    refused.held = ("run", "out", "process 1")
    named = case_named(refused, "ext\treme.yaml", "bad-x")
    assert str(named) == "ext\\treme.yaml (bad-x): --out: is held"
    assert type(named) is FolderHeld and named.held == refused.held
    assert (named.message, named.key, named.source) == ("is held", "--out", "ext\treme.yaml (bad-x)")
    other = InputError("is held", source="other.yaml")
    assert case_named(other, "ext\treme.yaml", "bad-x") is other


def test_a_sweep_points_error_named_keeps_its_class_and_its_line_byte_for_byte():
    refused = FolderHeld("is held", source="a\tb.yaml", key="--out")
    refused.held = ("run", "out", "process 1")
    moved = named(refused, "sweep.yaml (point 2: spp=4)")
    assert str(moved) == "sweep.yaml (point 2: spp=4): --out: is held"
    assert type(moved) is FolderHeld and moved.held == refused.held
    assert str(named(InputError("must be > 0"), "s\tw.yaml")) == "s\\tw.yaml: must be > 0"


def test_no_module_makes_an_input_errors_line_by_hand():
    """Only :class:`~tlm.errors.InputError` says how its line names its source (``path_shown(e.source)``):
    every other module changes a field by :meth:`~tlm.errors.InputError.replaced`."""
    package = Path(__file__).resolve().parents[1] / "tlm"
    by_hand = [f"{path.relative_to(package.parent)}:{i}" for path in sorted(package.rglob("*.py"))
               if path.name != "errors.py"
               for i, line in enumerate(path.read_text().splitlines(), 1)
               if re.search(r"path_shown\([^)]*\.source\)", line)]
    assert by_hand == []


def test_the_numba_cache_tells_a_handlers_raise_by_the_one_function():
    nc = pytest.importorskip("tlm.kernels._numba_cache")
    assert not hasattr(nc, "_raised_by_handler")
    assert nc.raised_by_handler is whole.raised_by_handler


@POSIX
def test_a_handler_passed_on_by_a_held_interrupt_is_a_handlers_raise():
    """A handler that an installed :class:`~tlm.whole_imports.HeldInterrupt` passes its signal to (its
    ``before``) raised the error: a handler's raise, though the error's frames do not pass the held one."""

    def timeout(signum, frame):
        raise RuntimeError("timed out")

    held = whole.HeldInterrupt({signal.SIGUSR1: timeout}, None)
    held.active = False
    before = signal.signal(signal.SIGUSR1, held)
    try:
        with pytest.raises(RuntimeError) as caught:
            timeout(signal.SIGUSR1, None)
        assert whole.raised_by_handler(caught.value)
        assert not whole.raised_by_handler(RuntimeError("of its own"))
    finally:
        signal.signal(signal.SIGUSR1, before)


def _whole_cache_entry(tmp_path, nc):
    """A stand-in for numba's ``Cache`` of one of tlm's files: an index and its data file, both whole."""
    index, entry = tmp_path / "probe.nbi", tmp_path / "probe.1.nbc"
    index.write_bytes(pickle.dumps("0.68.1", protocol=-1) + pickle.dumps(("stamp", {"key": entry.name}), -1))
    entry.write_bytes(pickle.dumps((b"ELF", b"BC\xc0\xde"), protocol=-1))

    class Locator(nc._PackageStamp):
        pass

    cache = types.SimpleNamespace(
        _impl=types.SimpleNamespace(locator=Locator()), _name="probe",
        _cache_file=types.SimpleNamespace(_index_path=str(index), _load_index=lambda: {"key": entry.name}),
        _index_key=lambda sig, codegen: "key")
    return cache, types.SimpleNamespace(codegen=lambda: None), (index, entry)


@POSIX
def test_an_error_that_came_of_a_handlers_raise_as_a_kernel_loaded_removes_no_file(tmp_path, capsys):
    """A timeout's handler raises as a cached kernel loads, and the load's cleanup fails of it (``EOFError``,
    the handler's RuntimeError its context): the error goes on and the whole files stay, as an import cut
    short so is said. Before: only the EOFError's own traceback was looked at: taken for damage, the files
    removed, a warning calling them damaged, and the call ran on, the timeout lost."""
    nc = pytest.importorskip("tlm.kernels._numba_cache")
    cache, context, files = _whole_cache_entry(tmp_path, nc)

    def timeout(signum, frame):
        raise RuntimeError("timed out")

    def load(self, sig, target_context):
        try:
            signal.raise_signal(signal.SIGUSR1)
        finally:
            pickle.loads(b"")  # (the cleanup's own error: EOFError, the timeout's raise its context)

    before = signal.signal(signal.SIGUSR1, timeout)
    try:
        with pytest.raises(EOFError) as caught:
            nc._damage_safe(load)(cache, "sig", context)
    finally:
        signal.signal(signal.SIGUSR1, before)
    assert isinstance(caught.value.__context__, RuntimeError)
    assert all(f.exists() for f in files) and "damaged" not in capsys.readouterr().err
