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

A cached entry of tlm's compiled files that cannot be loaded (its ``.nbc`` data or ``.nbi``
index cut off, zeroed or overwritten: numba raises ``UnpicklingError`` and the like on every
call, naming no file) is named in one warning, its function's files removed and the function
compiled and cached again (:func:`install` wraps numba's ``Cache.load_overload``); a cache
that cannot be written then is said once, and the compiled code runs.

Not covered: a package run from a zip file (no files to hash: numba's own stamps), and
``NUMBA_CACHE_LOCATOR_CLASSES``, which names numba's classes and so bypasses the wrapping.
``tests/test_numba_cache.py`` checks that every file of tlm with a cached function is
one of :func:`compiled_sources` and takes ``njit`` from here.
"""

from __future__ import annotations

import functools
import glob
import hashlib
import inspect
import io
import os
import pickle
import sys
import threading
from pathlib import Path

from numba import njit as _numba_njit
from numba import prange

from tlm.whole_imports import raised_by_handler

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
    cache = getattr(caching, "Cache", None)
    if isinstance(cache, type) and callable(getattr(cache, "load_overload", None)) \
            and not getattr(cache.load_overload, "_tlm_damage", False):
        cache.load_overload = _damage_safe(cache.load_overload)
    if isinstance(cache, type) and callable(getattr(cache, "save_overload", None)) \
            and not getattr(cache.save_overload, "_tlm_damage", False):
        cache.save_overload = _save_safe(cache.save_overload)
    return True


def _damage_safe(load):
    """numba's ``Cache.load_overload``, where a cached entry of tlm's compiled files cannot be
    loaded (its index or data file cut off, zeroed or overwritten: ``UnpicklingError``,
    ``EOFError``, ``ValueError``, ``OSError`` reading it, ...): a warning naming the file,
    the function's index and data files removed (:func:`_drop_damaged`), and None, so that
    numba compiles it again and writes a new entry. Other files' entries: numba's own load.
    An error of a numba left half imported (:func:`_half_imported`: ``module 'numba' has no attribute
    'core'``, as its contexts are refreshed or its data unpickled) and a MemoryError (the process out of
    memory: under ``ulimit -v``, ``Out of memory interning an attribute name``) where the files' bytes read
    whole (:func:`_bytes_whole`; a MemoryError reading them is raised too), and one a signal's handler
    raised during the load, or one that came of it (:func:`tlm.whole_imports.raised_by_handler`: a
    timeout's, a Ctrl-C's; not one the load began in the ``except`` block of, a timeout caught before a
    retry), are raised, no file removed;
    any other error (``LLVM bitcode parsing error``: a file's bytes zeroed inside the compiled code it holds,
    which its pickle reads whole) is the files'."""

    @functools.wraps(load)
    def load_overload(self, sig, target_context):
        handled = sys.exc_info()[1]  # (a load in an ``except`` block, a retry after a timeout: not the load's)
        try:
            return load(self, sig, target_context)
        except Exception as e:
            locator = getattr(getattr(self, "_impl", None), "locator", None)
            if not isinstance(locator, _PackageStamp) or getattr(self, "_cache_file", None) is None:
                raise
            if raised_by_handler(e, handled) or (_half_imported(e) and _bytes_whole(self._cache_file)):
                raise  # (not the files': an interrupt, a timeout's raise; a half-imported numba)
            if isinstance(e, MemoryError) and _bytes_whole(self._cache_file):
                raise  # (the process's memory, not the files': under ``ulimit -v`` a load can fail so)
            _drop_damaged(self, sig, target_context, e)
            return None

    load_overload._tlm_damage = True  # type: ignore[attr-defined]
    return load_overload


def _half_imported(error: Exception) -> bool:
    """Whether ``error`` is what a package left half imported raises, not a file's damage: a submodule
    imported (in ``sys.modules``) that its package lacks (``module 'numba' has no attribute 'core'``),
    or a module still being imported (``partially initialized module``)."""
    import re
    import sys

    if isinstance(error, ImportError):
        return "partially initialized module" in str(error)
    if not isinstance(error, AttributeError):
        return False
    obj, name = getattr(error, "obj", None), getattr(error, "name", None)
    if not (inspect.ismodule(obj) and isinstance(name, str)):  # (said by its message only: before Python 3.10)
        found = re.search(r"module '([\w.]+)' has no attribute '(\w+)'", str(error))
        if not found:
            return False
        obj, name = sys.modules.get(found.group(1)), found.group(2)
    return obj is not None and not hasattr(obj, name) and f"{obj.__name__}.{name}" in sys.modules


class _Stub:
    """Whatever a pickle names (a class, a function): it takes any arguments and state."""

    def __init__(self, *args, **kwargs):
        pass

    def __setstate__(self, state):
        pass

    def __setitem__(self, key, value):
        pass

    def append(self, item):
        pass

    def extend(self, items):
        pass

    def add(self, item):
        pass


class _BytesOnly(pickle.Unpickler):
    """An unpickler that imports nothing: a pickle's bytes read, its objects stubs (:class:`_Stub`)."""

    def find_class(self, module, name):
        return _Stub

    def persistent_load(self, pid):
        return _Stub()


def _bytes_whole(cache_file) -> bool:
    """Whether numba's ``IndexDataCacheFile``'s index (a version, then a ``(stamp, overloads)`` pair)
    and the data files it names (a tuple each) read whole, by the pickle format alone, importing nothing
    (the same, whatever state numba is in): false where one is cut off, zeroed or overwritten."""
    try:
        with open(cache_file._index_path, "rb") as f:
            _BytesOnly(f).load()  # (the version numba wrote; then its pair, a pickle of its own, as numba reads it)
            pair = _BytesOnly(io.BytesIO(f.read())).load()
        if not (isinstance(pair, tuple) and len(pair) == 2 and isinstance(pair[1], dict)):
            return False
        for name in pair[1].values():
            if not isinstance(name, str):
                return False
            with open(os.path.join(os.path.dirname(cache_file._index_path), name), "rb") as f:
                if not isinstance(_BytesOnly(f).load(), tuple):
                    return False
    except FileNotFoundError:  # (removed meanwhile, by another process: nothing damaged here)
        return True
    except MemoryError:  # (too little memory to read them: nothing known of the files, so nothing damaged)
        raise
    except Exception:
        return False
    return True


def _save_safe(save):
    """numba's ``Cache.save_overload``, where tlm's compiled code cannot be written to its cache (a
    damaged index left in place, a full disk): a warning, once a process; the compiled code runs."""

    @functools.wraps(save)
    def save_overload(self, sig, data):
        try:
            return save(self, sig, data)
        except Exception as e:
            if not isinstance(getattr(getattr(self, "_impl", None), "locator", None), _PackageStamp):
                raise
            line = (f"numba could not cache the compiled code of {_function_name(self)} in {self._cache_path} "
                    f"({type(e).__name__}: {str(e)[:100]}): it is compiled again in the next process")
            if "save" not in _DAMAGED:
                _DAMAGED.add("save")
                from tlm.storage import warn

                warn(line)

    save_overload._tlm_damage = True  # type: ignore[attr-defined]
    return save_overload


def _function_name(cache) -> str:
    """``tlm.kernels._jit_bsp.level_sums``: the function of numba's ``cache``, for a warning."""
    func = getattr(cache, "_py_func", None)
    return f"{func.__module__}.{func.__qualname__}" if func is not None else str(getattr(cache, "_name", "?"))


_DAMAGED: set[str] = set()  # the cache files said damaged in this process (each said once)


def _drop_damaged(cache, sig, target_context, error: Exception) -> None:
    """Say which file of numba's ``cache`` (its ``IndexDataCacheFile``: an index ``.nbi`` and
    its ``.nbc`` data files) could not be loaded for ``sig``, once a process, and remove
    the index and its data files (numba writes them again after the compile)."""
    from tlm.storage import warn

    cache_file = cache._cache_file
    index = Path(cache_file._index_path)
    base = index.name[: -len(".nbi")]
    bad = index
    try:
        name = cache_file._load_index().get(cache._index_key(sig, target_context.codegen()))
    except Exception:  # (the index is the damaged one)
        name = None
    if name:  # (the index loads: the data file it names for ``sig`` is the damaged one)
        bad = index.parent / name
    left = []
    for f in (index, *index.parent.glob(f"{glob.escape(base)}.*.nbc")):
        try:
            f.unlink()
        except FileNotFoundError:
            pass
        except OSError as e:
            left.append(f"{f.name}: {e.strerror or e}")
    if str(bad) in _DAMAGED:
        return
    _DAMAGED.add(str(bad))
    what = ("removed, with the rest of that function's cached files" if not left
            else f"could not be removed ({'; '.join(left)}): remove it by hand")
    warn(f"{bad}: numba's cached compiled code of {_function_name(cache)} is damaged and cannot be loaded "
         f"({type(error).__name__}: {str(error)[:100]}): {what}; compiled again")


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
