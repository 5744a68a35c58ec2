"""numba's ``njit`` for tlm's compiled modules, with the on-disk cache keyed on all of them.

numba keys a cached function (``@njit(cache=True)``) on its own source file only: a kernel
that calls or inlines a compiled helper of another file keeps running the helper's old
code after that file is edited, until its own file changes (numba's documented
limitation, "changes in symbols defined in another file are not recognized"). tlm's
kernels do call across files (``_jit_fgather`` -> ``_jit_photons`` and ``_jit_hash``,
``_jit``, ``_jit_bsp``, ``_jit_cones`` and ``_jit_photons`` -> ``_jit_leaf``), so an edit of a helper
could leave an editable install, or a checkout's ``__pycache__``, computing with the
helper as it was: images and work that match neither the new source nor the tests.

Importing this module wraps numba's source-file cache locators (:func:`install`) so that
every function defined in one of :func:`compiled_sources` is stamped with
:func:`package_stamp`, a hash of the content of *all* of them: an edit of any one
recompiles every kernel on its next call (the compile the first run after an install
does anyway). Functions in any other file, tlm's or not, keep numba's own stamp. The
compiled modules take ``njit`` (and ``prange``) from here, so the wrapping is in place
before their functions are decorated (numba picks a function's locator then), and
importing the rest of :mod:`tlm.kernels` does not import numba.

Where no folder can hold the compiled code (a read-only install, no writable ``~/.cache``,
``NUMBA_CACHE_DIR`` unset: numba raises "no locator available" when the function is
decorated), tlm's compiled files are cached in ``numba/`` of tlm's own cache folder
(:func:`tlm.caches.cache_home`: ``$TLM_CACHE`` may point somewhere writable) where that
can be written, else compiled without the on-disk cache: the same code, compiled again in
each process. That is said once a process, one line on stderr (:func:`njit`).

Not covered: a package run from a zip file (no files to hash: numba's own stamps), and
``NUMBA_CACHE_LOCATOR_CLASSES``, which names numba's classes and so bypasses the wrapping.
``tests/test_numba_cache.py`` checks that every file of tlm with a cached function is
one of :func:`compiled_sources` and takes ``njit`` from here.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import os
import threading
from pathlib import Path

from numba import njit as _numba_njit
from numba import prange

__all__ = ["compiled_sources", "install", "njit", "package_stamp", "prange", "stamp_of"]

PACKAGE = Path(__file__).resolve().parents[1]  # tlm/
# the files whose compiled functions may call each other's: tlm/kernels/_jit*.py and the
# reference's compiled estimate (tlm/experiments/_reference_jit.py)
SOURCES = (("kernels", "_jit*.py"), ("experiments", "_*jit.py"))


def compiled_sources(package: Path = PACKAGE) -> tuple[Path, ...]:
    """The package's files of compiled functions, in name order."""
    return tuple(sorted(p.resolve() for folder, pattern in SOURCES for p in (package / folder).glob(pattern)))


def stamp_of(paths: tuple[Path, ...]) -> str:
    """A hash of the files' names and contents, in the given order (no modification times:
    a checkout or a copy that keeps the content keeps the stamp)."""
    h = hashlib.sha256()
    for p in paths:
        data = p.read_bytes()
        h.update(f"{p.name}\0{len(data)}\0".encode())
        h.update(data)
    return h.hexdigest()


@functools.lru_cache(maxsize=4)
def _stamp(key: tuple) -> str:
    return stamp_of(tuple(Path(name) for name, _, _ in key))


def package_stamp() -> str:
    """:func:`stamp_of` the package's :func:`compiled_sources`, hashed again only when a
    file's size or modification time moved (an edit, then ``importlib.reload``, in one
    process: the reloaded functions get the new stamp, as numba's own stamp does)."""
    key = []
    for p in compiled_sources():
        st = os.stat(p)
        key.append((str(p), st.st_mtime_ns, st.st_size))
    return _stamp(tuple(key))


@functools.cache
def _covered() -> frozenset[str]:
    return frozenset(str(p) for p in compiled_sources())


class _PackageStamp:
    """Mixed into a numba locator: tlm's compiled files get the package's stamp."""

    def get_source_stamp(self):
        if _mine(getattr(self, "_py_file", "")):
            return ("tlm-kernels", package_stamp())
        return super().get_source_stamp()  # type: ignore[misc]


