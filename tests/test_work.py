"""The seam: a run's work cut into packets equals the kernels run on those packets."""

from __future__ import annotations

import numpy as np
import pytest

from tlm.arch.frame_program import split
from tlm.config import config_from_dict
from tlm.experiments.run import render
from tlm.kernels.memory import Streams
from tlm.render.frame import cast
from tlm.render.passes import reflect_pass
from tlm.render.pmap import pmap_pass


@pytest.fixture(scope="module")
def result():
    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "resolution": [24, 20],
                            "photons": {"count": 3000}, "estimate": {"final_gather": 0}})  # the four frames
    return render(cfg)


def test_packets_sum_to_the_frame_for_every_size(result):
    assert result.plan.run_names == ["rcast", "reflect", "refract", "pmap"]
    for size in (1, 7, 64, 480, 10_000):
        for name in result.plan.run_names:
            p = split(name, result.work[name], size)
            assert p.name == name and p.packet_size == size
            assert p.sizes.sum() == 24 * 20 and p.n == -(-480 // size)
            assert set(p.counts) == set(result.work[name])
            for k, v in p.counts.items():
                assert v.dtype == np.int64 and v.sum() == result.work[name][k].sum()
        traced = split("photons", result.photons.work, size)
        assert traced.sizes.sum() == 3000
        assert traced.counts["photons_emitted"].sum() == 3000


def test_a_packet_equals_the_kernels_run_on_it(result):
    """The seam's promise: packet k's counts are what the pass computes for its pixels, the
    packets run in order with the cache pairs' state carried (page misses depend on the
    accesses before)."""
    frame = result.frame
    reflect = split("reflect", result.work["reflect"], 64)
    pm = split("pmap", result.work["pmap"], 64)
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


@pytest.mark.parametrize("bad", [0, -3, 1.5, True])
def test_bad_packet_size(bad):
    with pytest.raises(ValueError, match="packet_size"):
        split("x", {"a": np.ones(4, np.int64)}, bad)


def test_empty_and_ragged():
    p = split("x", {"a": np.zeros(0, np.int64)}, 8)
    assert p.n == 0 and p.counts["a"].shape == (0,) and p.counts["a"].dtype == np.int64
    with pytest.raises(ValueError, match="differ in length"):
        split("x", {"a": np.ones(4), "b": np.ones(5)}, 2)
