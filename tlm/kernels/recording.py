"""Recording a kernel's reads for the data cache (:mod:`tlm.kernels.memory`): streams
gathered in another order than the program's, charged owner-major (:class:`Recorder`);
a packet charged on cold pairs and settled later, in order, on the carried pairs
(:class:`Deferred`); and the reads of a packet's ray traversal (:func:`traversal_accesses`).

The address streams, their compaction and the pairs' states (:class:`~tlm.kernels.memory.Accesses`,
:class:`~tlm.kernels.memory.Streams`, :func:`~tlm.kernels.memory.page_misses`) are
:mod:`tlm.kernels.memory`'s, with the memory layout the streams read.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from tlm.kernels.engine import engine
from tlm.kernels.memory import (
    INDICES_PER_WORD,
    NODE_WORDS,
    PAGE_WORDS,
    PAIRS,
    REGION_PAGES,
    VERTEX_WORDS,
    Accesses,
    PairState,
    Streams,
    _modules,
    _pages,
    _shift,
)


@dataclass
class _Head:
    """What the state before a packet decides on one pair: the packet's first run (its
    page, whether its own accesses armed the prefetch, where its first access's miss went:
    an ``into`` array and an owner) and, once seen, its second run (page, where its first
    access's miss went, whether it missed after the first run as charged from cold)."""

    page: int
    armed: bool
    first: tuple[np.ndarray, int]
    next_page: int = -1
    second: tuple[np.ndarray, int] | None = None
    second_missed: bool = True

    def settle(self, before: PairState, after_cold: PairState, first=None, second=None) -> PairState:
        """Correct the two misses for the state ``before`` the packet (in the arrays
        ``first``, ``second`` name, default: where they went); the state after it."""
        sink, owner = first or self.first
        if self.page == before.page or (self.page == before.page + 1 and before.armed and before.page >= 0):
            sink[owner] -= 1  # (from cold, the first access always missed)
        armed = self.armed or (before.armed and before.page == self.page)
        if self.second is None:  # one run: the packet ends on the page it started with
            return PairState(self.page, armed)
        sink, owner = second or self.second
        missed = not (self.next_page == self.page + 1 and armed)
        sink[owner] += int(missed) - int(self.second_missed)
        return after_cold  # from the second run on, nothing depends on the state before


def _address(a: np.ndarray, i: int) -> int:
    """Where element ``i`` of the one-dimensional ``a`` lies in memory."""
    return a.__array_interface__["data"][0] + i * a.strides[0]


class Deferred(Streams):
    """Cache pairs for a packet charged before its predecessors are (on another thread).

    Each pair starts empty, and the misses are those of cold pairs; what the real state
    before the packet would change is only the first access of the packet's first run on
    each pair (a miss from cold; a hit when the pair's page, or the armed prefetch of it,
    is that run's page) and the first access of its second run (a hit when it is the next
    page and the prefetch is armed, which the state can arm while the first run's page is
    current). Everything after the second run's start sees the same pages and arms from
    either state. So :meth:`Streams.settle` (the carried pairs, packets in order) corrects
    those two misses per pair in the ``into`` arrays they went to (every charge names
    them; through :meth:`fold`, in the arrays they were summed into) and takes the state
    after the packet: exactly the misses of the packets charged in order.
    """

    def __init__(self, page_words: int = PAGE_WORDS, pairs: int = PAIRS, **more):
        super().__init__(page_words, pairs, **more)  # (more: a setting Streams has beside these)
        self.heads: dict[str, _Head] = {}
        self.links: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    @classmethod
    def like(cls, streams: Streams) -> Deferred:
        """Cold pairs of ``streams``' settings, every one (:meth:`Streams.settings`: the block size,
        the pairs and any added since)."""
        return cls(**streams.settings())

    def fold(self, src: np.ndarray, index: np.ndarray, dst: np.ndarray) -> None:
        super().fold(src, index, dst)
        self.links.append((src, np.asarray(index), dst))

    def final(self, where: tuple[np.ndarray, int]) -> tuple[np.ndarray, int]:
        """The array and place a miss of ``where`` (an ``into`` array, an owner) ends in,
        through the :meth:`fold` calls (a query's miss in its pixel's count)."""
        sink, i = where
        if not self.links:
            return where
        for _ in range(len(self.links) + 1):
            at = _address(sink, i)
            for src, index, dst in self.links:
                start = _address(src, 0)
                q, r = divmod(at - start, src.strides[0] or 1)
                if r == 0 and 0 <= q < src.shape[0] and src.dtype == sink.dtype:
                    sink, i = dst, int(index[q])
                    break
            else:
                return sink, i
        raise ValueError("the folds of a Deferred's misses go round in a circle")

    def portable(self, names: dict[int, str]) -> Deferred:
        """This packet's charges with the arrays their misses end in (:meth:`final`) named
        by ``names`` (``id(array)`` -> name), to be settled in another process."""
        out = Deferred.like(self)
        out.states = dict(self.states)
        for key, head in self.heads.items():
            first = self.final(head.first)
            second = None if head.second is None else self.final(head.second)
            out.heads[key] = replace(head, first=(names[id(first[0])], first[1]),
                                     second=None if second is None else (names[id(second[0])], second[1]))
        return out

    def settle(self, later: Deferred, arrays: dict | None = None) -> None:
        raise TypeError("a Deferred's own state is not the packet's before: settle on the carried Streams")

    def _charged(self, key, acc, miss, names, into) -> None:
        words = acc.words
        n = words.shape[0]
        head = self.heads.get(key)
        if n == 0 or (head is not None and head.second is not None):
            return
        if into is None:
            raise ValueError("a Deferred charge needs the arrays its misses go to (into)")
        pw = self.page_words
        region_words = REGION_PAGES * pw

        def where(i: int) -> tuple[np.ndarray, int]:
            return into[names[int(words[i] // region_words)]], int(acc.owner[i])

        page = _pages(words, pw)
        if head is None:
            head = self.heads[key] = _Head(int(page[0]), False, where(0))
        away = page != head.page
        i = int(np.argmax(away)) if away.any() else n
        head.armed |= bool(np.any(words[:i] - page[:i] * pw > pw // 2))
        if i < n:
            head.next_page, head.second, head.second_missed = int(page[i]), where(i), bool(miss[i])


class Recorder:
    """Accesses of named streams, gathered in any order of owners, charged owner-major.

    A kernel that runs its work in another order than the program charges (the bounces
    of a specular walk, all photons of a bounce at once) adds each step's accesses with
    the program's owner (pixel, photon) of every access; :meth:`collect` puts each
    stream in owner order, each owner's accesses in the order they were added, and
    :meth:`charge` does the same per pair (streams sharing a pair merged, an owner's
    accesses of all of them in the order added).
    """

    def __init__(self, page_words: int = PAGE_WORDS):
        self.page_words = page_words
        self.added: list[tuple[str, Accesses]] = []

    def add(self, name: str, accesses: Accesses, owners: np.ndarray | None = None) -> None:
        """Append ``accesses`` to stream ``name``, owner ``i`` renamed ``owners[i]``."""
        if owners is not None:
            accesses = accesses.relabel(owners)
        self.added.append((name, accesses))

    def collect(self) -> dict[str, Accesses]:
        """Every stream's accesses, owner-major."""
        parts: dict[str, list[Accesses]] = {}
        for name, acc in self.added:
            parts.setdefault(name, []).append(acc)
        return {name: Accesses.concat(p, self.page_words).owner_major() for name, p in parts.items()}

    def charge(self, streams: Streams, n_owners: int, into: dict[str, np.ndarray] | None = None
               ) -> dict[str, np.ndarray]:
        """Misses per owner of every stream, charged to ``streams``' pairs owner-major
        (and added to ``into[name]`` when given, as :meth:`Streams.charge_owner_major`)."""
        if self.added and streams.page_words != self.page_words:
            raise ValueError(f"accesses recorded for {self.page_words}-word pages, the pairs have "
                             f"{streams.page_words}")
        return streams.charge_owner_major(self.added, n_owners, into)


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
    if engine() == "numba" and NODE_WORDS == 1 and page_words > 0:
        glue = _modules()[1]
        ok, *runs = glue.traversal_runs(
            touched.node_ids, np.asarray(touched.node_ptr, dtype=np.int64), touched.leaf_ids,
            np.asarray(touched.leaf_ptr, dtype=np.int64), leaf_first, leaf_last, INDICES_PER_WORD, VERTEX_WORDS,
            np.int64(page_words), _shift(page_words))
        if ok:  # (else the numpy code below says what is wrong)
            return {
                "nodes": Accesses(runs[0], runs[1], page_words),
                "indices": Accesses(runs[2], runs[3], page_words),
                "vertices": Accesses(runs[4], runs[5], page_words),
            }
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
