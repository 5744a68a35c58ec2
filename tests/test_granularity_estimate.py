"""The packets' estimated effect on TThru (tlm.arch.model.granularity_estimate, results.json
``timing.granularity``) against what packets of one measure: each Traversal/Intersection
phase a two-machine flow shop through the FIFO (tlm.arch.model.flow_shop), in the frame's
packets and in packets of one, and the warning of tlm.experiments.run_warnings.stream_warnings
on it (docs/architecture.md, "Packet size")."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import tlm
import tlm.arch.frame_program as frame_programs
import tlm.arch.granularity as granularity
import tlm.arch.model as model
from tlm.arch.costs import load_programs
from tlm.arch.frame_program import FrameProgram, JobSpec, PhaseSpec, Stage, Tile, split, ti_phases
from tlm.arch.granularity import fine_ti_cycles, flow_shop, flow_shop_python, ti_cycles
from tlm.arch.model import frame_program, simulate_program
from tlm.config import config_from_dict
from tlm.experiments.run_warnings import GRANULARITY_WARNING, stream_warnings


def _job(pm, cycles, role, entries):
    norm = np.asarray(cycles, dtype=np.int64)
    zeros = np.zeros_like(norm)
    return JobSpec(pm, "test", role, norm, zeros, zeros, np.ones_like(norm), np.asarray(entries, dtype=np.int64))


def _ti(t, i, entries):
    """One tiled stage of one tile: a Traversal/Intersection phase of packets costing t and i."""
    ph = PhaseSpec("x.rays", (_job("traversal", t, 0, entries), _job("intersection", i, 1, entries)), 0)
    return FrameProgram((Stage("pixels", False, (Tile("tile 0", (ph,)),)),), {})


@pytest.mark.parametrize("kernels", ["numba", "numpy"])
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("depth", [3, 40])
def test_the_flow_shop_is_the_simulated_phase_with_one_image(seed, depth, kernels, monkeypatch):
    """Packets of random cycles and FIFO entries (some more than the FIFO holds, some
    none): with one image in flight the simulated phase takes exactly the flow shop's
    cycles, the FIFO full or empty as it may be; compiled (tlm/kernels/_jit_flow.py) and
    with ``TLM_KERNELS=numpy`` (the Python loop)."""
    monkeypatch.setenv("TLM_KERNELS", kernels)
    rng = np.random.default_rng(seed)
    n = 60
    t, i = rng.integers(1, 50, n), rng.integers(1, 50, n)
    entries = rng.integers(0, 2 * depth, n)
    arch = config_from_dict({"arch": {"frames": 1, "images_in_flight": 1, "trace": False, "fifo_depth": depth}},
                            "test").arch
    timing = simulate_program(_ti(t, i, entries), arch)
    assert timing.units["pipe0.traversal"]["stall"].get("fifo_full", 0) > 0  # (the FIFO did fill)
    assert flow_shop(t, i, entries, depth) == timing.cycles["throughput"]
    # an ample FIFO: the flow shop of the packets alone, max over k of t_1..t_k + i_k..i_n
    deep = flow_shop(t, i, entries, 10**9)
    assert deep == int((np.cumsum(t) + np.cumsum(i[::-1])[::-1]).max()) <= flow_shop(t, i, entries, depth)


def test_flow_shop_edges(monkeypatch):
    """No packets: no cycles; no entries given: one entry each; the Python loop's packets
    taken a few at a time (the chunks a phase of millions of pixels is cut into) give the
    same cycles; arrays of different lengths are refused."""
    empty = np.zeros(0, dtype=np.int64)
    for fs in (flow_shop, flow_shop_python):
        assert fs(empty, empty, empty, 8) == 0
        assert fs(np.array([5, 5]), np.array([7, 7]), None, 1) == 5 + 7 + 7
    rng = np.random.default_rng(3)
    t, i, entries = rng.integers(1, 50, 500), rng.integers(1, 50, 500), rng.integers(0, 30, 500)
    whole = {depth: flow_shop_python(t, i, entries, depth) for depth in (1, 4, 40, 10**6)}
    monkeypatch.setattr(granularity, "FLOW_SHOP_CHUNK", 7)
    assert {depth: flow_shop_python(t, i, entries, depth) for depth in whole} == whole
    with pytest.raises(ValueError, match=r"3 packets' traversal cycles, 2 intersection cycles"):
        flow_shop(t[:3], i[:2], None, 4)
    with pytest.raises(ValueError, match=r", 4 entries"):
        flow_shop(t[:3], i[:3], entries[:4], 4)


@pytest.mark.parametrize("depth", [1, 2, 3, 16, 40, 10**9])
def test_the_compiled_flow_shop_is_the_python_loop(depth, monkeypatch):
    """tlm/kernels/_jit_flow.py's flow shop gives the Python loop's cycles (the reference,
    ``TLM_KERNELS=numpy``) on random phases: FIFO entries none, 0, within and beyond the
    FIFO's depth, costs from 0 to large, phases shorter and longer than the FIFO, and
    numpy's other integer types; ``TLM_KERNELS=numpy`` runs the loop, not the kernel."""
    from tlm.kernels import _jit_flow

    monkeypatch.setenv("TLM_KERNELS", "numba")  # (whatever the suite runs with)
    rng = np.random.default_rng(depth)
    for n in (1, 2, 5, 37, 1000):
        for top in (3, 2 * depth + 2):
            t = rng.integers(0, 10**6, n)
            i = rng.integers(0, 10**6, n) if n % 2 else rng.integers(0, 9, n)
            entries = rng.integers(0, min(top, 10**6), n)
            for e in (entries, None, entries.astype(np.int32)):
                want = flow_shop_python(t, i, e, depth)
                got = flow_shop(t.astype(np.int32) if e is None else t, i, e, depth)
                assert type(got) is int and got == want, (n, top, e is None)
    calls = []
    monkeypatch.setattr(_jit_flow, "flow_shop", lambda *a: calls.append(a) or 0)
    assert flow_shop(t, i, entries, depth) == 0 and len(calls) == 1
    monkeypatch.setenv("TLM_KERNELS", "numpy")
    assert flow_shop(t, i, entries, depth) == flow_shop_python(t, i, entries, depth) > 0 and len(calls) == 1


