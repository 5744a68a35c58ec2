"""The programmable PMs' data cache (thesis §IV.A.2): page misses from address streams.

"Eight blocks of data cache memory are available to each of the Vertex, Traversal and
Fragment Processing Modules at any time. They work in pairs: cache block 0 ∪ 1, 2 ∪ 3
... 6 ∪ 7. Each pair contains a current memory page and a pre-fetched memory page ...
All cache blocks are 1024 × 128-bits in size." The next block is prefetched "if the
index of the current operation M_i and index of first address of current page M'_i
are such that M_i > M'_i + BlockSize/2", while the current page is still in use.

Reading (documented in ``docs/architecture.md``): a *page* is a block-aligned run of
``block_words`` main-memory words of 128 bits (``PAGE_WORDS`` = 1024, the thesis's block,
by default). A pair serves data streams of the PM's program (for the Traversal PM: the
node heap, the leaf indices), so it sees those streams' addresses in program order. An
access to the pair's current page hits; an access to the next page hits too when the
prefetch was issued — that is, when an access to the current page reached past its
middle; any other page is a miss, which costs ``T_ms`` = 12 cycles (eq. 5.1) and makes
that page current.

Pairs per PM and the block size (the run config's ``cache`` section, ``cache.pairs`` =
``PAIRS`` = 4 and ``cache.block_words`` = ``PAGE_WORDS`` by default). Each PM has a
cache of its own, and a phase of its program (the eye and secondary rays, the shadow
rays, the photon rays, the fragments) runs on it alone, so the cached streams are
listed per PM phase (:data:`PM_STREAMS`) in a fixed order, and stream ``k`` of a phase
takes pair ``k mod pairs``:

* Traversal PM, eye and secondary rays (and, on a Streams of their own, the photon
  tracer's rays): ``nodes``, ``indices``;
* Traversal PM, shadow rays: ``shadow_nodes``, ``shadow_indices``;
* Fragment PM: ``shading``, ``photons`` (the gather's photon leaves).

So ``pairs`` = 1 puts both streams of a phase on pair 0; ``pairs`` >= 2 gives each its
own (pairs 0 and 1).

Streams that share a pair are charged as one stream: their accesses merged owner-major
(for each owner — a ray, a pixel, a photon, a query — its accesses in the order the
kernel added them: a ray's node reads, then its leaf indices; a pixel's bounces in
order; a shaded point's shadow rays' node reads, then their index reads), each stream
in an address region of its own (stream ``j`` of a pair reads pages ``j *
REGION_PAGES + p``), so two streams never share a page but do evict each other's. Each
miss of the merged stream is the miss of the stream whose access it was, so it goes
to that stream's work key; streams of one pair are always of one PM phase, so this is
the phase's key (``trav_misses``: node heap and leaf indices). The Fragment PM's two
streams are read by different passes (shading records by the ray-cast, reflect and
refract frames, photon leaves by the photon-map frame), each charged on cold pairs of
its own, so they never run in one stream; on one carried :class:`Streams` they would
share pair 0's state at ``pairs`` = 1.

The Intersection PM is fixed function and has no data cache in the thesis ("eight
blocks ... to each of the Vertex, Traversal and Fragment Processing Modules"); its
vertex reads (``vertices``, ``shadow_vertices``) are still charged here, as before, as
one stream on a page buffer of its own: ``cache.block_words`` sets its page, ``pairs``
does not touch it. A stream not listed in :data:`PM_STREAMS` has a pair of its own.

A finding: with the streams the PMs have today (at most two cached streams per phase),
``pairs`` = 1 puts the node heap and the leaf indices on one pair and changes the
Traversal PM's misses; ``pairs`` >= 2 gives every stream a pair of its own and the
misses are those of ``pairs`` = 4, the thesis's. Fewer pairs than streams is the only
thing the knob can show until a phase reads more streams (its rays, the stack, the
FIFO's triangle addresses are not modelled as memory streams); the config stops at 4,
the thesis's eight blocks, since more pairs could only show no change.

Everything is vectorized over the stream (the compaction and :func:`page_misses` also
compiled, :mod:`tlm.kernels._jit_memory`, unless ``TLM_KERNELS=numpy``; the same
results): consecutive accesses to one page form a run,
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
:class:`Streams` carries the pairs' states from packet to packet. Recording a kernel's
reads (:class:`~tlm.kernels.recording.Recorder`, :class:`~tlm.kernels.recording.Deferred`,
:func:`~tlm.kernels.recording.traversal_accesses`) is :mod:`tlm.kernels.recording`'s.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields, is_dataclass

import numpy as np

from tlm.kernels.engine import engine

PAGE_WORDS = 1024  # a cache block: 1024 x 128-bit words
WORD_BYTES = 16  # 128 bits
PAIRS = 4  # cache block pairs of a programmable PM
REGION_PAGES = 1 << 32  # pages of one stream's address region when streams share a pair
MAX_PAGE_WORDS = 1 << 24  # the largest page: a few regions of it still fit in int64 addresses
MISS_CYCLES = 12  # T_ms per page miss: DDR row and column access

NODE_WORDS = 1  # a BSP node (first index, last index, split: 96 bits)
INDICES_PER_WORD = 4  # 32-bit triangle indices of a leaf
VERTEX_WORDS = 3  # a triangle slot: three 96-bit vertices with 32-bit headers
SHADING_WORDS = 1  # a triangle's shading record (material and normal)
PHOTON_WORDS = 2  # a stored photon (position, power, incoming direction)

# The run config's ``cache`` keys (tlm.config_sections.CacheConfig) -> the Streams setting each sets: the one
# place the section becomes the cache model (:meth:`Streams.of`; a key not here is refused, not dropped)
CACHE_KEYS = {"block_words": "page_words", "pairs": "pairs"}

# The cached streams of each programmable PM phase, in the order they take the pairs
# (stream k: pair k mod pairs). The photon tracer's rays are the Traversal PM's
# "nodes" and "indices" of a phase of their own (a Streams of their own).
PM_STREAMS = {
    "traversal": ("nodes", "indices"),
    "shadow_traversal": ("shadow_nodes", "shadow_indices"),
    "fragment": ("shading", "photons"),
}
_PAIR_OF = {name: (phase, k) for phase, names in PM_STREAMS.items() for k, name in enumerate(names)}


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

    The rule is said three times, alike: here (numpy), in :func:`tlm.kernels._jit_memory.page_misses`
    (numba, the default engine) and in :mod:`tlm.kernels.recording` (``_Head.settle`` and the arming in
    ``Deferred._charged``): docs/architecture.md, "Changing the cache model".
    """
    a = np.asarray(addresses, dtype=np.int64)
    state = state or PairState()
    n = a.shape[0]
    if n == 0:
        return np.zeros(0, dtype=bool), state
    if page_words <= 0:
        raise ValueError(f"page_words (={page_words}) must be > 0")
    jit = _jit()
    if jit is not None:
        miss, last, armed = jit.page_misses(np.ascontiguousarray(a), np.int64(state.page), bool(state.armed),
                                            np.int64(page_words), _shift(page_words))
        return miss, PairState(int(last), bool(armed))
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


