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
be carried into the next stream of the same pair (a prefetch issued before stays issued
while the stream goes on with the same page), so a frame split into packets gives
exactly the misses of the whole frame.

What the kernels read (the memory layout, one 128-bit word per address):

* the node heap, ``NODE_WORDS`` = 1 word per node at its heap index;
* a leaf's triangle indices, 32 bits each, ``INDICES_PER_WORD`` = 4 to a word: leaf
  slots ``[first, last)`` are words ``first // 4 .. (last - 1) // 4``;
* the triangle vertex data, ``VERTEX_WORDS`` = 3 words per slot (three 96-bit vertices
  with their 32-bit headers): slot ``s`` is words ``3 s .. 3 s + 2``;
* a triangle's shading record, ``SHADING_WORDS`` = 1 word at the triangle id;
* a photon in leaf order, ``PHOTON_WORDS`` = 2 words per slot.

Each stream lives in its own address space (word 0 is its first word). A leaf's words
are a contiguous range, so streams are built from ranges without listing every word
(:func:`page_spans`: per page a range touches, its first and last word), and
*compacted* (:class:`Accesses`): consecutive accesses of one owner (a ray, a pixel, a
photon, a query) to one page become one access at their largest offset. A run's page
and whether it armed the prefetch are all :func:`page_misses` reads, so a compacted
stream has exactly the misses of the full one, and streams compacted per owner can be
put in another owner order (pixel-major, photon-major) before they are charged.
:class:`Streams` carries the named pairs' states from packet to packet.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PAGE_WORDS = 1024  # a cache block: 1024 x 128-bit words
WORD_BYTES = 16  # 128 bits
PAIRS = 4  # cache block pairs of a programmable PM
MISS_CYCLES = 12  # T_ms per page miss: DDR row and column access

NODE_WORDS = 1  # a BSP node (first index, last index, split: 96 bits)
INDICES_PER_WORD = 4  # 32-bit triangle indices of a leaf
VERTEX_WORDS = 3  # a triangle slot: three 96-bit vertices with 32-bit headers
SHADING_WORDS = 1  # a triangle's shading record (material and normal)
PHOTON_WORDS = 2  # a stored photon (position, power, incoming direction)


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
    if run_page[0] == state.page:  # the stream goes on with the current page: a prefetch
        run_armed[0] |= state.armed  # issued before it stays issued
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


def _pages(words: np.ndarray, page_words: int) -> np.ndarray:
    """Page of each word (a shift for the usual power-of-two page)."""
    if page_words & (page_words - 1) == 0:
        return words >> (page_words.bit_length() - 1)
    return words // page_words


def _spans(first, last, owner, page_words: int):
    """Per (range, page) span of the non-empty ranges: its first and last word, its owner."""
    if page_words <= 0:
        raise ValueError(f"page_words (={page_words}) must be > 0")
    first = np.asarray(first, dtype=np.int64).reshape(-1)
    last = np.asarray(last, dtype=np.int64).reshape(-1)
    if first.shape != last.shape:
        raise ValueError(f"first ({first.shape[0]}) and last ({last.shape[0]}) differ in length")
    if owner is None:
        owner = np.arange(first.shape[0], dtype=np.int64)
    else:
        owner = np.broadcast_to(np.asarray(owner, dtype=np.int64), first.shape)
    keep = last > first
    if not keep.all():
        first, last, owner = first[keep], last[keep], owner[keep]
    hi = last - 1
    p0 = _pages(first, page_words)
    pages = _pages(hi, page_words) - p0 + 1
    if pages.shape[0] == 0 or int(pages.max()) == 1:
        return first, hi, owner
    rep = np.repeat(np.arange(pages.shape[0]), pages)
    page = p0[rep] + (np.arange(rep.shape[0]) - np.repeat(np.cumsum(pages) - pages, pages))
    base = page * page_words
    return np.maximum(first[rep], base), np.minimum(hi[rep], base + (page_words - 1)), owner[rep]


def page_spans(
    first: np.ndarray, last: np.ndarray, owner: np.ndarray | None = None, page_words: int = PAGE_WORDS
) -> tuple[np.ndarray, np.ndarray]:
    """Word ranges ``[first, last)`` read one after another, as per-page spans.

    first, last : (m,) int64 word addresses; an empty range (``last <= first``) reads
    nothing. owner : (m,) int64 owner of each range (a ray, a query; default: its index).

    Returns ``words`` and ``owner``, each (2 s,) int64 for the ``s`` (range, page) spans
    in reading order: a span's first word in the page, then its last. :func:`page_misses`
    gives this stream exactly the misses of the full stream (:func:`span_addresses` of
    the same ranges), on accesses of the same owners: its runs are the same pages in the
    same order, each reaching the same largest offset (the words of a range ascend).
    """
    lo, hi, owner = _spans(first, last, owner, page_words)
    words = np.empty(2 * lo.shape[0], dtype=np.int64)
    words[0::2] = lo
    words[1::2] = hi
    return words, np.repeat(owner, 2)


