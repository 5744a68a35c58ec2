"""h427, review of ad65084 (h425): the FIFOs' peaks (``timing.fifo``) and the rule that names an
``arch.fifo_depth`` that changes no simulated cycle (:func:`tlm.arch.fifo.fifo_depth_alike`).

h425 checked the rule on one pipeline, one image in flight and seven phase shapes. Here it is
tried where it could break: several pipelines under both schedulers, two images in flight (the
Traversal PM preempted while its put waits, the Intersection PM while its FIFO is empty), phases
whose packets are larger than the depth, puts that wait with several packets held. Wherever the
rule says another depth runs alike, the run at that depth is simulated and must be the same in
every cycle, stall, event and frame time. And ``timing.fifo`` grows with the pipelines, not with
the frames or the FIFOs (one a phase a tile a frame), so a long run of many pipelines does not
bloat results.json."""

from __future__ import annotations

import dataclasses
import json
import random

import numpy as np
import pytest

from tlm.arch.fifo import fifo_depth_alike
from tlm.arch.frame_program import FanOut, Stage, Tile
from tlm.arch.model import FrameProgram, JobSpec, PhaseSpec, simulate_program
from tlm.config import config_from_dict

DEPTHS = (8, 64, 1024)
# a phase's shape: (Traversal cycles a packet, Intersection cycles a packet, addresses a packet)
SHAPES = {
    "slow traversal": lambda rng: (rng.randint(5, 8) * 4, rng.randint(1, 3) * 4, rng.randint(1, 40)),
    "large packets": lambda rng: (rng.randint(1, 2) * 4, rng.randint(5, 8) * 4, rng.randint(520, 900)),
    "piling up": lambda rng: (rng.randint(4, 5) * 4, rng.randint(5, 6) * 4, rng.randint(0, 3)),
    "anything": lambda rng: (rng.randint(1, 8) * 4, rng.randint(1, 8) * 4, rng.choice([0, 1, 7, 70, 700, 2000])),
}


def _job(pm, role, norm, entries=None):
    n = len(norm)
    return JobSpec(pm, "test", role, np.asarray(norm, dtype=np.int64), np.zeros(n, np.int64), np.zeros(n, np.int64),
                   np.ones(n, np.int64), None if entries is None else np.asarray(entries, dtype=np.int64))


def _tile(name, rng, pixels):
    phases = []
    for j in range(rng.randint(1, 3)):
        shape = SHAPES[rng.choice(sorted(SHAPES))]
        t, i, e = zip(*(shape(rng) for _ in range(rng.randint(2, 8))), strict=True)
        phases.append(PhaseSpec(f"p{j}.ti", (_job("traversal", 0, t, e), _job("intersection", 1, i, e)),
                                rng.choice([0, 6])))
        if rng.random() < 0.5:
            phases.append(PhaseSpec(f"p{j}.f", (_job("fragment", 1, [rng.randint(1, 6) * 4]),), 0))
    return Tile(name, tuple(phases), pixels, rng.choice([0, 4]))


def _program(rng, pipelines, scheduler, tiles):
    def shared(name):
        return Stage(name, True, (Tile(name, (PhaseSpec(name, (_job("vertex", 0, [4, 8]),), 0),)),))

    return FrameProgram((shared("geometry"),
                         Stage("photons", False, tuple(_tile(f"c{k}", rng, 0) for k in range(tiles)),
                               (FanOut("tree", 8, 0, 0), FanOut("vertices", 6, 0, 1))),
                         shared("photon tree"),
                         Stage("pixels", False, tuple(_tile(f"t{k}", rng, rng.randint(0, 5)) for k in range(tiles)),
                               (FanOut("photon tree", 4, 0, 1),))), {}, pipelines, scheduler)


def _same(a, b) -> bool:
    """Two timings alike in everything but the FIFOs' record (which names the depth)."""
    da, db = a.to_dict(), b.to_dict()
    da.pop("fifo")
    db.pop("fifo")
    return da == db


def _runs(seed):
    rng = random.Random(seed)
    pipelines, scheduler = rng.choice([2, 3, 4]), rng.choice(["static", "dynamic"])
    program = _program(rng, pipelines, scheduler, pipelines * (1 if scheduler == "static" else 2))
    arch = {"pipelines": pipelines, "scheduler": scheduler, "images_in_flight": 2, "frames": 3, "trace": False,
            "context_switch_cycles": rng.choice([0, 4]), "fanout": rng.choice(["broadcast", "serial"])}
    return {d: simulate_program(program, config_from_dict({"arch": {**arch, "fifo_depth": d}}, "h427").arch)
            for d in DEPTHS}


def test_where_the_peaks_say_another_depth_runs_alike_it_does_with_pipelines_and_two_images():
    seen = {"claims": 0, "waited": 0, "shared": 0, "refused": 0, "many": 0}
    for seed in range(24):
        runs = _runs(seed)
        for depth, timing in runs.items():
            peaks = timing.fifo
            seen["many"] += peaks["waited_on_many"] > 0
            for other in DEPTHS:
                if other == depth:
                    continue
                if not fifo_depth_alike(peaks, depth, other):
                    seen["refused"] += 1
                    continue
                assert _same(timing, runs[other]), (seed, depth, other, {k: v for k, v in peaks.items()
                                                                          if k != "pipelines"})
                seen["claims"] += 1
                seen["waited"] += peaks["waited"] > 0
                seen["shared"] += peaks["peak_shared"] > 0
    # the rule was put to the test: it claimed, with puts that waited and puts beside others, and it refused
    assert all(seen.values()), seen


@pytest.mark.parametrize("frames", [2, 6])
def test_timing_fifo_grows_with_the_pipelines_not_the_frames(frames):
    rng = random.Random(7)
    pipelines = 8
    program = _program(rng, pipelines, "static", pipelines)
    arch = config_from_dict({"arch": {"pipelines": pipelines, "frames": frames, "trace": False, "fifo_depth": 64}},
                            "h427").arch
    peaks = simulate_program(program, arch).fifo
    assert len(peaks["pipelines"]) == pipelines and peaks["fifos"] >= frames * pipelines
    assert all(isinstance(v, int | None) for row in peaks["pipelines"] for v in row.values())
    # one row of six numbers a pipeline, whatever the frames and FIFOs: 64 pipelines stay within a few KB
    assert len(json.dumps(peaks)) < 200 + 160 * pipelines


def _linear(t, i, entries, depth):
    n = len(entries)
    program = FrameProgram.linear([PhaseSpec("ti", (_job("traversal", 0, [t] * n, entries),
                                                    _job("intersection", 1, [i] * n, entries)), 0)])
    return program, config_from_dict({"arch": {"frames": 2, "fifo_depth": depth, "trace": False}}, "h427").arch


@pytest.mark.parametrize("t, i, entries, depth, other, alike", [
    (4, 20, [512, 512, 512], 64, 1024, False),  # each put waits for one packet: 1024 addresses fit in 1024
    (4, 20, [513, 512, 513], 64, 1024, True),  # 1025: too many at 1024 as well
    (16, 20, [4, 4], 64, 8, True),  # the second enters beside the first: 8 addresses, within 8
    (16, 20, [4, 5], 64, 8, False),  # 9 addresses: the second put waits at 8
])
def test_the_rule_at_its_edges(t, i, entries, depth, other, alike):
    program, arch = _linear(t, i, entries, depth)
    timing = simulate_program(program, arch)
    assert fifo_depth_alike(timing.fifo, depth, other) is alike
    assert _same(timing, simulate_program(program, dataclasses.replace(arch, fifo_depth=other))) is alike
