"""h294, a review of 8e3e56b (InputError.replaced; whole_imports.raised_by_handler).

What tells a handler's raise looked at the whole chain of an error's causes and contexts, the exception
being handled as the work began too: a load of a cached kernel (or an API call) in the ``except`` block of
a timeout caught before (a retry) took its own error, the files' damage or an import failing of itself,
for the timeout's. A Ctrl-C raised by Python's own SIGINT handler (from C: no frame of a handler) that
cut a load whose cleanup then failed was taken for the files' damage. And an API error's ``message``
kept the command line's flags its line no longer names, so that ``replaced`` made another line."""

from __future__ import annotations

import importlib
import pickle
import signal
import sys

import pytest

import tlm.whole_imports as whole
from tlm.api_common import as_arguments
from tlm.errors import InputError

from .test_errors_replaced_h289 import _whole_cache_entry as _cache_entry  # (one stand-in)

POSIX = pytest.mark.skipif(not hasattr(signal, "SIGALRM"), reason="POSIX signals")


def _timeout(signum, frame):
    raise TimeoutError("timed out")


@POSIX
def test_a_load_in_the_except_block_of_a_caught_timeout_still_drops_damaged_files(tmp_path, capsys):
    """A timeout's handler raised and was caught; the retry in its ``except`` block loads a damaged entry
    (EOFError, the timeout its context, though no handler raised during the load): the files' damage,
    removed and said, the load None (compiled again). Before: taken for the timeout's, raised, the retry failed."""
    nc = pytest.importorskip("tlm.kernels._numba_cache")
    cache, context, files = _cache_entry(tmp_path, nc)

    def load(self, sig, target_context):
        raise EOFError("Ran out of input")

    before = signal.signal(signal.SIGALRM, _timeout)
    try:
        try:
            signal.raise_signal(signal.SIGALRM)
        except TimeoutError:
            loaded = nc._damage_safe(load)(cache, "sig", context)
    finally:
        signal.signal(signal.SIGALRM, before)
    assert loaded is None and not any(f.exists() for f in files)
    assert "damaged" in capsys.readouterr().err


@POSIX
def test_a_ctrl_c_of_pythons_own_handler_that_cut_a_load_removes_no_file(tmp_path, capsys):
    """Python's own SIGINT handler (C code: no frame of it in a traceback) raises KeyboardInterrupt as a
    cached kernel loads, and the load's cleanup fails of it (EOFError): the error goes on, the whole files
    stay. Before: taken for damage, the files removed, the Ctrl-C lost (the call ran on)."""
    nc = pytest.importorskip("tlm.kernels._numba_cache")
    cache, context, files = _cache_entry(tmp_path, nc)

    def load(self, sig, target_context):
        try:
            signal.raise_signal(signal.SIGINT)
        finally:
            pickle.loads(b"")  # (the cleanup's own error: EOFError, the KeyboardInterrupt its context)

    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(EOFError) as caught:
            nc._damage_safe(load)(cache, "sig", context)
    finally:
        signal.signal(signal.SIGINT, before)
    assert isinstance(caught.value.__context__, KeyboardInterrupt)
    assert all(f.exists() for f in files) and "damaged" not in capsys.readouterr().err


@POSIX
def test_an_import_failing_of_itself_after_a_caught_timeout_asks_for_no_restart(tmp_path, monkeypatch):
    """An API call in the ``except`` block of a timeout caught before fails of its own import (an
    ImportError that leaves a submodule without its package): no interrupt cut it, so the next call runs.
    Before: the timeout, its context, was taken for the call's interrupt, and every later call raised
    'restart the Python process'."""
    package = tmp_path / "h294pkg"
    package.mkdir()
    (package / "sub.py").write_text("")
    (package / "__init__.py").write_text("import h294pkg.sub\nraise ImportError('of itself')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(whole, "_LEFT_HALF", {})
    monkeypatch.setattr(whole, "_HALF_RUN", {})
    before = signal.signal(signal.SIGALRM, _timeout)
    try:
        try:
            signal.raise_signal(signal.SIGALRM)
        except TimeoutError:
            with pytest.raises(ImportError, match="of itself"):
                whole.imports_whole(lambda: importlib.import_module("h294pkg"))()
        assert "h294pkg.sub" in sys.modules and "h294pkg" not in sys.modules  # (left without its package)
        assert whole.imports_whole(lambda: "ran")() == "ran"
    finally:
        signal.signal(signal.SIGALRM, before)
        sys.modules.pop("h294pkg.sub", None)


def test_an_api_errors_message_names_what_its_line_names():
    """An error of the API naming the arguments (:func:`~tlm.api_common.as_arguments`): its ``message`` as
    its line says it, so that :meth:`~tlm.errors.InputError.replaced` makes the same line (before: the
    flags back, ``--dask``); its source, a file's path, shown as it is (before: ``/tmp/--out/`` shown
    ``/tmp/out/``, another folder)."""
    e = InputError("give --force or --dask local", source="/tmp/--out/a\tb.yaml", key="--jobs")
    as_arguments(e, {"out", "jobs", "force", "dask"}, {"force"})
    assert str(e) == "/tmp/--out/a\\tb.yaml: jobs: give force=True or dask local"
    assert e.message == "give force=True or dask local"
    assert str(e.replaced()) == str(e)
    assert str(e.replaced(source="s.yaml")) == "s.yaml: jobs: give force=True or dask local"
    again = pickle.loads(pickle.dumps(e))
    assert str(again.replaced()) == str(e) and again.message == e.message