@pytest.fixture(scope="module")
def cornell_rcast_48(tmp_path_factory):
    """``configs/cornell.yaml --mode rcast --set resolution=[48,48]``'s frame (spp 4, 4 light samples)."""
    mp = pytest.MonkeyPatch()
    mp.setenv("TLM_CACHE", str(tmp_path_factory.mktemp("cache")))
    try:
        yield tlm.render_image(tlm.load_config({"scene": "cornell", "mode": "rcast", "resolution": [48, 48],
                                                "arch": {"trace": False}}))
    finally:
        mp.undo()


def _packet_lines(timing, res, **arch):
    cfg = replace(res.cfg, arch=replace(res.cfg.arch, **arch))
    return [w for w in stream_warnings(timing, cfg) if w.startswith("arch.packet_size")]


def test_with_one_image_the_estimate_is_the_measured_change(cornell_rcast_48):
    """Cornell RCast at 48x48, one image in flight: the Traversal/Intersection phases'
    flow shops in the frame's packets minus in packets of one are the change in TThru
    that simulating packets of one measures, to the cycle, either way: packets of 64 are
    faster (the FIFO: a whole packet enters at once), packets of 256 about as fast."""
    one = {"images_in_flight": 1, "frames": 1}
    fine = tlm.simulate(cornell_rcast_48, {**one, "packet_size": 1})
    assert fine.granularity["change_cycles"] == 0 and fine.granularity["share"] == 0.0
    shares = {}
    for size in (64, 256):
        t = tlm.simulate(cornell_rcast_48, {**one, "packet_size": size})
        change = t.cycles["throughput"] - fine.cycles["throughput"]
        assert t.granularity["change_cycles"] == change
        assert t.granularity["share"] == round(min(change, t.granularity["over_slowest_pm"]) / t.cycles["throughput"],
                                               4)
        shares[size] = t.granularity["share"]
        lines = _packet_lines(t, cornell_rcast_48, **one, packet_size=size)
        assert len(lines) == (abs(shares[size]) >= GRANULARITY_WARNING)
    assert shares[64] <= -GRANULARITY_WARNING and abs(shares[256]) < 0.02


def test_no_false_alarm_where_packets_barely_move_the_cycles(cornell_rcast_48):
    """Two images in flight, the default stream: packets of 256 move TThru by 0.6% against
    packets of one, which the hand-overs alone put at 9.9% (the warning said so); packets of
    64 move it by -6.1% (they were below the threshold at 2.4%). The run warns of the second only."""
    coarse = tlm.simulate(cornell_rcast_48)
    fine = tlm.simulate(cornell_rcast_48, {"packet_size": 1})
    assert abs(coarse.cycles["throughput"] / fine.cycles["throughput"] - 1) < 0.02
    assert _packet_lines(coarse, cornell_rcast_48) == []
    mid = tlm.simulate(cornell_rcast_48, {"packet_size": 64})
    assert mid.cycles["throughput"] / fine.cycles["throughput"] - 1 < -0.05
    (line,) = _packet_lines(mid, cornell_rcast_48, packet_size=64)
    assert line.startswith("arch.packet_size = 64 is coarse for this frame: with 2 images in flight whole packets can "
                           "move cycles.throughput by about 6% either way") and "'tlm granularity'" in line
    assert "share -6.4% is each Traversal/Intersection phase alone, where packets of one ray would take that much " \
        "more" in line


@pytest.fixture(scope="module")
def cornell_pmap_16(tmp_path_factory):
    """A Cornell PMap frame at 16x16 (spp 1, 400 photons): photon tiles as well as pixel tiles."""
    mp = pytest.MonkeyPatch()
    mp.setenv("TLM_CACHE", str(tmp_path_factory.mktemp("cache")))
    try:
        yield tlm.render_image(tlm.load_config({"scene": "cornell", "mode": "pmap", "resolution": [16, 16],
                                                "render": {"spp": 1}, "photons": {"count": 400},
                                                "arch": {"trace": False}}))
    finally:
        mp.undo()


