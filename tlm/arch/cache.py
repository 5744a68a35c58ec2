"""The programmable PMs' data cache (thesis §IV.A.2): page misses from address streams.

"Eight blocks of data cache memory are available to each of the Vertex, Traversal and
Fragment Processing Modules at any time. They work in pairs: cache block 0 ∪ 1, 2 ∪ 3
... 6 ∪ 7. Each pair contains a current memory page and a pre-fetched memory page ...
All cache blocks are 1024 × 128-bits in size." The next block is prefetched "if the
index of the current operation M_i and index of first address of current page M'_i
are such that M_i > M'_i + BlockSize/2", while the current page is still in use.

Reading (documented in ``docs/architecture.md``): a *page* is a block-aligned run of
``PAGE_WORDS`` = 1024 main-memory words of 128 bits. Each of the four pairs serves one
data stream of the PM's program (for the Traversal PM: its rays, the node heap, ...),
so a pair sees that stream's addresses in program order. An access to the pair's
current page hits; an access to the next page hits too when the prefetch was issued —
that is, when an access to the current page reached past its middle; any other page
is a miss, which costs ``T_ms`` = 12 cycles (eq. 5.1) and makes that page current.

Everything is vectorized over the stream: consecutive accesses to one page form a run,
and a run is a miss unless it continues its predecessor onto the prefetched next page.
The state at the end of a stream (its last page and whether the prefetch is armed) can
be carried into the next stream of the same pair, so a frame split into packets gives
exactly the misses of the whole frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PAGE_WORDS = 1024  # a cache block: 1024 x 128-bit words
WORD_BYTES = 16  # 128 bits
PAIRS = 4  # cache block pairs of a programmable PM
MISS_CYCLES = 12  # T_ms per page miss: DDR row and column access


@dataclass(frozen=True)
class PairState:
    """A pair's state between streams: its current page and whether the prefetch of the
    next page was issued (-1: nothing cached)."""

    page: int = -1
    armed: bool = False


def page_misses(
    addresses: np.ndarray, state: PairState | None = None, page_words: int = PAGE_WORDS
) -> tuple[np.ndarray, PairState]:
    """Which accesses of one pair's stream miss.

    addresses : (n,) int64 word addresses in program order.
    state : the pair's state before the stream (default: empty, the first access misses).

    Returns ``miss`` (n,) bool (True on the accesses that start a missing run) and the
    state after the stream.
    """
    a = np.asarray(addresses, dtype=np.int64)
    state = state or PairState()
    n = a.shape[0]
    if n == 0:
        return np.zeros(0, dtype=bool), state
    if page_words <= 0:
        raise ValueError(f"page_words (={page_words}) must be > 0")
    page = a // page_words
    offset = a - page * page_words
    start = np.flatnonzero(np.concatenate([[True], page[1:] != page[:-1]]))
    run_page = page[start]
    # the prefetch is armed once any access of a run reached past the page's middle
    run_armed = np.maximum.reduceat(offset > page_words // 2, start)
    prev_page = np.concatenate([[state.page], run_page[:-1]])
    prev_armed = np.concatenate([[state.armed], run_armed[:-1]])
    continues = (run_page == prev_page) | ((run_page == prev_page + 1) & prev_armed & (prev_page >= 0))
    miss = np.zeros(n, dtype=bool)
    miss[start[~continues]] = True
    return miss, PairState(int(run_page[-1]), bool(run_armed[-1]))


def misses_per_packet(
    addresses: np.ndarray, packet: np.ndarray, n_packets: int, state: PairState | None = None,
    page_words: int = PAGE_WORDS,
) -> tuple[np.ndarray, PairState]:
    """Page misses of one pair's stream, attributed to the packet each access belongs to.

    addresses, packet : (n,) int64, in program order (packets in the order they run).
    Returns misses (n_packets,) int64 and the state after the stream.
    """
    miss, end = page_misses(addresses, state, page_words)
    counts = np.bincount(np.asarray(packet, dtype=np.int64)[miss], minlength=n_packets)
    return counts.astype(np.int64), end


def span_addresses(first: np.ndarray, last: np.ndarray, words_per_item: int = 1) -> np.ndarray:
    """The word addresses of the item ranges ``[first, last)`` read one after another.

    Items of ``words_per_item`` words each (a triangle with its vertex headers: 3
    words; a BSP node: 1 word). Returns the (sum of lengths * words_per_item,) stream.
    """
    first = np.asarray(first, dtype=np.int64) * words_per_item
    last = np.asarray(last, dtype=np.int64) * words_per_item
    length = np.maximum(last - first, 0)
    total = int(length.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    starts = np.repeat(first - (np.cumsum(length) - length), length)
    return starts + np.arange(total, dtype=np.int64)
