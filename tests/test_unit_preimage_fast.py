"""The vectorized :func:`tlm.scenes.objfile.unit_preimage` gives, bit for bit, what the first,
one-scale-at-a-time search gave (kept below as the oracle): an exported file holds its results,
so a reader that found another pre-image (a later scale, another rounding) would read back
other normals. Random unit normals, normals written with few digits, the few whose first scale
is past 4096 or that none fixes, zero, NaN, infinite, tiny and huge ones, every shape."""

from __future__ import annotations

import numpy as np
import pytest

from tlm.scenes import objfile


def _oracle(normals: np.ndarray) -> np.ndarray:
    """unit_preimage as it was (commit 22b6071): scale k alone for k = 1 .. 4096 over the
    vectors left, then 2 ** 16 more scales per vector left, 4096 at a time."""
    _unit, _PHI = objfile._unit, objfile._PHI
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    out = n.copy()
    todo = np.flatnonzero((_unit(n) != n).any(axis=1))
    k = 1
    while todo.shape[0] and k <= 4096:
        cand = n[todo] * 2.0 ** ((k * _PHI) % 1.0)
        ok = (_unit(cand) == n[todo]).all(axis=1)
        out[todo[ok]] = cand[ok]
        todo, k = todo[~ok], k + 1
    if todo.shape[0]:
        scales = (2.0 ** ((np.arange(k, k + (1 << 16)) * _PHI) % 1.0)).reshape(16, -1, 1)
        for i in todo.tolist():
            for chunk in scales:
                cand = n[i] * chunk
                hit = np.flatnonzero((_unit(cand) == n[i]).all(axis=1))
                if hit.shape[0]:
                    out[i] = cand[hit[0]]
                    break
    return out.reshape(np.shape(normals))


def _hex(rows: list[tuple[str, str, str]]) -> np.ndarray:
    return np.array([[float.fromhex(c) for c in r] for r in rows])


# unit normals (from a seeded normal distribution) whose first scale is past the first 4096
# (4968, 7198, 15770: the oracle's second stage), and two that no scale fixes
LATE = _hex([("-0x1.b20b4cf8f39dep-2", "0x1.53e21647ef152p-1", "-0x1.3b79c1d854175p-1"),
             ("-0x1.fa461af1e3390p-2", "0x1.29adb956a2565p-3", "0x1.b6c78a91b5556p-1"),
             ("-0x1.50a07958841b0p-1", "-0x1.9fdb415317065p-2", "-0x1.44f315fcd023bp-1")])
NONE_FIXES = _hex([("-0x1.cf3dac407d7afp-3", "0x1.ede0daa7447e6p-1", "0x1.159845c9a9558p-3"),
                   ("-0x1.40ed157648366p-6", "0x1.c729c79c643aap-2", "0x1.ca87c1aef2422p-1")])


def _odd() -> np.ndarray:
    """Zero (signed), NaN (quiet, signalling, one component), infinite, tiny, huge, non-unit vectors."""
    snan = np.array([0x7FF0000000000001], dtype=np.uint64).view(np.float64)[0]
    nan, inf = np.nan, np.inf
    return np.array([[0.0, 0.0, 0.0], [-0.0, 0.0, -0.0], [nan, nan, nan], [nan, 0.0, 0.0], [snan, 1.0, 0.0],
                     [inf, 0.0, 0.0], [-inf, inf, 1.0], [5e-324, 0.0, 0.0], [1e-200, 1e-200, 0.0],
                     [1e200, 1e200, 1e200], [3.0, 4.0, 0.0], [0.5, 0.5, 0.5]])


@pytest.fixture(scope="module")
def normals() -> np.ndarray:
    rng = np.random.default_rng(20041)
    v = rng.normal(size=(40000, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    digits = rng.integers(1, 7, size=48)  # (as a file writes them: 'vn 0.707 0 -0.7')
    few = np.array([np.round(r, d) for r, d in zip(v[:48], digits, strict=True)])
    exact = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [0.6, 0.8, 0.0], [0.28, 0.0, -0.96],
                      [0.36, 0.48, 0.8]])
    out = np.concatenate([v, few, exact, LATE, NONE_FIXES, _odd()])
    return out[rng.permutation(out.shape[0])]