@pytest.mark.parametrize("arch", [{}, {"pipelines": 2}, {"pipelines": 3, "scheduler": "dynamic", "packet_size": 16},
                                  {"fifo_depth": 3, "memory": "copy"}])
@pytest.mark.parametrize("frame", ["cornell_rcast_48", "cornell_pmap_16"])
def test_the_fine_phases_are_the_program_in_packets_of_one(frame, arch, request):
    """fine_ti_cycles (what simulate's estimate reads of packets of one): per tile, the
    flow shops of the Traversal/Intersection phases of the whole frame program in packets
    of one, to the cycle, without building that program: ti_phases builds the same phases
    (names, per-ray costs, entries), tile by tile, and no other phase."""
    res = request.getfixturevalue(frame)
    programs = load_programs()
    cfg = res.cfg
    a = replace(cfg.arch, **arch)
    fn = res.functional()
    whole = frame_program(fn, programs, replace(a, packet_size=1))
    tiled = [tile for stage in whole.stages if not stage.shared for tile in stage.tiles]
    built = []
    real_f = frame_programs._Builder.f

    def f(self, *args):
        built.append(args[0])
        return real_f(self, *args)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(frame_programs._Builder, "f", f)
        lazy = [list(phases) for phases in ti_phases(fn, programs, replace(a, packet_size=1))]
        fine = fine_ti_cycles(fn, programs, a)
    assert built == []  # (no Fragment phase)
    assert len(lazy) == len(tiled) and any(lazy)
    for tile, phases in zip(tiled, lazy, strict=True):
        want = [ph for ph in tile.phases if len(ph.jobs) == 2]
        assert [ph.name for ph in phases] == [ph.name for ph in want]
        for got, ph in zip(phases, want, strict=True):
            for gj, wj in zip(got.jobs, ph.jobs, strict=True):
                for key in ("norm", "misses", "flushes", "items", "entries"):
                    assert np.array_equal(getattr(gj, key), getattr(wj, key)), (ph.name, key)
    assert fine == ti_cycles(whole, a)
    if frame == "cornell_pmap_16":
        assert any(ph.name == "photons.trace" for phases in lazy for ph in phases)


def test_simulate_builds_one_frame_program(cornell_rcast_48, monkeypatch):
    """simulate builds the frame program at the run's packet size only (packets of one:
    their Traversal/Intersection phases alone, one at a time) and gives the estimate the
    whole program in packets of one gives."""
    calls = []
    real = model.frame_program

    def counted(fn, programs, arch):
        calls.append(arch.packet_size)
        return real(fn, programs, arch)

    monkeypatch.setattr(model, "frame_program", counted)
    fn, programs = cornell_rcast_48.functional(), load_programs()
    arch = replace(cornell_rcast_48.cfg.arch, frames=1, images_in_flight=1)
    timing = model.simulate(fn, programs, arch)
    assert calls == [arch.packet_size]
    fine = real(fn, programs, replace(arch, packet_size=1))
    slowest = timing.cycles[timing.throughput_estimate["slowest_pm"]]
    assert timing.granularity == model.granularity_estimate(timing.program, arch, timing.cycles["throughput"],
                                                            slowest, fine)


def test_packets_of_one_are_the_items():
    """split and the builder's lazy sums in packets of one: each item's own value, int64,
    as the per-packet sums (reduceat) give them, and no view of the caller's array."""
    rng = np.random.default_rng(5)
    work = {"a": rng.integers(0, 100, (4, 5)).astype(np.int32), "b": rng.integers(0, 7, 20)}
    p = split("x", work, 1)
    for k, v in work.items():
        assert p.counts[k].dtype == np.int64
        assert np.array_equal(p.counts[k], np.add.reduceat(v.reshape(-1).astype(np.int64), np.arange(20)))
    p.counts["b"][0] += 1000
    assert work["b"][0] < 1000
    assert np.array_equal(p.sizes, np.ones(20, dtype=np.int64)) and p.sizes.dtype == np.int64
    idx = np.array([3, 1, 7, 7, 19], dtype=np.int64)
    sums = frame_programs._PacketSums({k: v.reshape(-1) for k, v in work.items()}, idx, 1, np.arange(5))
    assert np.array_equal(sums.get("a"), work["a"].reshape(-1)[idx]) and sums.get("a").dtype == np.int64
    assert sums.get("nothing", 5) == 5


def test_fine_cycles_for_other_tiles_are_refused():
    """granularity_estimate given packets-of-one cycles of another number of tiles than the
    program's: refused, naming both, rather than compared tile against the wrong tile."""
    program = _ti([5, 5], [7, 7], [1, 1])
    arch = config_from_dict({"arch": {"trace": False}}, "test").arch
    assert model.granularity_estimate(program, arch, 100, 50, [19])["change_cycles"] == 0  # (5 + 7 + 7: its flow shop)
    with pytest.raises(ValueError, match=r"2 tiles' cycles in packets of one for the program's 1 tiles"):
        model.granularity_estimate(program, arch, 100, 50, [19, 0])