_COMPILED: list = []  # [_jit_memory, _jit_glue] once imported (one assignment: threads see it whole)


def _jit():
    """The compiled compaction (:mod:`tlm.kernels._jit_memory`), None with ``TLM_KERNELS=numpy``."""
    if engine() != "numba":
        return None
    return _modules()[0]


def _modules() -> list:
    """:mod:`tlm.kernels._jit_memory` and :mod:`tlm.kernels._jit_glue`, imported on first use
    and kept (an import statement per call held the interpreter lock for a dict lookup and more)."""
    mods = _COMPILED
    if not mods:
        from tlm.kernels import _jit_glue, _jit_memory

        mods = [_jit_memory, _jit_glue]
        _COMPILED[:] = mods
    return mods


_SHIFTS: dict[int, int] = {}


def _shift(page_words: int) -> int:
    """:func:`tlm.kernels._jit_memory.shift_of`, kept per page size."""
    s = _SHIFTS.get(page_words)
    if s is None:
        s = _SHIFTS[page_words] = _modules()[0].shift_of(page_words)
    return s


def _pages(words: np.ndarray, page_words: int) -> np.ndarray:
    """Page of each word (a shift for the usual power-of-two page)."""
    if page_words & (page_words - 1) == 0:
        return words >> (page_words.bit_length() - 1)
    return words // page_words