@pytest.fixture(scope="module")
def expected(normals: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore", invalid="ignore"):
        return _oracle(normals)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def test_the_same_bits_as_the_one_scale_at_a_time_search(normals, expected):
    with np.errstate(over="ignore", invalid="ignore"):
        got = objfile.unit_preimage(normals)
        fixed = (objfile._unit(expected) == normals).all(axis=1)
    assert _same(got, expected), f"{np.count_nonzero((got != expected).any(axis=1))} vectors differ"
    # (the cases are there: most fixed as they are, many by a scale, the late ones, the unfixable ones)
    assert 0.5 < np.count_nonzero(fixed & (expected == normals).all(axis=1)) / normals.shape[0] < 0.8
    assert np.count_nonzero(fixed & (expected != normals).any(axis=1)) > 0.2 * normals.shape[0]
    k = objfile._first_scales(LATE, objfile._scales())
    assert (k >= 4096).all() and (objfile._first_scales(NONE_FIXES, objfile._scales()) == -1).all()


def test_the_same_bits_in_small_blocks(normals, expected, monkeypatch):
    """Blocks of rows and of candidates far smaller than the vectors: every way of trying a block
    (one scale for many vectors, a few scales (scale, vector), many scales (vector, scale))."""
    monkeypatch.setattr(objfile, "_ROWS", 5000)
    monkeypatch.setattr(objfile, "_BLOCK", 1024)
    monkeypatch.setattr(objfile, "_MIN", 64)
    seen = set()
    gives_back = objfile._gives_back

    def spy(cx, cy, cz, n):
        b = "one" if cx.ndim == 1 else "scale, vector" if n[0].ndim == 1 else "vector, scale"
        seen.add(b)
        return gives_back(cx, cy, cz, n)

    monkeypatch.setattr(objfile, "_gives_back", spy)
    with np.errstate(over="ignore", invalid="ignore"):
        got = objfile.unit_preimage(normals)
    assert _same(got, expected), f"{np.count_nonzero((got != expected).any(axis=1))} vectors differ"
    assert seen == {"one", "scale, vector", "vector, scale"}


@pytest.mark.parametrize("shape", ["(3,)", "(2, 2, 3)", "(0, 3)", "list", "float32", "strided"])
def test_every_shape_and_type_as_before(normals, shape):
    rng = np.random.default_rng(3)
    v = normals[rng.permutation(normals.shape[0])[:12]]
    v = v[np.isfinite(v).all(axis=1) & (np.abs(v) < 1e100).all(axis=1)][:4]
    arg = {"(3,)": v[0], "(2, 2, 3)": v.reshape(2, 2, 3), "(0, 3)": v[:0], "list": v.tolist(),
           "float32": v.astype(np.float32), "strided": np.asfortranarray(np.c_[v, v])[:, ::2]}[shape]
    assert _same(objfile.unit_preimage(arg), _oracle(arg))


def test_the_length_is_summed_as_numpys_norm_sums_it():
    """_gives_back computes the length itself (sqrt((x x + y y) + z z)): the same bits as
    ``np.linalg.norm`` (which _unit calls) where the order of the sum matters, and the same
    verdict as ``_unit(c) == n`` for vectors that normalize to n, an ulp off it, and odd ones."""
    rng = np.random.default_rng(11)
    c = rng.normal(size=(20000, 3)) * np.exp(rng.normal(size=(20000, 3)) * 4)  # (magnitudes far apart)
    s = c * c
    assert not np.array_equal((s[:, 0] + s[:, 1]) + s[:, 2], s[:, 0] + (s[:, 1] + s[:, 2]))  # (the order matters)
    c = np.concatenate([c, _odd()])
    with np.errstate(over="ignore", invalid="ignore"):
        n = objfile._unit(c)
    n[::3, 1] = np.nextafter(n[::3, 1], 2.0)
    with np.errstate(over="ignore", invalid="ignore"):
        want = (objfile._unit(c) == n).all(axis=1)
        got = objfile._gives_back(c[:, 0].copy(), c[:, 1].copy(), c[:, 2].copy(), (n[:, 0], n[:, 1], n[:, 2]))
    assert np.array_equal(got, want)
    assert 0.4 < np.count_nonzero(want) / want.shape[0] < 0.9