def range_misses(
    first: np.ndarray, last: np.ndarray, owner: np.ndarray, n_owners: int, state: PairState | None = None,
    page_words: int = PAGE_WORDS,
) -> tuple[np.ndarray, PairState]:
    """Page misses of one pair reading the word ranges ``[first, last)`` in order, per owner.

    owner : (m,) int64 in ``[0, n_owners)``, the owner each range's misses go to.
    Returns misses (n_owners,) int64 and the state after the stream: the same as
    :func:`misses_per_packet` of the full word stream, without listing every word.
    """
    words, own = page_spans(first, last, owner, page_words)
    return misses_per_packet(words, own, n_owners, state, page_words)


def _run_starts(words: np.ndarray, page_words: int, owner: np.ndarray | None = None,
                bounds: np.ndarray | None = None) -> np.ndarray:
    """Indices where a (page, owner) run starts: the page changes, or the owner (given
    per access by ``owner``, or by the indices ``bounds`` where a new owner begins)."""
    n = words.shape[0]
    page = _pages(words, page_words)
    new = np.empty(n, dtype=bool)
    new[0] = True
    np.not_equal(page[1:], page[:-1], out=new[1:])
    if owner is not None:
        new[1:] |= owner[1:] != owner[:-1]
    if bounds is not None:
        new[bounds] = True
    return np.flatnonzero(new)


def compact(words: np.ndarray, owner: np.ndarray, page_words: int = PAGE_WORDS) -> tuple[np.ndarray, np.ndarray]:
    """Merge consecutive accesses of one owner to one page into one, at their largest word.

    A run of :func:`page_misses` is the same page and arms the prefetch when any access
    reached past the middle, so the merged stream has the same misses on the same owners
    — also after its owners' accesses are put in another order, as long as each owner's
    own accesses keep theirs (:meth:`Accesses.owner_major`).
    """
    words = np.asarray(words, dtype=np.int64).reshape(-1)
    owner = np.asarray(owner, dtype=np.int64).reshape(-1)
    if words.shape[0] < 2:
        return words, owner
    start = _run_starts(words, page_words, owner)
    if start.shape[0] == words.shape[0]:
        return words, owner
    return np.maximum.reduceat(words, start), owner[start]


@dataclass(frozen=True)
class Accesses:
    """One stream's accesses in program order, compacted (:func:`compact`).

    words : (a,) int64 word addresses; owner : (a,) int64, the ray, pixel, photon or query
    each access belongs to; page_words : the page size they were compacted for.
    """

    words: np.ndarray
    owner: np.ndarray
    page_words: int = PAGE_WORDS

    @classmethod
    def of_words(cls, words, owner, page_words: int = PAGE_WORDS) -> Accesses:
        """One access per word, in order."""
        return cls(*compact(words, owner, page_words), page_words)

    @classmethod
    def of_ranges(cls, first, last, owner, page_words: int = PAGE_WORDS) -> Accesses:
        """The words ``[first, last)`` of each range, ranges in order (:func:`page_spans`)."""
        _, hi, owner = _spans(first, last, owner, page_words)  # a span's last word is its largest
        return cls(*compact(hi, owner, page_words), page_words)

    @classmethod
    def of_csr(cls, words, ptr, page_words: int = PAGE_WORDS) -> Accesses:
        """One access per word, owner ``i``'s words ``words[ptr[i]:ptr[i+1]]``."""
        words = np.asarray(words)  # any integer type: only the compacted words are widened
        ptr = np.asarray(ptr, dtype=np.int64)
        if words.shape[0] == 0:
            return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), page_words)
        first = ptr[:-1][ptr[1:] > ptr[:-1]]
        start = _run_starts(words, page_words, bounds=first)
        owner = np.searchsorted(ptr, start, side="right") - 1
        return cls(np.maximum.reduceat(words, start).astype(np.int64), owner, page_words)

    @classmethod
    def concat(cls, parts: list[Accesses], page_words: int = PAGE_WORDS) -> Accesses:
        """The parts one after another."""
        if any(p.page_words != page_words for p in parts):
            raise ValueError(f"accesses compacted for another page size than {page_words}")
        if not parts:
            return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), page_words)
        if len(parts) == 1:
            return parts[0]
        return cls(np.concatenate([p.words for p in parts]), np.concatenate([p.owner for p in parts]), page_words)

    def relabel(self, owners: np.ndarray) -> Accesses:
        """Owner ``i`` renamed ``owners[i]``."""
        return Accesses(self.words, np.asarray(owners, dtype=np.int64)[self.owner], self.page_words)

    def owner_major(self) -> Accesses:
        """All accesses of owner 0, then of owner 1, ..., each owner's in their order."""
        own = self.owner
        if own.shape[0] < 2 or bool(np.all(own[1:] >= own[:-1])):
            return self
        order = np.argsort(own, kind="stable")
        return Accesses(*compact(self.words[order], own[order], self.page_words), self.page_words)