def _ranges(first, last, owner, page_words: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``first``, ``last`` and ``owner`` (default: each range's index) as checked,
    contiguous int64 arrays of one length."""
    if page_words <= 0:
        raise ValueError(f"page_words (={page_words}) must be > 0")
    first = np.ascontiguousarray(first, dtype=np.int64).reshape(-1)
    last = np.ascontiguousarray(last, dtype=np.int64).reshape(-1)
    if first.shape != last.shape:
        raise ValueError(f"first ({first.shape[0]}) and last ({last.shape[0]}) differ in length")
    if owner is None:
        return first, last, np.arange(first.shape[0], dtype=np.int64)
    if isinstance(owner, np.ndarray) and owner.dtype == np.int64 and owner.shape == first.shape:
        return first, last, np.ascontiguousarray(owner)  # (already one int64 per range)
    return first, last, np.ascontiguousarray(np.broadcast_to(np.asarray(owner, dtype=np.int64), first.shape))


def _spans(first, last, owner, page_words: int):
    """Per (range, page) span of the non-empty ranges: its first and last word, its owner."""
    first, last, owner = _ranges(first, last, owner, page_words)
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
    if owner.shape != words.shape:
        raise ValueError(f"words ({words.shape[0]}) and owner ({owner.shape[0]}) differ in length")
    if words.shape[0] < 2:
        return words, owner
    jit = _jit()
    if jit is not None:
        if page_words <= 0:
            raise ValueError(f"page_words (={page_words}) must be > 0")
        return jit.compact(words, owner, np.int64(page_words), _shift(page_words))
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
        jit = _jit()
        if jit is not None:
            first, last, owner = _ranges(first, last, owner, page_words)
            return cls(*jit.range_runs(first, last, owner, np.int64(page_words), _shift(page_words)), page_words)
        _, hi, owner = _spans(first, last, owner, page_words)  # a span's last word is its largest
        return cls(*compact(hi, owner, page_words), page_words)

    @classmethod
    def of_csr(cls, words, ptr, page_words: int = PAGE_WORDS) -> Accesses:
        """One access per word, owner ``i``'s words ``words[ptr[i]:ptr[i+1]]``."""
        words = np.asarray(words)  # any integer type: only the compacted words are widened
        ptr = np.asarray(ptr, dtype=np.int64)
        if words.shape[0] == 0:
            return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), page_words)
        if ptr.ndim != 1 or ptr.shape[0] < 1 or ptr[0] != 0 or ptr[-1] != words.shape[0] or np.any(ptr[1:] < ptr[:-1]):
            raise ValueError(f"ptr must rise from 0 to the {words.shape[0]} words")
        jit = _jit()
        if jit is not None:
            if page_words <= 0:
                raise ValueError(f"page_words (={page_words}) must be > 0")
            return cls(*jit.csr_runs(words, ptr, np.int64(page_words), _shift(page_words)), page_words)
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

    def shifted(self, offset: int) -> Accesses:
        """The accesses ``offset`` words further (a whole number of pages: the same runs)."""
        if offset == 0:
            return self
        if offset % self.page_words:
            raise ValueError(f"offset (={offset}) is not a whole number of {self.page_words}-word pages")
        return Accesses(self.words + offset, self.owner, self.page_words)

    def relabel(self, owners: np.ndarray) -> Accesses:
        """Owner ``i`` renamed ``owners[i]``."""
        return Accesses(self.words, np.asarray(owners, dtype=np.int64)[self.owner], self.page_words)

    def owner_major(self) -> Accesses:
        """All accesses of owner 0, then of owner 1, ..., each owner's in their order."""
        own = self.owner
        if own.shape[0] < 2:
            return self
        if engine() == "numba" and own.dtype == np.int64 and self.words.dtype == np.int64:
            pw = self.page_words
            status, words, owner = _modules()[1].owner_major(self.words, own, np.int64(pw), _shift(pw))
            if status == 0:
                return self
            if status == 1:
                return Accesses(words, owner, pw)
        elif bool(np.all(own[1:] >= own[:-1])):
            return self
        order = np.argsort(own, kind="stable")
        return Accesses(*compact(self.words[order], own[order], self.page_words), self.page_words)


