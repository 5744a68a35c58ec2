"""Which flow shop the coarse-packet estimate runs (tlm/arch/granularity.py, ``_FlowShops``):
a small estimate's phases take the Python loop, so that a process whose frame came from the
functional cache does not import numba and load the compiled kernel (0.5 to 2.5 s) for the
estimate of a frame that simulates in a tenth of that; past ``FLOW_SHOP_LOOP_PACKETS``
packets, or once the kernel is loaded, the compiled one. The same cycles either way."""

from __future__ import annotations

import sys
import types

import numpy as np

import tlm.arch.granularity as granularity
from tlm.arch.frame_program import FrameProgram, JobSpec, PhaseSpec, Stage, Tile
from tlm.arch.granularity import flow_shop_python, ti_cycles
from tlm.config import config_from_dict

KERNEL = "tlm.kernels._jit_flow"


def _job(pm, cycles, role, entries):
    norm = np.asarray(cycles, dtype=np.int64)
    zeros = np.zeros_like(norm)
    return JobSpec(pm, "test", role, norm, zeros, zeros, np.ones_like(norm), np.asarray(entries, dtype=np.int64))


def test_a_small_estimate_takes_the_python_loop(monkeypatch):
    """Three Traversal/Intersection phases of 30, 50 and 40 packets, one tile each: with the
    kernel not loaded, every phase through the Python loop (the compiled ``flow_shop`` not
    called); with room for 60 packets in the loop, the first phase there and the other two
    compiled; with the kernel loaded, all three compiled. Each tile's cycles the loop's."""
    rng = np.random.default_rng(7)
    arch = config_from_dict({"arch": {"fifo_depth": 6}}, "test").arch
    tiles, want = [], []
    for k, n in enumerate((30, 50, 40)):
        t, i, entries = rng.integers(1, 50, n), rng.integers(1, 50, n), rng.integers(0, 12, n)
        ph = PhaseSpec("x.rays", (_job("traversal", t, 0, entries), _job("intersection", i, 1, entries)), 0)
        tiles.append(Tile(f"tile {k}", (ph,)))
        want.append(flow_shop_python(t, i, entries, arch.fifo_depth))
    program = FrameProgram((Stage("pixels", False, tuple(tiles)),), {})
    calls = []
    monkeypatch.setattr(granularity, "flow_shop", lambda t, *a: calls.append(len(t)) or flow_shop_python(t, *a))
    monkeypatch.delitem(sys.modules, KERNEL, raising=False)
    assert ti_cycles(program, arch) == want and calls == []
    monkeypatch.setattr(granularity, "FLOW_SHOP_LOOP_PACKETS", 60)
    assert ti_cycles(program, arch) == want and calls == [50, 40]
    calls.clear()
    monkeypatch.setattr(granularity, "FLOW_SHOP_LOOP_PACKETS", 1 << 16)
    monkeypatch.setitem(sys.modules, KERNEL, types.ModuleType(KERNEL))  # (loaded: its first call is paid)
    assert ti_cycles(program, arch) == want and calls == [30, 50, 40]
