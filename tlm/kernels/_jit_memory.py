"""Address streams compiled with numba: their compaction (:class:`tlm.kernels.memory.Accesses`) and misses.

Each function returns what its numpy counterpart in :mod:`tlm.kernels.memory` returns,
element for element (int64 words and owners): a *run* is consecutive accesses of one
owner to one page, and becomes one access at its largest word, owned by the run's owner.

* :func:`compact`: :func:`tlm.kernels.memory.compact` (runs of a word stream);
* :func:`csr_runs`: ``Accesses.of_csr`` (owner ``i``'s words ``words[ptr[i]:ptr[i+1]]``);
* :func:`range_runs`: ``Accesses.of_ranges`` (each range ``[first, last)`` cut at page
  boundaries, a span's last word its largest, then compacted);
* :func:`page_misses`: :func:`tlm.kernels.memory.page_misses` (which accesses of a pair's
  stream miss, and the pair's state after it).

The runs' bookkeeping (a new run, or the last run's largest word) is written out in each
loop: a shared helper function, inlined or not, made them 2.5x - 3.5x slower (measured
2026-11-28 on 1M ranges). Integer arithmetic only, so nothing can differ but the speed: one pass instead of
numpy's temporaries, and ``nogil``, so the threads of a render (:mod:`tlm.kernels.threads`)
run it at once. ``TLM_KERNELS=numpy`` runs the numpy code, the reference
(tests/test_engines.py compares the two).
"""

from __future__ import annotations

import numpy as np

from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)


@njit(cache=True, nogil=True, inline="always")
def _page(w, page_words, shift):
    """The page of word ``w``: a shift for a power-of-two page (``shift`` >= 0)."""
    if shift >= 0:
        return w >> shift
    return w // page_words


def shift_of(page_words: int) -> int:
    """log2 of a power-of-two page, else -1 (the functions below then divide)."""
    page_words = int(page_words)
    return page_words.bit_length() - 1 if page_words > 0 and page_words & (page_words - 1) == 0 else -1


@njit(cache=True, nogil=True)
def compact(words, owner, page_words, shift):
    n = words.shape[0]
    out_w = np.empty(n, dtype=np.int64)
    out_o = np.empty(n, dtype=np.int64)
    k = -1
    page = np.int64(0)
    for j in range(n):
        w = np.int64(words[j])
        p = _page(w, page_words, shift)
        o = np.int64(owner[j])
        if k < 0 or p != page or o != out_o[k]:
            k += 1
            out_w[k] = w
            out_o[k] = o
            page = p
        elif w > out_w[k]:
            out_w[k] = w
    return out_w[: k + 1].copy(), out_o[: k + 1].copy()


@njit(cache=True, nogil=True)
def csr_runs(words, ptr, page_words, shift):
    n = words.shape[0]
    out_w = np.empty(n, dtype=np.int64)
    out_o = np.empty(n, dtype=np.int64)
    k = -1
    for i in range(ptr.shape[0] - 1):
        page = np.int64(0)
        for j in range(ptr[i], ptr[i + 1]):
            w = np.int64(words[j])
            p = _page(w, page_words, shift)
            if j == ptr[i] or p != page:
                k += 1
                out_w[k] = w
                out_o[k] = i
                page = p
            elif w > out_w[k]:
                out_w[k] = w
    return out_w[: k + 1].copy(), out_o[: k + 1].copy()


@njit(cache=True, nogil=True)
def range_runs(first, last, owner, page_words, shift):
    m = first.shape[0]
    total = 0
    for i in range(m):
        if last[i] > first[i]:
            total += _page(last[i] - 1, page_words, shift) - _page(first[i], page_words, shift) + 1
    out_w = np.empty(total, dtype=np.int64)
    out_o = np.empty(total, dtype=np.int64)
    k = -1
    page = np.int64(0)
    for i in range(m):
        f = np.int64(first[i])
        if last[i] <= f:
            continue
        hi = np.int64(last[i]) - 1
        o = np.int64(owner[i])
        for p in range(_page(f, page_words, shift), _page(hi, page_words, shift) + 1):
            w = min(hi, p * page_words + (page_words - 1))
            if k < 0 or p != page or o != out_o[k]:
                k += 1
                out_w[k] = w
                out_o[k] = o
                page = p
            elif w > out_w[k]:
                out_w[k] = w
    return out_w[: k + 1].copy(), out_o[: k + 1].copy()


@njit(cache=True, nogil=True)
def page_misses(words, state_page, state_armed, page_words, shift):
    """:func:`tlm.kernels.memory.page_misses`: the miss of each access and the state after."""
    n = words.shape[0]
    miss = np.zeros(n, dtype=np.bool_)
    half = page_words // 2
    prev_page, prev_armed = np.int64(state_page), state_armed
    page, armed = np.int64(state_page), state_armed
    for i in range(n):
        w = words[i]
        p = _page(w, page_words, shift)
        if i == 0 or p != page:
            if i > 0:
                prev_page, prev_armed = page, armed
            armed = i == 0 and p == state_page and state_armed  # a prefetch issued before stays issued
            page = p
            miss[i] = not (p == prev_page or (p == prev_page + 1 and prev_armed and prev_page >= 0))
        if w - p * page_words > half:
            armed = True
    return miss, page, armed
