"""The numpy reference walk lives in :mod:`tlm.kernels.traverse_numpy` and the recording of
a kernel's reads in :mod:`tlm.kernels.recording`: the traversal's numpy engine reads its
leaf tests from there (so a test that patches them there patches the walk), and a packet
recorded on cold pairs settles on the carried :class:`~tlm.kernels.memory.Streams`."""

from __future__ import annotations

import numpy as np
import pytest

from tlm.kernels import traverse, traverse_numpy
from tlm.kernels.memory import Streams
from tlm.kernels.recording import Deferred, traversal_accesses
from tlm.kernels.traverse import any_hit, build_accel, closest_hit


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(11)
    centres = rng.uniform(-1.0, 1.0, (60, 1, 3))
    accel = build_accel(centres + rng.normal(scale=0.15, size=(60, 3, 3)))
    o = rng.uniform(-2.0, 2.0, (200, 3))
    d = rng.uniform(-0.8, 0.8, (200, 3)) - o
    return accel, o, d


def blind(real):
    """``real`` (a leaf test) made to find nothing."""

    def test(*args):
        slot, t = real(*args)
        return np.full_like(slot, -1), np.full_like(t, np.inf)

    return test


@pytest.mark.parametrize("first_only", [False, True])
def test_the_numpy_walk_tests_leaves_with_traverse_numpy_s_tests(scene, monkeypatch, first_only):
    """Patched in traverse_numpy, the float32 test finds nothing, so every ray visits every
    leaf it crosses; with the float64 fallback made to run (every check fails) and its
    test patched too, the hits found in float32 are gone again."""
    monkeypatch.setenv("TLM_KERNELS", "numpy")
    accel, o, d = scene
    fn = any_hit if first_only else closest_hit
    plain = fn(accel, o, d)
    found = plain.occluded if first_only else plain.triangle >= 0
    assert 20 < int(found.sum()) < o.shape[0]
    assert np.any(plain.counts.leaf_visits < plain.counts.leaves_crossed)

    monkeypatch.setattr(traverse_numpy, "closest_slots", blind(traverse_numpy.closest_slots))
    res = fn(accel, o, d, record=True)
    np.testing.assert_array_equal(res.counts.leaf_visits, res.counts.leaves_crossed)
    assert not np.any(res.occluded if first_only else res.triangle >= 0)
    np.testing.assert_array_equal(res.counts.node_visits, plain.counts.node_visits)

    monkeypatch.undo()
    monkeypatch.setenv("TLM_KERNELS", "numpy")
    real_check = traverse.check

    def failing(*args):
        t, u, v, ok = real_check(*args)
        return t, u, v, np.zeros_like(ok)

    monkeypatch.setattr(traverse, "check", failing)
    monkeypatch.setattr(traverse_numpy, "closest_slots64", blind(traverse_numpy.closest_slots64))
    res = fn(accel, o, d)
    assert not np.any(res.occluded if first_only else res.triangle >= 0)
    np.testing.assert_array_equal(res.counts.leaf_visits[found], res.counts.leaves_crossed[found])


def test_a_deferred_packet_settles_on_the_carried_streams(scene, monkeypatch):
    """Two packets' traversal reads: the second charged on cold :class:`Deferred` pairs and
    settled on the carried Streams gives the misses and state of the two charged in order."""
    monkeypatch.setenv("TLM_KERNELS", "numpy")
    accel, o, d = scene
    packets = [closest_hit(accel, o[s], d[s], record=True).touched for s in (slice(0, 100), slice(100, 200))]
    reads = [traversal_accesses(t, accel.leaf_first, accel.leaf_last, 64) for t in packets]

    in_order, want = Streams(64, 1), []
    for r in reads:
        want.append({name: in_order.charge(name, acc, 100) for name, acc in r.items()})

    carried = Streams(64, 1)
    got0 = {name: carried.charge(name, acc, 100) for name, acc in reads[0].items()}
    later = Deferred.like(carried)
    got1 = {name: np.zeros(100, dtype=np.int64) for name in reads[1]}
    for name, acc in reads[1].items():
        later.charge(name, acc, 100, into=got1[name])
    carried.settle(later)
    for name in want[0]:
        np.testing.assert_array_equal(got0[name], want[0][name])
        np.testing.assert_array_equal(got1[name], want[1][name])
    assert carried.states == in_order.states
    assert sum(int(v.sum()) for v in want[1].values()) > 0
