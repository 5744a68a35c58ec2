"""The PM data cache: page misses of address streams, checked by hand; compressed
streams (page spans, compaction, owner-major reordering) against the full streams;
streams sharing a pair (``cache.pairs``), by hand and against the full merged stream."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tlm.kernels.memory import (
    PAGE_WORDS,
    PM_STREAMS,
    REGION_PAGES,
    Accesses,
    PairState,
    Streams,
    misses_per_packet,
    page_misses,
    page_spans,
    range_misses,
    span_addresses,
)
from tlm.kernels.recording import Recorder


def misses(addresses, state=None, page_words=8):
    miss, end = page_misses(np.array(addresses), state, page_words)
    return np.flatnonzero(miss).tolist(), end


def test_sequential_stream_misses_once_prefetch_hides_the_rest():
    # pages of 8 words: the prefetch of page p+1 is armed once an access passes offset 4
    got, end = misses(range(40))
    assert got == [0]  # a cold miss, then every next page was prefetched
    assert end == PairState(page=4, armed=True)


def test_a_jump_back_misses_and_a_next_page_before_the_middle_misses():
    #            page 0      page 1 (offset 0-3: prefetch not armed)   page 2
    got, _ = misses([0, 1, 2, 3, 8, 9, 10, 11, 16, 17, 0])
    assert got == [0, 4, 8, 10]


def test_state_carries_across_packets():
    stream = np.arange(100)
    whole, _ = page_misses(stream, page_words=8)
    first, mid = page_misses(stream[:37], page_words=8)
    second, _ = page_misses(stream[37:], mid, page_words=8)
    np.testing.assert_array_equal(np.concatenate([first, second]), whole)


def test_a_prefetch_armed_in_the_previous_packet_stays_armed():
    # page 0 is armed by offset 6 in the first packet; the second goes on with page 0
    # below the middle, then steps to page 1: the prefetch issued before still hits
    whole, _ = misses([0, 6, 1, 2, 8])
    first, mid = misses([0, 6])
    second, end = misses([1, 2, 8], mid)
    assert whole == first == [0] and second == [] and end == PairState(1, False)


def test_misses_per_packet_and_empty_stream():
    addresses = np.array([0, 1, 2, 3, 4, 5, 6, 7, 100, 101, 0])
    packet = np.array([0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2])
    counts, _ = misses_per_packet(addresses, packet, 4, page_words=8)
    assert counts.tolist() == [1, 1, 1, 0]
    miss, end = page_misses(np.zeros(0, np.int64))
    assert miss.shape == (0,) and end == PairState()


def test_repeated_page_is_one_run():
    got, end = misses([5, 5, 5, 5])
    assert got == [0] and end.page == 0 and end.armed  # offset 5 > 4: armed


def test_span_addresses():
    assert span_addresses([0, 5], [2, 6], 3).tolist() == [0, 1, 2, 3, 4, 5, 15, 16, 17]
    assert span_addresses([3], [3]).tolist() == []
    assert span_addresses([], []).tolist() == []


def test_default_page_is_the_thesis_block():
    assert PAGE_WORDS == 1024
    got, _ = page_misses(np.arange(10 * 1024))
    assert np.flatnonzero(got).tolist() == [0]


def test_bad_page_size():
    with pytest.raises(ValueError, match="page_words"):
        page_misses(np.arange(3), page_words=0)


# ---------------------------------------------------------------- compressed streams

OWNERS = 5
ranges = st.lists(st.tuples(st.integers(0, 120), st.integers(-3, 40), st.integers(0, OWNERS - 1)), max_size=30)
pages = st.sampled_from([1, 2, 3, 4, 8, 16, 1024])
states = st.one_of(st.none(), st.builds(PairState, st.integers(-1, 12), st.booleans()))


def expand(first, last, owner):
    """The full stream: every word of every range, with its owner."""
    words = span_addresses(first, last)
    return words, np.repeat(owner, np.maximum(np.asarray(last) - np.asarray(first), 0))


def arrays(rs):
    a = np.array(rs, dtype=np.int64).reshape(-1, 3)
    return a[:, 0], a[:, 0] + a[:, 1], a[:, 2]


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(ranges, pages, states)
def test_page_spans_give_the_misses_of_the_full_stream(rs, page_words, state):
    first, last, owner = arrays(rs)
    words, own = expand(first, last, owner)
    want, want_end = misses_per_packet(words, own, OWNERS, state, page_words)
    got, end = range_misses(first, last, owner, OWNERS, state, page_words)
    np.testing.assert_array_equal(got, want)
    assert end == want_end
    # the spans: first and last word of each (range, page), in the range's page
    spans, span_owner = page_spans(first, last, owner, page_words)
    assert spans.shape == span_owner.shape and spans.shape[0] % 2 == 0
    lo, hi = spans[0::2], spans[1::2]
    assert np.all(lo <= hi) and np.all(lo // page_words == hi // page_words)
    assert np.isin(spans, words).all() and np.array_equal(np.unique(lo // page_words), np.unique(words // page_words))
    # and compacted
    acc = Accesses.of_ranges(first, last, owner, page_words)
    got, end = misses_per_packet(acc.words, acc.owner, OWNERS, state, page_words)
    np.testing.assert_array_equal(got, want)
    assert end == want_end


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.integers(0, OWNERS - 1), ranges), max_size=8), pages, states)
def test_compacted_steps_in_owner_order_give_the_full_owner_major_stream(steps, page_words, state):
    """A kernel's steps (bounces) each read ranges for several owners; charged owner-major,
    each owner's reads in step order, the compacted steps give the full stream's misses."""
    rec = Recorder(page_words)
    per_owner = {o: [] for o in range(OWNERS)}
    for shift, rs in steps:
        first, last, owner = arrays(rs)
        local = (owner + shift) % OWNERS  # the step's own owner numbering ...
        names = (np.arange(OWNERS) - shift) % OWNERS  # ... renamed to the program's
        rec.add("s", Accesses.of_ranges(first, last, local, page_words), names)
        for f, la, o in zip(first.tolist(), last.tolist(), owner.tolist(), strict=True):
            per_owner[o].append((f, la))
    flat = np.array([(f, la, o) for o in range(OWNERS) for f, la in per_owner[o]], dtype=np.int64).reshape(-1, 3)
    words, own = expand(flat[:, 0], flat[:, 1], flat[:, 2])
    want, want_end = misses_per_packet(words, own, OWNERS, state, page_words)
    streams = Streams(page_words)
    if state is not None:
        streams.states["s"] = state
    got = rec.charge(streams, OWNERS).get("s", np.zeros(OWNERS, np.int64))
    np.testing.assert_array_equal(got, want)
    assert streams.states.get("s", state or PairState()) == want_end


def test_streams_carry_the_state_from_packet_to_packet():
    rng = np.random.default_rng(1)
    length = rng.integers(0, 60, 300)
    first = np.cumsum(length) - length + np.where(rng.random(300) < 0.05, 500, 0)  # mostly sequential
    last = first + length
    owner = np.sort(rng.integers(0, 40, 300))
    whole, _ = range_misses(first, last, owner, 40, page_words=64)
    cuts = ((0, 7), (7, 8), (8, 40))
    for carried in (True, False):
        streams = Streams(64)
        parts = []
        for lo, hi in cuts:
            sel = (owner >= lo) & (owner < hi)
            acc = Accesses.of_ranges(first[sel], last[sel], owner[sel] - lo, 64)
            parts.append((streams if carried else Streams(64)).charge("x", acc, hi - lo))
        if carried:
            np.testing.assert_array_equal(np.concatenate(parts), whole)
        else:  # cold pairs per packet miss where the packet starts
            assert np.concatenate(parts).sum() > whole.sum()


def test_compact_keeps_the_largest_word_of_each_run():
    acc = Accesses.of_words([3, 1, 6, 9, 8, 2, 2], [0, 0, 0, 0, 1, 1, 2], page_words=8)
    assert acc.words.tolist() == [6, 9, 8, 2, 2] and acc.owner.tolist() == [0, 0, 1, 1, 2]
    assert page_spans([0, 5, 9], [20, 5, 10], [4, 5, 6], 8)[0].tolist() == [0, 7, 8, 15, 16, 19, 9, 9]
    with pytest.raises(ValueError, match="16-word pages"):
        Streams(8).charge("x", acc.__class__(acc.words, acc.owner, 16), 3)
    with pytest.raises(ValueError, match="page_words"):
        Streams(0)


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(0, 60), max_size=40), st.lists(st.integers(0, 40), max_size=4), pages, states)
def test_any_split_with_the_state_carried_is_the_whole_stream(stream, cuts, page_words, state):
    a = np.array(stream, dtype=np.int64)
    whole, end = page_misses(a, state, page_words)
    parts, s = [], state
    for lo, hi in zip([0, *sorted(cuts)], [*sorted(cuts), len(stream)], strict=True):
        miss, s = page_misses(a[lo:hi] if lo < hi else a[:0], s, page_words)
        parts.append(miss)
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    assert s == end or (len(stream) == 0 and s == (state or PairState()))


# ---------------------------------------------------------------- pairs shared by streams


def test_streams_take_pair_k_mod_pairs_of_their_pm_phase():
    want = {  # pairs -> stream -> (pair, address region in it)
        1: {"nodes": ("traversal[0]", 0), "indices": ("traversal[0]", 1),
            "shadow_nodes": ("shadow_traversal[0]", 0), "shadow_indices": ("shadow_traversal[0]", 1),
            "shading": ("fragment[0]", 0), "photons": ("fragment[0]", 1)},
        2: {"nodes": ("traversal[0]", 0), "indices": ("traversal[1]", 0),
            "shadow_nodes": ("shadow_traversal[0]", 0), "shadow_indices": ("shadow_traversal[1]", 0),
            "shading": ("fragment[0]", 0), "photons": ("fragment[1]", 0)},
    }
    want[3] = want[4] = want[2]
    for pairs, table in want.items():
        streams = Streams(pairs=pairs)
        assert {name: streams.pair_of(name) for name in table} == table
        # the Intersection PM's vertex streams (and any unlisted one) have a pair of their own
        for name in ("vertices", "shadow_vertices", "x"):
            assert streams.pair_of(name) == (name, 0)
    assert PM_STREAMS["traversal"] == ("nodes", "indices")
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="pairs"):
            Streams(pairs=bad)


def test_two_streams_on_one_pair_evict_each_other_by_hand():
    # pages of 8 words (prefetch armed past offset 4). Owner 0 reads node words 0, 5 and
    # index words 0, 1; owner 1 reads node word 9 and index word 2. Alone (pairs = 2):
    #   nodes    0 5 | 9   -> page 0 misses (armed by 5), page 1 was prefetched: [1, 0]
    #   indices  0 1 | 2   -> page 0 misses once:                                 [1, 0]
    # On one pair (pairs = 1), owner-major, a ray's nodes then its indices, the indices in
    # a region of their own (page R = REGION_PAGES of the merged stream):
    #   N0 (0, 5) miss | R (0, 1) miss | N1 (9) miss: its prefetch was lost | R (2) miss
    #   -> nodes [1, 1], indices [1, 1]; the pair ends on page R, not armed (offset 2).
    # The Intersection PM's vertices (0 | 3, 30) keep a pair of their own either way:
    #   page 0 misses, 3 hits, page 3 misses (and arms): [1, 1].
    def record(pairs):
        rec = Recorder(8)
        rec.add("nodes", Accesses.of_words([0, 5, 9], [0, 0, 1], 8))
        rec.add("indices", Accesses.of_words([2, 0, 1], [0, 1, 1], 8), owners=[1, 0])  # a step's own numbering
        rec.add("vertices", Accesses.of_words([0, 3, 30], [0, 1, 1], 8))
        streams = Streams(8, pairs)
        got = {k: v.tolist() for k, v in rec.charge(streams, 2).items()}
        return got, streams.states

    got, states = record(2)
    assert got == {"nodes": [1, 0], "indices": [1, 0], "vertices": [1, 1]}
    assert states == {"traversal[0]": PairState(1, False), "traversal[1]": PairState(0, False),
                      "vertices": PairState(3, True)}
    got, states = record(1)
    assert got == {"nodes": [1, 1], "indices": [1, 1], "vertices": [1, 1]}  # the vertices: unaffected
    assert states == {"traversal[0]": PairState(REGION_PAGES, False), "vertices": PairState(3, True)}
    # a stream charged alone on a shared pair keeps its region: the pair's state goes on
    streams = Streams(8, 1)
    assert streams.charge("indices", Accesses.of_words([3], [0], 8), 1).tolist() == [1]
    assert streams.charge("indices", Accesses.of_words([6], [0], 8), 1).tolist() == [0]
    assert streams.states == {"traversal[0]": PairState(REGION_PAGES, True)}


STREAMS = ("nodes", "indices", "vertices")


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(STREAMS), st.integers(0, OWNERS - 1), ranges), max_size=8),
       pages, st.sampled_from([1, 2, 4]), st.lists(st.integers(0, OWNERS), max_size=3))
def test_shared_pairs_give_the_full_merged_stream_in_any_packets(steps, page_words, pairs, cuts):
    """Steps of several streams, charged owner-major with their pairs merged, give the
    misses of the full merged stream (each owner's words in step order, each stream's
    words in its region), per stream; and so do packets of owners with the state carried."""
    rec = Recorder(page_words)
    per_owner = {o: [] for o in range(OWNERS)}
    probe = Streams(page_words, pairs)
    for name, shift, rs in steps:
        first, last, owner = arrays(rs)
        local = (owner + shift) % OWNERS
        rec.add(name, Accesses.of_ranges(first, last, local, page_words), (np.arange(OWNERS) - shift) % OWNERS)
        for f, la, o in zip(first.tolist(), last.tolist(), owner.tolist(), strict=True):
            per_owner[o].append((name, f, la))
    want = {}
    for key in dict.fromkeys(probe.pair_of(name)[0] for name in STREAMS):
        rows = [(o, name, f, la) for o in range(OWNERS) for name, f, la in per_owner[o]
                if probe.pair_of(name)[0] == key]
        words, owner, which = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
        for o, name, f, la in rows:
            w = span_addresses([f], [la]) + probe.pair_of(name)[1] * REGION_PAGES * page_words
            words.append(w)
            owner.append(np.full(w.shape[0], o))
            which.append(np.full(w.shape[0], STREAMS.index(name)))
        miss, _ = page_misses(np.concatenate(words), page_words=page_words)
        owner, which = np.concatenate(owner)[miss], np.concatenate(which)[miss]
        for name in STREAMS:
            if probe.pair_of(name)[0] == key:
                want[name] = np.bincount(owner[which == STREAMS.index(name)], minlength=OWNERS)
    got = rec.charge(Streams(page_words, pairs), OWNERS)
    for name in STREAMS:
        np.testing.assert_array_equal(got.get(name, np.zeros(OWNERS, np.int64)), want[name], err_msg=name)
    # the same steps charged in packets of owners, in owner order, with one Streams
    streams, parts = Streams(page_words, pairs), {name: [] for name in STREAMS}
    bounds = [0, *sorted(cuts), OWNERS]
    for lo, hi in itertools.pairwise(bounds):
        packet = Recorder(page_words)
        for name, acc in rec.added:
            keep = (acc.owner >= lo) & (acc.owner < hi)
            packet.add(name, Accesses(acc.words[keep], acc.owner[keep] - lo, page_words))
        got = packet.charge(streams, hi - lo)
        for name in STREAMS:
            parts[name].append(got.get(name, np.zeros(hi - lo, np.int64)))
    for name in STREAMS:
        np.testing.assert_array_equal(np.concatenate(parts[name]), want[name], err_msg=name)
