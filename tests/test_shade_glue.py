"""The shading glue that runs every batch: a light's constants made once (tlm.scenes.model.Light's
cached ``area``, ``areas``, ``normal``, ``axis`` and ``quad``), :func:`tlm.kernels.shade.emitted`
reading them, and :func:`tlm.kernels.shade.hash_uniform` broadcasting its keys straight into the
compiled kernel's rows. Each must give the bits the per-call numpy code gave (the reference
functions below are that code, as it was)."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from tlm.kernels import shade
from tlm.kernels.shade import _GOLD, _mix, emitted, hash_uniform
from tlm.scenes.model import Light, QuadFrame


def _emitted_reference(lights, o, d, t_hit, eps):
    """emitted() as it was: every light's constants recomputed per call, the right-hand sides stacked."""
    k = o.shape[0]
    radiance = np.zeros((k, 3))
    seen = np.zeros(k, dtype=bool)
    best = t_hit.copy()
    for light in lights:
        area = float(np.linalg.norm(np.cross(light.edge_u, light.edge_v)))
        if light.kind != "quad" or area == 0.0:
            continue
        n = np.cross(light.edge_u, light.edge_v)
        nl = n / np.linalg.norm(n)
        dn = d @ nl
        c = np.asarray(light.corner)
        eu, ev = np.asarray(light.edge_u), np.asarray(light.edge_v)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((c - o) @ nl) / dn
        p = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d - c
        g = np.array([[eu @ eu, eu @ ev], [eu @ ev, ev @ ev]])
        a, b = np.linalg.solve(g, np.stack([p @ eu, p @ ev]))
        dist_eps = eps / np.linalg.norm(d, axis=1)
        hit = (dn < 0) & (t > dist_eps) & (t <= best + dist_eps) & (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1)
        radiance[hit] = np.asarray(light.power) / (np.pi * area)
        seen |= hit
        best = np.where(hit, t, best)
    return radiance, seen


def _hash_reference(seed, *keys):
    """hash_uniform()'s numpy code (the reference of the compiled kernel)."""
    arrays = np.broadcast_arrays(*[np.asarray(k, dtype=np.int64) for k in keys])
    h = _mix(np.full(arrays[0].shape, np.uint64(seed & 0xFFFFFFFFFFFFFFFF)) + _GOLD)
    for k in arrays:
        h = _mix(h ^ (k.astype(np.uint64) * _GOLD))
    return (h >> np.uint64(11)).astype(np.float64) * (1.0 / (1 << 53))


def _quad(rng, power=None):
    return Light("quad", tuple(rng.uniform(1, 10, 3)) if power is None else power, corner=tuple(rng.normal(size=3)),
                 edge_u=tuple(rng.normal(size=3)), edge_v=tuple(rng.normal(size=3)))


def _lights(rng, n):
    out = []
    for _ in range(n):
        pick = rng.integers(5)
        if pick == 0:  # a quad of no area (parallel edges): neither seen nor hiding
            out.append(Light("quad", (1.0, 2.0, 3.0), corner=(0.0, 1.0, 0.0), edge_u=(1.0, 0.0, 0.0),
                             edge_v=(2.0, 0.0, 0.0)))
        elif pick == 1:  # integer fields (a scene built in code): integer arrays, as np.asarray made them
            out.append(Light("quad", (5, 6, 7), corner=(0, 1, 0), edge_u=(1, 0, 0), edge_v=(0, 0, 1)))
        elif pick == 2:
            out.append(Light("point", (1.0, 1.0, 1.0), position=tuple(rng.normal(size=3))))
        else:
            out.append(_quad(rng))
    return tuple(out)


