"""h349: what arch.fifo_depth's run warning claims.

``arch.fifo_depth`` "has no effect in this run" was said where every coarse packet enters the FIFO alone, while
the packets-of-one estimate (timing.granularity, past packets of one) reads the depth.
"""

from __future__ import annotations

import dataclasses

import tlm
from tlm.experiments.run_warnings import stream_warnings, timing_inert


def _sim(res, **arch):
    return tlm.simulate(res, {"trace": False, **arch})


def test_fifo_depth_is_not_called_inert_where_the_estimate_reads_it():
    """Cornell refract 24x24, one image, packets of 64: at depth 1 every coarse packet enters the FIFO alone
    (the run's cycles as at 1024), but the packets-of-one estimate reads the depth: share 0.0417 against
    0.059, and no 'has no effect' line."""
    cfg = tlm.load_config("cornell", {"mode": "refract", "resolution": [24, 24], "render.spp": 1,
                                      "render.light_samples": 1})
    res = tlm.render_image(cfg)
    cfg = res.cfg  # (the run config: tlm.load_config's wraps it)
    arch = {"images_in_flight": 1, "packet_size": 64}
    shallow, deep = (_sim(res, fifo_depth=depth, **arch) for depth in (1, 1024))
    assert shallow.cycles["throughput"] == deep.cycles["throughput"]
    assert shallow.granularity["share"] != deep.granularity["share"]
    a = dataclasses.replace(cfg.arch, fifo_depth=1, trace=False, **arch)
    assert "arch.fifo_depth" not in timing_inert(shallow, a)
    assert not any("arch.fifo_depth" in line for line in
                   stream_warnings(shallow, dataclasses.replace(cfg, arch=a)))
    # a frame whose phases' rays fit in 1024 entries together, each taking one at least: inert, estimate too
    small = tlm.render_image(tlm.load_config("cornell", {"mode": "rcast", "resolution": [2, 2], "render.spp": 1,
                                                         "render.light_samples": 1}))
    wide, default = (_sim(small, fifo_depth=depth, **arch) for depth in (4096, 1024))
    assert "never fills" in timing_inert(wide, dataclasses.replace(a, fifo_depth=4096))["arch.fifo_depth"]
    assert (wide.cycles, wide.granularity) == (default.cycles, default.granularity)
