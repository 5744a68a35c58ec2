"""The integer glue around the compiled traversal, compiled with numba (nogil): what
:func:`tlm.kernels.traverse._traverse_jit` forms from a packet's answers (the CSR pointers
of the recorded nodes and leaves) and what :func:`tlm.kernels.recording.traversal_accesses`
forms from them (the compacted node, leaf-index and vertex streams), each in one call
instead of a dozen numpy calls that hold the interpreter lock between them.

Integer arithmetic only: each returns, element for element, what the numpy (and
:mod:`tlm.kernels._jit_memory`) code it replaces returns (``tests/test_traverse_glue.py``
compares them). The streams are compacted by :mod:`tlm.kernels._jit_memory`'s ``csr_runs``
(the nodes) and ``range_runs`` (the leaves' index and vertex words).
"""

from __future__ import annotations

import numpy as np

from tlm.kernels._jit_memory import compact, csr_runs, range_runs
from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)


@njit(cache=True, nogil=True)
def touched_ptrs(node_visits, leaf_visits):
    """``node_ptr`` and ``leaf_ptr`` (r + 1,) int64: 0, then the running sums of the
    per-ray ``node_visits`` and ``leaf_visits`` (r,) (numpy's ``cumsum`` into ``ptr[1:]``)."""
    r = node_visits.shape[0]
    node_ptr = np.empty(r + 1, dtype=np.int64)
    leaf_ptr = np.empty(r + 1, dtype=np.int64)
    a = np.int64(0)
    b = np.int64(0)
    node_ptr[0] = 0
    leaf_ptr[0] = 0
    for i in range(r):
        a += node_visits[i]
        b += leaf_visits[i]
        node_ptr[i + 1] = a
        leaf_ptr[i + 1] = b
    return node_ptr, leaf_ptr


@njit(cache=True, nogil=True)
def _valid_ptr(ptr, n):
    """``ptr`` rises from 0 to ``n`` (what ``Accesses.of_csr`` checks)."""
    if ptr.shape[0] < 1 or ptr[0] != 0 or ptr[ptr.shape[0] - 1] != n:
        return False
    ok = True
    for i in range(ptr.shape[0] - 1):
        ok &= ptr[i + 1] >= ptr[i]
    return ok


@njit(cache=True, nogil=True)
def traversal_runs(node_ids, node_ptr, leaf_ids, leaf_ptr, leaf_first, leaf_last, indices_per_word,
                   vertex_words, page_words, shift):
    """The three compacted streams of :func:`tlm.kernels.recording.traversal_accesses` (node
    words ``NODE_WORDS`` = 1 per node).

    Returns ``ok`` (False: a pointer array does not rise from 0 to its list's length,
    nothing else is valid) and the words and owners of ``nodes`` (``Accesses.of_csr`` of
    ``node_ids``, ``node_ptr``), ``indices`` (``Accesses.of_ranges`` of the words
    ``first // indices_per_word .. (last - 1) // indices_per_word`` of every visited
    non-empty leaf, owner its ray) and ``vertices`` (``Accesses.of_ranges`` of
    ``[vertex_words * first, vertex_words * last)``), each int64.
    """
    e = np.zeros(0, dtype=np.int64)
    if not (_valid_ptr(node_ptr, node_ids.shape[0]) and _valid_ptr(leaf_ptr, leaf_ids.shape[0])):
        return False, e, e, e, e, e, e
    nodes_w, nodes_o = csr_runs(node_ids, node_ptr, page_words, shift)  # (owner i's words node_ids[ptr[i]:ptr[i+1]])
    # the leaves' ranges, each visited leaf's in its ray's order (an empty leaf: an empty range)
    m = leaf_ids.shape[0]
    i_first = np.zeros(m, dtype=np.int64)
    i_last = np.zeros(m, dtype=np.int64)
    v_first = np.zeros(m, dtype=np.int64)
    v_last = np.zeros(m, dtype=np.int64)
    owner = np.empty(m, dtype=np.int64)
    for i in range(leaf_ptr.shape[0] - 1):
        for j in range(leaf_ptr[i], leaf_ptr[i + 1]):
            owner[j] = i
            f = np.int64(leaf_first[leaf_ids[j]])
            last = np.int64(leaf_last[leaf_ids[j]])
            if last > f:
                i_first[j] = f // indices_per_word
                i_last[j] = (last - 1) // indices_per_word + 1
                v_first[j] = f * vertex_words
                v_last[j] = last * vertex_words
    iw, io = range_runs(i_first, i_last, owner, page_words, shift)
    vw, vo = range_runs(v_first, v_last, owner, page_words, shift)
    return True, nodes_w, nodes_o, iw, io, vw, vo


@njit(cache=True, nogil=True)
def owner_major(words, owner, page_words, shift):
    """``Accesses.owner_major`` of the compacted stream ``words``, ``owner`` (a,) int64:
    ``status`` 0 when the owners already rise (nothing to do), 1 with the stream put in
    owner order, each owner's accesses in their order (numpy's stable ``argsort`` of the
    owners), and compacted again (:func:`tlm.kernels._jit_memory.compact`), 2 when the
    owners are negative or spread over more than ``4 a + 1024`` values (a counting sort
    would not pay: the caller sorts)."""
    n = owner.shape[0]
    e = np.zeros(0, dtype=np.int64)
    rising = True
    lo = owner[0] if n else 0
    hi = lo
    for i in range(1, n):
        x = owner[i]
        rising &= x >= owner[i - 1]
        lo = min(lo, x)
        hi = max(hi, x)
    if rising:
        return 0, e, e
    if lo < 0 or hi > 4 * n + 1024:
        return 2, e, e
    # a stable counting sort by owner, then the runs (page, owner) of the sorted stream
    at = np.zeros(hi + 2, dtype=np.int64)
    for i in range(n):
        at[owner[i] + 1] += 1
    for v in range(hi + 1):
        at[v + 1] += at[v]
    order = np.empty(n, dtype=np.int64)
    for i in range(n):
        x = owner[i]
        order[at[x]] = i
        at[x] += 1
    out_w, out_o = compact(words[order], owner[order], page_words, shift)
    return 1, out_w, out_o