@pytest.mark.parametrize("k", [0, 1, 2, 7, 64, 65, 1001, 3073])
def test_emitted_bits_match_the_per_call_code(k):
    """Random rays against random quad, point and zero-area lights, with rays parallel to a light,
    of no length and missing everything (t_hit inf): the same radiance and seen mask, bit for bit,
    and some rays do see a light."""
    rng = np.random.default_rng(k)
    total_seen = 0
    for trial in range(12):
        lights = _lights(rng, trial % 4 + 1)
        o = rng.normal(size=(k, 3)) * 2.0
        d = rng.normal(size=(k, 3))
        if k > 4:
            d[0] = (1.0, 0.0, 0.0)
            d[1] = 0.0
            d[2] = np.asarray(lights[0].edge_u, dtype=np.float64)  # parallel to the first light's plane
        t_hit = rng.uniform(0.0, 5.0, k)
        t_hit[rng.random(k) < 0.2] = np.inf
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # (a ray of no length: eps / 0)
            want = _emitted_reference(lights, o, d, t_hit, 1e-3)
            got = emitted(lights, o, d, t_hit, 1e-3)
        for w, g in zip(want, got, strict=True):
            assert w.dtype == g.dtype and w.shape == g.shape
            assert w.tobytes() == g.tobytes()
        total_seen += int(got[1].sum())
    if k > 60:
        assert total_seen > 0


def test_emitted_nearest_light_wins_and_order_of_lights():
    """Two quads one behind the other: a ray sees the nearer one's radiance whichever comes first."""
    near = Light("quad", (1.0, 1.0, 1.0), corner=(-1.0, 1.0, -1.0), edge_u=(2.0, 0.0, 0.0), edge_v=(0.0, 0.0, 2.0))
    far = Light("quad", (9.0, 9.0, 9.0), corner=(-1.0, 2.0, -1.0), edge_u=(2.0, 0.0, 0.0), edge_v=(0.0, 0.0, 2.0))
    assert near.normal[1] < 0  # emits downwards, towards the ray's origin
    o = np.zeros((1, 3))
    d = np.array([[0.0, 1.0, 0.0]])
    for lights in ((near, far), (far, near)):
        rad, seen = emitted(lights, o, d, np.array([np.inf]), 1e-6)
        assert seen[0]
        np.testing.assert_array_equal(rad[0], np.asarray(near.power) / (np.pi * 4.0))


def test_light_constants_are_made_once(monkeypatch):
    """A quad light's area and normal cost one cross product each however often they are read, and
    emitted() computes none on later calls (it recomputed them per light per call)."""
    rng = np.random.default_rng(3)
    light = _quad(rng)
    calls = []
    cross = np.cross

    def counting(*a, **kw):
        calls.append(1)
        return cross(*a, **kw)

    monkeypatch.setattr(np, "cross", counting)
    first = light.area
    assert light.area == first and light.area == first
    assert len(calls) == 1
    assert light.normal is light.normal
    assert len(calls) == 2
    o, d = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    emitted((light,), o, d, np.full(50, np.inf), 1e-4)
    calls.clear()
    emitted((light,), o, d, np.full(50, np.inf), 1e-4)
    assert calls == []


def test_cached_values_are_read_only_and_per_light():
    """The arrays kept on a light are read-only (no caller can change another's), and a light made
    from it with other values (dataclasses.replace: another scene's, a moved light) has its own."""
    rng = np.random.default_rng(4)
    light = _quad(rng)
    q = light.quad
    assert isinstance(q, QuadFrame)
    for a in (light.normal, *q):
        assert not a.flags.writeable
        with pytest.raises(ValueError):
            a[0] = 1.0
    other = dataclasses.replace(light, edge_u=tuple(2.0 * np.asarray(light.edge_u)), power=(1.0, 2.0, 3.0))
    assert other.area == pytest.approx(2.0 * light.area)
    assert other.quad is not q
    np.testing.assert_array_equal(other.quad.edge_u, 2.0 * q.edge_u)
    np.testing.assert_array_equal(other.quad.radiance, np.asarray((1.0, 2.0, 3.0)) / (np.pi * other.area))
    assert light.area == float(np.linalg.norm(np.cross(light.edge_u, light.edge_v)))  # not the other's
    eu, ev = np.asarray(light.edge_u), np.asarray(light.edge_v)
    np.testing.assert_array_equal(q.gram, [[eu @ eu, eu @ ev], [eu @ ev, ev @ ev]])
    # the tuples given are not frozen by it (np.array copies them)
    arr = np.array([1.0, 0.0, 0.0])
    assert Light("quad", (1.0, 1.0, 1.0), edge_u=arr, edge_v=(0.0, 1.0, 0.0)).quad.edge_u[0] == 1.0
    assert arr.flags.writeable


