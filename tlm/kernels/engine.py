"""Which implementation of the compiled kernels runs: ``TLM_KERNELS``.

``numba`` (the default when numba imports) runs the traversal and the BSP builder's
per-element passes compiled (:mod:`tlm.kernels._jit`, :mod:`tlm.kernels._jit_bsp`);
``numpy`` runs the vectorized numpy reference. Both give bit-identical results
(``tests/test_engines.py`` compares them). Unset or empty is the default; any other
value is refused as bad input.
"""

from __future__ import annotations

import functools
import os

from tlm.errors import InputError

ENGINES = ("numba", "numpy")


def engine() -> str:
    """``numba`` or ``numpy``, from ``TLM_KERNELS`` (default: numba if it imports); any
    other value is an :class:`~tlm.errors.InputError` naming the variable (exit status 2)."""
    raw = os.environ.get("TLM_KERNELS", "")
    name = raw.strip().lower()
    if name and name not in ENGINES:
        raise InputError(f"{raw!r} is not an engine: expected {' or '.join(ENGINES)} (unset or empty: numba "
                         "where it imports, else numpy)", source="environment", key="TLM_KERNELS")
    if name == "numpy" or not numba_available():
        return "numpy"
    return "numba"


@functools.cache
def numba_available() -> bool:
    """Whether numba imports: False where it is not installed (the kernels run on numpy, said by
    nothing: numba is optional), and where it is but cannot load (an ``OSError``: llvmlite's shared
    library missing or of another machine), which one warning names, with its cause (once: :data:`SAID_BY`);
    one that could not be mapped under a limit on the address space (its library, an OSError, or an extension
    module, an ImportError) is out of memory (:func:`tlm.errors.memory_problem`)."""
    try:
        import numba  # noqa: F401
    except (ImportError, OSError) as e:
        from tlm.errors import memory_problem

        if memory_problem(e) is not None:  # (a library not mapped under ulimit -v: out of memory, as ever; an
            raise  # extension module's is an ImportError: not "not installed", nor cached as numpy's kernels)
        if isinstance(e, ImportError):
            return False
        line = (f"numba is installed but cannot load ({type(e).__name__}: {e}): the kernels run on numpy (the same "
                "results, slower; TLM_KERNELS=numpy says so without numba)")
        said = os.environ.get(SAID_BY, "").partition(" ")
        if said[0] != str(os.getpid()) and said[2] == line:  # (a sweep's or Dask's worker: its sweep said it)
            return False
        from tlm.storage import warn

        warn(line)  # (numba installed, its compiler's library not loadable: numpy's kernels, said once)
        os.environ[SAID_BY] = f"{os.getpid()} {line}"
        return False
    return True


# where numba could not load: "PID LINE", the process that said so and its warning, in the environment of the
# processes it starts (a sweep's workers, as its TLM_* variables; a local Dask cluster's): one that fails
# alike says nothing again (it said it once per worker, each on the sweep's stderr); one whose numba loads
# runs it, and the process that said it says it again after ``numba_available.cache_clear()``
SAID_BY = "TLM_NUMBA_UNLOADABLE_SAID"