class Streams:
    """The cache pairs' states of named streams, carried from packet to packet (mutable).

    A pass takes one (default: a fresh one, every pair empty), charges each of its
    streams' accesses to the pair of that name and leaves the state after its packet in
    it. Packets of a frame run in order with one object give exactly the whole frame's
    misses, per owner.
    """

    def __init__(self, page_words: int = PAGE_WORDS):
        if isinstance(page_words, bool) or int(page_words) != page_words or page_words <= 0:
            raise ValueError(f"page_words (={page_words!r}) must be a whole number > 0")
        self.page_words = int(page_words)
        self.states: dict[str, PairState] = {}

    def charge(self, name: str, accesses: Accesses, n_owners: int) -> np.ndarray:
        """Misses (n_owners,) int64 per owner of stream ``name``'s accesses, which run next."""
        if accesses.page_words != self.page_words:
            raise ValueError(f"accesses compacted for {accesses.page_words}-word pages, the pairs have "
                             f"{self.page_words}")
        counts, self.states[name] = misses_per_packet(
            accesses.words, accesses.owner, n_owners, self.states.get(name), self.page_words
        )
        return counts

    def __repr__(self) -> str:
        return f"Streams(page_words={self.page_words}, states={self.states!r})"


class Recorder:
    """Accesses of named streams, gathered in any order of owners, charged owner-major.

    A kernel that runs its work in another order than the program charges (the bounces
    of a specular walk, all photons of a bounce at once) adds each step's accesses with
    the program's owner (pixel, photon) of every access; :meth:`collect` puts them in
    owner order, each owner's accesses in the order they were added.
    """

    def __init__(self, page_words: int = PAGE_WORDS):
        self.page_words = page_words
        self.parts: dict[str, list[Accesses]] = {}

    def add(self, name: str, accesses: Accesses, owners: np.ndarray | None = None) -> None:
        """Append ``accesses`` to stream ``name``, owner ``i`` renamed ``owners[i]``."""
        if owners is not None:
            accesses = accesses.relabel(owners)
        self.parts.setdefault(name, []).append(accesses)

    def collect(self) -> dict[str, Accesses]:
        """Every stream's accesses, owner-major."""
        return {name: Accesses.concat(parts, self.page_words).owner_major() for name, parts in self.parts.items()}

    def charge(self, streams: Streams, n_owners: int) -> dict[str, np.ndarray]:
        """Misses per owner of every stream, charged to ``streams`` owner-major."""
        return {name: streams.charge(name, acc, n_owners) for name, acc in self.collect().items()}


def traversal_accesses(touched, leaf_first: np.ndarray, leaf_last: np.ndarray,
                       page_words: int = PAGE_WORDS) -> dict[str, Accesses]:
    """The reads of a packet's ray traversal, owner = the ray's index in the packet.

    touched : a :class:`~tlm.kernels.traverse.Touched` (CSR node and leaf lists per ray).
    leaf_first, leaf_last : each leaf's triangle slot range.

    Returns ``nodes`` (the Traversal PM's node heap: each inner node entered, one word at
    its heap index), ``indices`` (the Traversal PM's leaf triangle indices: the slots of
    every tested leaf, four to a word) and ``vertices`` (the Intersection PM's triangle
    data: three words per slot), each in visiting order. Empty leaves read nothing.
    """
    r = touched.leaf_ptr.shape[0] - 1
    ids = touched.node_ids
    nodes = Accesses.of_csr(ids if NODE_WORDS == 1 else ids.astype(np.int64) * NODE_WORDS, touched.node_ptr,
                            page_words)
    leaves = touched.leaf_ids
    lf = leaf_first[leaves].astype(np.int64, copy=False)
    ll = leaf_last[leaves].astype(np.int64, copy=False)
    owner = np.repeat(np.arange(r, dtype=np.int64), np.diff(touched.leaf_ptr))
    full = ll > lf
    if not full.all():
        lf, ll, owner = lf[full], ll[full], owner[full]
    return {
        "nodes": nodes,
        "indices": Accesses.of_ranges(lf // INDICES_PER_WORD, (ll - 1) // INDICES_PER_WORD + 1, owner, page_words),
        "vertices": Accesses.of_ranges(lf * VERTEX_WORDS, ll * VERTEX_WORDS, owner, page_words),
    }
