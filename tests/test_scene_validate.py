"""The checks of scene-file values (:mod:`tlm.scenes.validate`): each value it accepts
comes back as a float, each it rejects is a one-line InputError naming file, key and value."""

from __future__ import annotations

import math

import pytest

from tlm.errors import InputError
from tlm.scenes.validate import keys, mapping, num, vec

SRC = "scenes/x.yaml"


def _error(call) -> str:
    with pytest.raises(InputError) as e:
        call()
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{SRC}: ")
    return msg


def test_mapping_and_keys():
    d = {"albedo": 1}
    assert mapping(d, SRC, "materials.red") is d
    assert _error(lambda: mapping([1], SRC, "materials.red")) == f"{SRC}: materials.red: must be a mapping, got [1]"
    keys({"albedo": 1, "kind": 2}, ("kind", "albedo"), SRC, "materials.red")
    msg = _error(lambda: keys({"kind": 1, "albdo": 2}, ("kind", "albedo"), SRC, "materials.red"))
    assert msg.startswith(f"{SRC}: materials.red.albdo: unknown key") and "albedo" in msg  # did you mean
    assert _error(lambda: keys({"cmaera": 1}, ("camera",), SRC, "")).startswith(f"{SRC}: cmaera: unknown key")


def test_vec_accepts_n_finite_numbers_in_range():
    assert vec([1, 2.5, -3], SRC, "eye") == (1.0, 2.5, -3.0)
    assert all(type(x) is float for x in vec([1, 2, 3], SRC, "eye"))
    assert vec([0, 1], SRC, "uv", n=2, lo=0, hi=1) == (0.0, 1.0)
    for bad in ([1, 2], [1, 2, 3, 4], (1, 2, 3), [1, True, 3], [1, "2", 3], 3):
        assert _error(lambda bad=bad: vec(bad, SRC, "eye")) == f"{SRC}: eye: {bad!r} is not a list of 3 numbers"
    assert _error(lambda: vec([1, math.inf, 3], SRC, "eye")).endswith("is not finite")
    assert _error(lambda: vec([1, math.nan, 3], SRC, "eye")).endswith("is not finite")
    assert _error(lambda: vec([0.5, -0.1, 0], SRC, "albedo", lo=0, hi=1)).endswith("[0.5, -0.1, 0] must be >= 0")
    assert _error(lambda: vec([0.5, 1.1, 0], SRC, "albedo", lo=0, hi=1)).endswith("[0.5, 1.1, 0] must be <= 1")


def test_num_bounds_inclusive_or_exclusive():
    assert num(3, SRC, "ior") == 3.0 and type(num(3, SRC, "ior")) is float
    assert num(0, SRC, "k", lo=0) == 0.0 and num(1, SRC, "k", hi=1) == 1.0
    for bad in (True, "1", None, math.nan, math.inf):
        assert _error(lambda bad=bad: num(bad, SRC, "ior")) == f"{SRC}: ior: {bad!r} is not a finite number"
    assert _error(lambda: num(0, SRC, "vfov", lo=0, lo_exclusive=True)) == f"{SRC}: vfov: 0 must be > 0"
    assert _error(lambda: num(-1, SRC, "k", lo=0)) == f"{SRC}: k: -1 must be >= 0"
    assert _error(lambda: num(181, SRC, "vfov", hi=180)) == f"{SRC}: vfov: 181 must be <= 180"
