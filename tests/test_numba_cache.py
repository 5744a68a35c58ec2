"""numba's on-disk cache of the compiled kernels follows an edit of any compiled file.

numba keys a cached function on its own file only, so a kernel inlining a helper of another
file kept the helper's old code after an edit (:mod:`tlm.kernels._numba_cache`).
"""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
from pathlib import Path

import pytest
from numba.core.dispatcher import Dispatcher

from tests._subproc import probe_copy
from tlm.kernels import _numba_cache

REPO = Path(__file__).resolve().parents[1]


def compiled_modules() -> list:
    names = [f"tlm.{p.parent.name}.{p.stem}" for p in _numba_cache.compiled_sources()]
    return [importlib.import_module(n) for n in names]


def test_every_cached_kernel_is_stamped_with_all_compiled_files():
    assert _numba_cache.install(), "numba's caching module no longer has the locators this wraps"
    stamp = ("tlm-kernels", _numba_cache.package_stamp())
    checked = []
    for module in compiled_modules():
        for name, obj in vars(module).items():
            if isinstance(obj, Dispatcher) and obj.__module__ == module.__name__ and obj._cache.__class__.__name__ \
                    != "NullCache":
                assert obj._cache._impl.locator.get_source_stamp() == stamp, f"{module.__name__}.{name}"
                checked.append(name)
    # the kernels that call across files among them (fg_bounce -> _jit_photons, level_sums -> _jit)
    assert {"fg_bounce", "level_sums", "trace", "bounce", "hash_uniform"} <= set(checked)
    assert len(checked) >= 20


def test_the_stamp_follows_every_files_content_not_its_time(tmp_path):
    a, b = tmp_path / "_jit_a.py", tmp_path / "_jit_b.py"
    a.write_text("x = 1\n")
    b.write_text("y = 2\n")
    first = _numba_cache.stamp_of((a, b))
    os.utime(a, (1, 1))  # a checkout or a copy that keeps the content keeps the stamp
    assert _numba_cache.stamp_of((a, b)) == first
    b.write_text("y = 3\n")  # the other file's edit changes it
    assert _numba_cache.stamp_of((a, b)) != first
    b.write_text("y = 2\n")
    assert _numba_cache.stamp_of((a, b)) == first
    a.write_text("x = 1\n\n")
    assert _numba_cache.stamp_of((a, b)) != first


def test_every_file_with_a_cached_function_is_covered_and_takes_njit_from_here():
    """A new compiled file outside the patterns, or one decorating with numba's own njit
    before the wrapping is in place, would be keyed on itself alone again."""
    covered = set(_numba_cache.compiled_sources())
    assert {"_jit.py", "_jit_photons.py", "_jit_fgather.py", "_jit_bsp.py", "_reference_jit.py"} <= {
        p.name for p in covered}
    cached = set()
    for path in (REPO / "tlm").rglob("*.py"):
        text = path.read_text()
        if "cache=True" in text and path.name != "_numba_cache.py":
            cached.add(path.resolve())
            assert "from tlm.kernels._numba_cache import" in text, path
            assert "from numba import njit" not in text and "numba.njit" not in text, path
    assert cached == covered


def test_an_edited_file_changes_the_stamp_in_the_same_process(tmp_path, monkeypatch):
    """Edited, then reloaded in one process: the reloaded functions get a new stamp."""
    files = (tmp_path / "_jit_a.py", tmp_path / "_jit_b.py")
    for f in files:
        f.write_text("x = 1\n")
    monkeypatch.setattr(_numba_cache, "compiled_sources", lambda: files)
    first = _numba_cache.package_stamp()
    assert _numba_cache.package_stamp() == first
    files[1].write_text("x = 22\n")
    assert _numba_cache.package_stamp() != first


def test_importing_the_kernels_package_does_not_import_numba():
    code = "import sys, tlm.kernels, tlm.kernels.bsp; print('numba' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"


PROBE = """from tlm.kernels._jit_leaf import _mn
from tlm.kernels._numba_cache import njit


@njit(cache=True)
def probe(a, b):
    return _mn(a, b)
"""


@pytest.mark.slow
def test_an_edit_of_a_helper_recompiles_the_kernel_that_inlines_it(tmp_path):
    """A copy of the package with a cached kernel inlining ``_jit_leaf._mn`` (another file): run,
    edit ``_mn`` alone, run again. numba's own stamps would load the first build (1.0)."""
    root, run_copy = probe_copy(tmp_path, PROBE)

    def run() -> str:
        return run_copy().stdout.strip()  # (its exit status 0 asserted there)

    assert run() == "1.0"
    cached = list((root / "tlm" / "kernels" / "__pycache__").glob("_jit_probe.probe-*.nbi"))
    assert cached, "the probe's build was cached (else the second run proves nothing)"
    jit = root / "tlm" / "kernels" / "_jit_leaf.py"
    source = jit.read_text()
    body = '    if a != a:\n        return a\n    if a < b:\n        return a\n    return b\n'
    assert source.count(body) == 1
    jit.write_text(source.replace(body, "    return b\n"))  # _mn edited: now the second operand
    assert run() == "2.0"
