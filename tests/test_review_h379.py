"""h379's review of 8e84258: the report's granularity note calls the frame count most sizes ran
"the others" only where those are two sizes or more; where each count ran at one size (two sizes
in all, or every size its own count) it names every size."""

from pathlib import Path

from tlm.report.collect import Study
from tlm.report.tradeoff import granularity_per_frame

from .test_granularity_frames_h364 import _rows


def _note(frames) -> str:
    return granularity_per_frame(Study("granularity", Path("g"), _rows(frames)))


def test_one_size_of_each_count_is_named_not_the_others():
    note = _note((5, 16, 20))
    assert "the others" not in note
    assert "(5 at packets of 1; 16 at packets of 64; 20 at packets of 256: " in note


def test_two_or_more_sizes_of_the_most_common_count_are_the_others():
    assert "(5 at packets of 64; 16 at the others: " in _note((16, 5, 16))
    # (a tie of one size each: every size named, fewest frames first)
    rows = [r for r in _rows((16, 5, 16)) if r["packet_size"] != 256]
    note = granularity_per_frame(Study("granularity", Path("g"), rows))
    assert "(5 at packets of 64; 16 at packets of 1: " in note and "the others" not in note
