"""The PM data cache: page misses of address streams, checked by hand."""

from __future__ import annotations

import numpy as np
import pytest

from tlm.arch.cache import PAGE_WORDS, PairState, misses_per_packet, page_misses, span_addresses


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
