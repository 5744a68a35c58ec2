"""A cached kernel that cannot be loaded for want of memory is not a damaged file.

Under ``ulimit -v`` numba's load of a whole ``.nbi`` index can fail with ``MemoryError: Out of memory
interning an attribute name``. That was taken for the files' damage: a warning calling whole files
damaged, the function's cached code removed, and the compile that followed (needing more memory than
the load) ended the process in LLVM's abort instead of tlm's out-of-memory line."""

from __future__ import annotations

import pytest

from .test_errors_replaced_h289 import _whole_cache_entry as _cache_entry  # (one stand-in)


def test_a_memory_error_loading_whole_files_is_raised_and_removes_none(tmp_path, capsys):
    nc = pytest.importorskip("tlm.kernels._numba_cache")
    cache, context, files = _cache_entry(tmp_path, nc)

    def load(self, sig, target_context):
        raise MemoryError("Out of memory interning an attribute name")

    with pytest.raises(MemoryError):
        nc._damage_safe(load)(cache, "sig", context)
    assert all(f.exists() for f in files) and "damaged" not in capsys.readouterr().err


def test_a_memory_error_reading_the_files_again_removes_none(tmp_path, capsys, monkeypatch):
    """Where even the check of the files' bytes runs out of memory, nothing is known of them: raised, kept."""
    nc = pytest.importorskip("tlm.kernels._numba_cache")
    cache, context, files = _cache_entry(tmp_path, nc)

    def load(self, sig, target_context):
        raise MemoryError()

    class _Starved:
        def __init__(self, *args, **kwargs):
            raise MemoryError()

    monkeypatch.setattr(nc, "_BytesOnly", _Starved)
    with pytest.raises(MemoryError):
        nc._damage_safe(load)(cache, "sig", context)
    assert all(f.exists() for f in files) and "damaged" not in capsys.readouterr().err


def test_a_memory_error_from_files_that_do_not_read_whole_is_their_damage(tmp_path, capsys):
    """A damaged file can raise a MemoryError of its own (a length field overwritten): where the bytes do
    not read whole, the files are damaged as before: removed and said, the load None."""
    nc = pytest.importorskip("tlm.kernels._numba_cache")
    cache, context, files = _cache_entry(tmp_path, nc)
    files[0].write_bytes(b"\x00" * 16)

    def load(self, sig, target_context):
        raise MemoryError()

    assert nc._damage_safe(load)(cache, "sig", context) is None
    assert not any(f.exists() for f in files) and "damaged" in capsys.readouterr().err