def _mine(py_file: str) -> bool:
    try:
        return str(Path(py_file).resolve()) in _covered()
    except OSError:
        return False


def _tlm_cache_locator(caching) -> type:
    """A locator of the last resort, for tlm's compiled files only: ``<tlm's cache>/numba``
    (:func:`tlm.caches.cache_home`), where numba's own folders cannot be written."""

    class TlmCacheRootLocator(_PackageStamp, caching._SourceFileBackedLocatorMixin, caching._CacheLocator):
        def __init__(self, py_func, py_file):
            from tlm.caches import cache_home

            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._cache_path = str(cache_home() / "numba" / self.get_suitable_cache_subpath(py_file))

        def get_cache_path(self):
            return self._cache_path

        @classmethod
        def from_function(cls, py_func, py_file):
            if not _mine(py_file):
                return None
            return super().from_function(py_func, py_file)  # (None where its folder cannot be written)

    return TlmCacheRootLocator


def install() -> bool:
    """Wrap numba's source-file locators, and add tlm's cache folder as the last one
    (once; idempotent). False where numba's caching module lacks what this needs (then
    numba's own stamps stand: the test fails)."""
    from numba.core import caching

    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)  # (numba 0.6x: private)
    mixin = getattr(caching, "_SourceFileBackedLocatorMixin", None)
    if impl is None or mixin is None or not isinstance(getattr(impl, "_locator_classes", None), list) \
            or not isinstance(getattr(caching, "_CacheLocator", None), type):
        return False
    classes = impl._locator_classes
    for i, cls in enumerate(classes):
        if isinstance(cls, type) and issubclass(cls, mixin) and not issubclass(cls, _PackageStamp):
            classes[i] = type(f"Tlm{cls.__name__}", (_PackageStamp, cls), {"__module__": __name__})
    if not any(getattr(cls, "__name__", "") == "TlmCacheRootLocator" for cls in classes):
        classes.append(_tlm_cache_locator(caching))
    return True


_UNCACHED: list[str] = []  # the line said when a function found no folder for its compiled code
_UNCACHED_LOCK = threading.Lock()


def njit(*args, **kwargs):
    """numba's ``njit``. With ``cache=True`` where no folder can hold the compiled code
    (numba raises "no locator available" as it decorates), the function is compiled
    without the on-disk cache instead (the same code, compiled in each process again),
    said once a process (:func:`tlm.storage.warn`)."""
    if not kwargs.get("cache"):
        return _numba_njit(*args, **kwargs)
    if args and inspect.isfunction(args[0]):  # (njit(f, cache=True))
        return _cached_or_not(args[0], args[1:], kwargs)
    return lambda func: _cached_or_not(func, args, kwargs)


def _cached_or_not(func, args: tuple, kwargs: dict):
    try:
        return _numba_njit(*args, **kwargs)(func)
    except RuntimeError as e:
        if "no locator available" not in str(e):
            raise
    with _UNCACHED_LOCK:  # (said once, though two threads import compiled modules at once)
        if not _UNCACHED:
            _UNCACHED.append(_uncached_line(inspect.getfile(func)))
            from tlm.storage import warn

            warn(_UNCACHED[0])
    return _numba_njit(*args, **{**kwargs, "cache": False})(func)


def _uncached_line(py_file: str) -> str:
    """Where numba looked for a folder to write the compiled code of ``py_file`` in, and what to do."""
    from numba.core import config

    from tlm.caches import cache_home

    places = [f"NUMBA_CACHE_DIR={config.CACHE_DIR}" if config.CACHE_DIR else "NUMBA_CACHE_DIR unset",
              str(Path(py_file).parent / "__pycache__")]
    try:
        from numba.misc.appdirs import AppDirs

        places.append(AppDirs(appname="numba", appauthor=False).user_cache_dir)
    except Exception:  # (numba's private helper moved: the line names the others)
        pass
    if _mine(py_file):
        places.append(str(cache_home() / "numba"))
    return (f"numba cannot write its compiled kernels anywhere ({', '.join(places)}: none can be written): "
            "they are compiled again in each process; set NUMBA_CACHE_DIR to a writable folder")


install()
