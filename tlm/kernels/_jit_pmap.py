"""The photon-map glue compiled with numba (``nogil``): what ran as small numpy steps, holding
the interpreter lock, between the compiled gathers of :mod:`tlm.kernels.estimate` and
:mod:`tlm.render.pmap`. Integers only, or the same floating-point formula in the same
order, so every result is bit-identical to the numpy code it replaces (tests/test_gather_glue.py).

* :func:`pair_words`: a gather chunk's per-query leaf and photon counts and the word range
  of each (query, leaf) pair's photon reads (:func:`tlm.kernels.estimate.charge_leaves`).
* :func:`add_per_owner`: ``into += bincount(owner, weights=values)`` for integer counts.
"""

from __future__ import annotations

import numpy as np

from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)


@njit(cache=True, error_model="numpy", nogil=True)
def pair_words(pq, leaf, first, size, m, words):
    """(query, leaf) pairs ``pq`` (in ``[0, m)``), ``leaf`` of a gather: each query's leaves
    (``bincount(pq, minlength=m)``) and photons tested (``bincount(pq, weights=size[leaf])``),
    and the pairs' word ranges ``first[leaf] * words`` .. that ``+ size[leaf] * words``."""
    p = pq.shape[0]
    leaves = np.zeros(m, dtype=np.int64)
    tested = np.zeros(m, dtype=np.int64)
    lo = np.empty(p, dtype=np.int64)
    hi = np.empty(p, dtype=np.int64)
    for i in range(p):
        f = leaf[i]
        q = pq[i]
        leaves[q] += 1
        tested[q] += size[f]
        lo[i] = first[f] * words
        hi[i] = lo[i] + size[f] * words
    return leaves, tested, lo, hi


@njit(cache=True, error_model="numpy", nogil=True)
def add_per_owner(into, owner, values):
    """``into[owner[i]] += values[i]`` in order (int64: ``bincount(owner, weights=values)``
    added, exact while the sums stay below 2**53). An owner outside ``into`` is an
    IndexError, as numpy's bincount-and-add refuses one (nothing is written past the end)."""
    n = into.shape[0]
    for i in range(owner.shape[0]):
        if owner[i] < 0 or owner[i] >= n:
            raise IndexError("add_per_owner: an owner outside the counts")
    for i in range(owner.shape[0]):
        into[owner[i]] += values[i]
