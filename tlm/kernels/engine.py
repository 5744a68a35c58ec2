"""Which implementation of the compiled kernels runs: ``TLM_KERNELS``.

``numba`` (the default when numba imports) runs the traversal and the BSP builder's
per-element passes compiled (:mod:`tlm.kernels._jit`, :mod:`tlm.kernels._jit_bsp`);
``numpy`` runs the vectorized numpy reference. Both give bit-identical results
(``tests/test_engines.py`` compares them).
"""

from __future__ import annotations

import functools
import os

ENGINES = ("numba", "numpy")


def engine() -> str:
    """``numba`` or ``numpy``, from ``TLM_KERNELS`` (default: numba if it imports)."""
    name = os.environ.get("TLM_KERNELS", "").strip().lower()
    if name and name not in ENGINES:
        raise ValueError(f"TLM_KERNELS={name!r}: expected one of {', '.join(ENGINES)}")
    if name == "numpy" or not numba_available():
        return "numpy"
    return "numba"


@functools.cache
def numba_available() -> bool:
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True