def _whole(name: str, value, low: int, high: int | None = None) -> int:
    """``value`` as an int, checked to be a whole number in ``[low, high]``."""
    ok = not isinstance(value, bool) and isinstance(value, (int, float, np.integer)) and int(value) == value
    if not ok or value < low or (high is not None and value > high):
        bound = f">= {low}" if high is None else f"in [{low}, {high}]"
        raise ValueError(f"{name} (={value!r}) must be a whole number {bound}")
    return int(value)


class Streams:
    """The cache pairs' states, carried from packet to packet (mutable).

    page_words : words per cache block (the page); pairs : block pairs of each PM's
    cache (:data:`PM_STREAMS` says which stream takes which pair). ``states`` is keyed
    by pair: ``"traversal[0]"`` (pair 0 of the Traversal PM's eye-ray phase), or a
    stream's own name for a stream with a pair of its own (the Intersection PM's).

    A pass takes one (default: a fresh one, every pair empty), charges its streams'
    accesses to their pairs and leaves the state after its packet in it. Packets of a
    frame run in order with one object give exactly the whole frame's misses, per owner.
    """

    # every setting, as :meth:`__init__` names it: what :meth:`settings` returns and a copy keeps
    # (:meth:`~tlm.kernels.recording.Deferred.like`); a new one is added here and to __init__
    SETTINGS = ("page_words", "pairs")

    def __init__(self, page_words: int = PAGE_WORDS, pairs: int = PAIRS):
        self.page_words = _whole("page_words", page_words, 1, MAX_PAGE_WORDS)
        self.pairs = _whole("pairs", pairs, 1)
        self.states: dict[str, PairState] = {}

    @classmethod
    def of(cls, cache) -> Streams:
        """Cold pairs of a run config's ``cache`` section (a :class:`~tlm.config_sections.CacheConfig`, or
        any object with its keys): every key by :data:`CACHE_KEYS`, so every caller (the frame's passes,
        the photon tracer, a study's map key) gets a new key with no change of its own; a key of the
        section that :data:`CACHE_KEYS` lacks is an error, never dropped. A mapping (the section as a config file
        gives it) or another object may give some keys only: the others are the defaults (h547)."""
        if is_dataclass(cache):
            given = {f.name: getattr(cache, f.name) for f in fields(cache)}
        elif isinstance(cache, Mapping):
            given = dict(cache)
        else:
            given = {name: getattr(cache, name) for name in CACHE_KEYS if hasattr(cache, name)}
        unknown = [name for name in given if name not in CACHE_KEYS]
        if unknown:
            raise ValueError(f"cache.{unknown[0]} is no setting of the cache model: give it a Streams setting "
                             f"in tlm.kernels.memory.CACHE_KEYS (docs/architecture.md, 'Changing the cache model')")
        return cls(**{CACHE_KEYS[name]: value for name, value in given.items()})

    def settings(self) -> dict:
        """Every setting (:data:`SETTINGS`) by its :meth:`__init__` name: ``type(self)(**settings())``
        is cold pairs like these."""
        return {name: getattr(self, name) for name in self.SETTINGS}

    def pair_of(self, name: str) -> tuple[str, int]:
        """The pair serving stream ``name`` and the stream's address region in it."""
        if name not in _PAIR_OF:
            return name, 0
        phase, k = _PAIR_OF[name]
        return f"{phase}[{k % self.pairs}]", k // self.pairs

    def charge(self, name: str, accesses: Accesses, n_owners: int, into: np.ndarray | None = None) -> np.ndarray:
        """Misses (n_owners,) int64 per owner of stream ``name``'s accesses, which run
        next on its pair, in the order given; also added to ``into`` (n_owners,) when
        given (which a :class:`~tlm.kernels.recording.Deferred` requires)."""
        sink = None if into is None else {name: into}
        return self._charge_pair(self.pair_of(name)[0], [(name, accesses)], n_owners, False, sink)[name]

    def charge_owner_major(self, parts: list[tuple[str, Accesses]], n_owners: int,
                           into: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        """Misses per owner of each named stream; ``parts`` are (name, accesses) in the
        order a kernel added them. The streams of one pair are merged into one stream,
        owner-major (each owner's accesses in the order added); the pairs run next.
        ``into``: stream name -> (n_owners,) int64 array the stream's misses are added to."""
        by_pair: dict[str, list[tuple[str, Accesses]]] = {}
        for name, acc in parts:
            by_pair.setdefault(self.pair_of(name)[0], []).append((name, acc))
        out: dict[str, np.ndarray] = {}
        for key, group in by_pair.items():
            out.update(self._charge_pair(key, group, n_owners, True, into))
        return out

    def fold(self, src: np.ndarray, index: np.ndarray, dst: np.ndarray) -> None:
        """Add misses ``src`` (n,) of ``into`` arrays to ``dst[index[i]]`` (misses per query
        summed per pixel); a :class:`~tlm.kernels.recording.Deferred` remembers it, to
        correct ``dst`` too."""
        dst += np.bincount(index, weights=src, minlength=dst.shape[0]).astype(np.int64)

    def settle(self, later: Streams, arrays: dict | None = None) -> None:
        """Charge a packet that ``later`` (a :class:`~tlm.kernels.recording.Deferred`)
        charged on cold pairs, as if it had run on these pairs (this packet's predecessors'
        state): the arrays its misses went to corrected (``arrays``: name -> array, where
        :meth:`~tlm.kernels.recording.Deferred.portable` named them), these pairs left in
        the state after it."""
        if later.settings() != self.settings():
            raise ValueError(f"{later!r} is not charged on pairs like {self!r}")
        for key, head in later.heads.items():
            where = (later.final(head.first), None if head.second is None else later.final(head.second))
            if arrays is not None:
                where = tuple(None if w is None else (arrays[w[0]], w[1]) for w in where)
            self.states[key] = head.settle(self.states.get(key, PairState()), later.states[key], *where)

    def _charge_pair(self, key: str, group: list[tuple[str, Accesses]], n_owners: int,
                     owner_major: bool, into: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        pw = self.page_words
        for _, acc in group:
            if acc.page_words != pw:
                raise ValueError(f"accesses compacted for {acc.page_words}-word pages, the pairs have {pw}")
        region_words = REGION_PAGES * pw
        region = {name: self.pair_of(name)[1] for name, _ in group}
        acc = Accesses.concat([a.shifted(region[name] * region_words) for name, a in group], pw)
        if owner_major:
            acc = acc.owner_major()
        miss, self.states[key] = page_misses(acc.words, self.states.get(key), pw)
        owner = np.asarray(acc.owner, dtype=np.int64)
        if len(region) == 1:
            (name,) = region
            out = {name: np.bincount(owner[miss], minlength=n_owners).astype(np.int64)}
        else:
            where = acc.words[miss] // region_words
            out = {name: np.bincount(owner[miss][where == r], minlength=n_owners).astype(np.int64)
                   for name, r in region.items()}
        if into is not None:
            for name, counts in out.items():
                into[name] += counts
        self._charged(key, acc, miss, {r: name for name, r in region.items()}, into)
        return out

    def _charged(self, key, acc, miss, names, into) -> None:
        """(A :class:`~tlm.kernels.recording.Deferred` remembers what the pair's state
        before the packet decides.)"""

    def __repr__(self) -> str:
        settings = "".join(f"{k}={v!r}, " for k, v in self.settings().items())
        return f"{type(self).__name__}({settings}states={self.states!r})"
