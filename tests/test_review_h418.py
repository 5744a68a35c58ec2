"""h418: review of 6cf04f1 (:func:`tlm.config_words.listing`, :meth:`tlm.report.collect.Sweep.run_of`): a
``whole`` not above ``named`` no longer lets "and 1 more" through, items are said as ``str`` gives them (a
generator of numbers, read once), a list of alternatives counts the rest after "or", and a row without a hash
finds no point (not the folder ``points/None``)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from tlm.config_words import listing
from tlm.report.collect import Sweep


@pytest.mark.parametrize("whole", [2, 3, 4])
def test_a_whole_not_above_named_never_says_one_more(whole):
    assert listing(list("abcde"), 4, whole=whole) == "a, b, c, d and e"
    assert listing(list("abcdef"), 4, whole=whole) == "a, b, c, d and 2 more"


def test_items_said_as_str_gives_them_read_once():
    numbers = (i for i in range(6))
    assert listing(numbers, 3) == "0, 1, 2 and 3 more"
    assert listing(numbers) == ""  # (the generator was read once, by the first call)
    assert listing([7]) == "7"
    assert listing([1, 2.5, None]) == "1, 2.5 and None"


def test_alternatives_count_the_rest_after_or():
    assert listing(list("abcdef"), 3, last="or") == "a, b, c or 3 more"
    assert listing(list("abcd"), 3, last="or") == "a, b, c or d"


def test_a_row_without_a_hash_has_no_point():
    runs = [SimpleNamespace(path=Path("sw/points/None")), SimpleNamespace(path=Path("sw/points/7"))]
    sw = Sweep(Path("sw"), {}, [], runs)
    assert sw.run_of({"hash": None}) is None
    assert sw.run_of({"point": 0}) is None
    assert sw.run_of({"hash": 7}) is runs[1]  # (a hash read as a number: its folder's name as text)