def test_mesh_light_areas_and_axis_cached():
    tri = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                    [[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [0.0, 2.0, 1.0]]])
    mesh = Light("mesh", (1.0, 1.0, 1.0), ids=np.arange(2), triangles=tri, radiance=np.ones((2, 3)))
    assert mesh.areas is mesh.areas and not mesh.areas.flags.writeable
    np.testing.assert_array_equal(mesh.areas, [0.5, 2.0])
    assert mesh.area == 2.5
    spot = Light("spot", (1.0, 1.0, 1.0), direction=(0.0, -2.0, 0.0), inner_angle=10.0, outer_angle=20.0)
    assert spot.axis is spot.axis and not spot.axis.flags.writeable
    np.testing.assert_array_equal(spot.axis, [0.0, -1.0, 0.0])
    flat = Light("directional", (0.0, 0.0, 0.0), direction=(0.0, 0.0, 0.0))
    for _ in range(2):  # the error is raised on every read (nothing kept)
        with pytest.raises(ValueError, match=r"has no length"):
            _ = flat.axis


CASES = [
    lambda keys, s: (keys[:, None], 1, 3, s[None, :], 0),
    lambda keys, s: (keys, 7, -1, 3),
    lambda keys, s: (keys[:, None], s[None, :]),
    lambda keys, s: (5, keys, np.uint64(3)),
    lambda keys, s: (keys.reshape(-1, 1, 1), s.reshape(1, -1, 1), np.arange(2)),
    lambda keys, s: (keys.astype(np.int32), 1),
    lambda keys, s: (s[::-1][None, :], keys[::2, None]),  # strided views
]


@pytest.mark.parametrize("k", [0, 1, 3, 16, 63, 64, 65, 500])
@pytest.mark.parametrize("case", range(len(CASES)))
def test_hash_uniform_bits(k, case):
    """The compiled path (keys broadcast straight into its rows) gives the numpy code's numbers and
    shape, for broadcast keys of every layout, scalars, negative keys and empty arrays."""
    rng = np.random.default_rng(100 * k + case)
    keys = rng.integers(-2**62, 2**62, k)
    s = np.arange(int(rng.choice([1, 4, 9, 16])))
    args = CASES[case](keys, s)
    want = _hash_reference(12345, *args)
    got = hash_uniform(12345, *args)
    assert got.shape == want.shape
    assert got.tobytes() == want.tobytes()


def test_hash_uniform_takes_the_compiled_path(monkeypatch):
    """Many numbers go to the compiled kernel (so the test above compares it, not the numpy code twice)."""
    pytest.importorskip("numba")
    from tlm.kernels import _jit_hash

    monkeypatch.delenv("TLM_KERNELS", raising=False)
    seen = []
    real = _jit_hash.hash_uniform

    def spy(seed, stacked):
        seen.append(stacked.shape)
        return real(seed, stacked)

    monkeypatch.setattr(_jit_hash, "hash_uniform", spy)
    keys = np.arange(40)
    out = hash_uniform(9, keys[:, None], 2, np.arange(4)[None, :])
    assert seen == [(3, 160)]
    assert out.shape == (40, 4)
    assert out.tobytes() == _hash_reference(9, keys[:, None], 2, np.arange(4)[None, :]).tobytes()
    assert shade.HASH_MIN_COMPILED <= 160
