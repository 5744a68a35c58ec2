"""The seam: a run's work cut into packets equals the kernels run on those packets."""

from __future__ import annotations

import numpy as np
import pytest

from tlm.arch.work import frame_work, split, tree_work
from tlm.config import config_from_dict
from tlm.experiments.run import render
from tlm.kernels.memory import Streams
from tlm.render.passes import cast, pmap_pass, reflect_pass


@pytest.fixture(scope="module")
def result():
    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "resolution": [24, 20],
                            "photons": {"count": 3000}, "estimate": {"final_gather": 0}})  # the four frames
    return render(cfg)


def test_packets_sum_to_the_frame_for_every_size(result):
    for size in (1, 7, 64, 480, 10_000):
        fw = frame_work(result, size)
        assert [p.name for p in fw.passes] == ["rcast", "reflect", "refract", "pmap"]
        for p in fw.passes:
            assert p.sizes.sum() == 24 * 20 and p.n == -(-480 // size)
            for k, v in p.counts.items():
                assert v.dtype == np.int64 and v.sum() == result.work[p.name][k].sum()
        assert fw.photon_trace.sizes.sum() == 3000
        assert fw.photon_trace.totals()["photons_emitted"] == 3000


def test_a_packet_equals_the_kernels_run_on_it(result):
    """The seam's promise: packet k's counts are what the pass computes for its pixels, the
    packets run in order with the cache pairs' state carried (page misses depend on the
    accesses before)."""
    fw = frame_work(result, 64)
    frame = result.frame
    reflect = next(p for p in fw.passes if p.name == "reflect")
    pm = next(p for p in fw.passes if p.name == "pmap")
    assert reflect.counts["trav_misses"].sum() > 0 and pm.counts["gather_misses"].sum() > 0
    streams = {"reflect": Streams(), "pmap": Streams()}
    cold = 0
    for k in range(8):  # 7 is the short last packet (480 = 7 * 64 + 32)
        pixels = np.arange(64 * k, min(64 * (k + 1), 480))
        g = cast(frame, pixels)
        _, work = reflect_pass(frame, g, streams["reflect"])
        for key, v in work.items():
            assert reflect.counts[key][k] == v.sum(), key
        _, gather = pmap_pass(frame, g, result.photons.photons, streams=streams["pmap"])
        for key, v in gather.items():
            assert pm.counts[key][k] == v.sum(), key
        _, alone = pmap_pass(frame, g, result.photons.photons)  # cold pairs
        cold += alone["gather_misses"].sum()
    assert cold > pm.counts["gather_misses"].sum()  # without the carried state it differs


def test_tree_work_matches_algorithm_1(result):
    w = tree_work(result.accel.tree)
    t = result.accel.tree
    assert w["levels"] == t.levels == 7 and w["elements"] == 2604 and w["nodes"] == 2**8 - 1
    assert w["storage_reads"] == 2 * w["com_reads"]
    assert w["writes"] - w["com_reads"] == w["expansion_copies"] >= 0
    fw = frame_work(result, 100)
    assert fw.geometry == w and fw.photon_tree["elements"] == result.photons.photons.n


@pytest.mark.parametrize("bad", [0, -3, 1.5, True])
def test_bad_packet_size(bad):
    with pytest.raises(ValueError, match="packet_size"):
        split("x", {"a": np.ones(4, np.int64)}, bad)


def test_empty_and_ragged():
    p = split("x", {"a": np.zeros(0, np.int64)}, 8)
    assert p.n == 0 and p.totals() == {"a": 0}
    with pytest.raises(ValueError, match="differ in length"):
        split("x", {"a": np.ones(4), "b": np.ones(5)}, 2)
