"""How far the packet size moves TThru from packets of one ray, pixel or photon: the
estimate behind results.json ``timing.granularity`` and ``tlm run``'s coarse-packet
warning (docs/architecture.md, "Packet size").

Each Traversal/Intersection phase is a two-machine flow shop through the FIFO
(:func:`flow_shop`), at the run's packets and at packets of one (:func:`fine_ti_cycles`,
built phase by phase); :func:`fill_and_drain` is the packets' hand-overs at the phase
boundaries alone. Computed from the frame program, without simulating packets of one;
:func:`tlm.arch.model.simulate` calls :func:`granularity_estimate` after its run. A small
frame's phases take the Python loop rather than the compiled flow shop, whose first call
in a process costs more than the whole simulation of such a frame (:class:`_FlowShops`).
"""

from __future__ import annotations

import sys
from dataclasses import replace
from fractions import Fraction

import numpy as np

from tlm.arch.costs import Programs
from tlm.arch.frame_program import FrameProgram, PhaseSpec, ti_phases
from tlm.arch.functional import Functional
from tlm.arch.units import INT64_MAX, within_int64
from tlm.config import ArchConfig
from tlm.kernels.engine import engine
from tlm.registry import SCHEDULERS


def _ti_costs(ph: PhaseSpec, arch: ArchConfig) -> tuple[np.ndarray, np.ndarray] | None:
    """A Traversal/Intersection phase's cycles per packet on each of its two PMs
    (instructions, page misses and flushes: what each packet keeps the PM busy), or None
    for any other phase (and one without packets)."""
    if len(ph.jobs) != 2 or not ph.jobs[0].n:
        return None
    page, flush = arch.page_miss_cycles, arch.flush_cycles
    # both PMs' cycles of the whole phase, exact (Python ints), within int64: no packet's cycles, sum (np.cumsum)
    # or flow-shop time can wrap then
    within_int64(sum(int(js.norm.sum()) + int(js.misses.sum()) * page + int(js.flushes.sum()) * flush
                     for js in ph.jobs), "a Traversal/Intersection phase's packets")
    t, i = (js.norm.astype(np.int64) + js.misses.astype(np.int64) * page + js.flushes.astype(np.int64) * flush
            for js in ph.jobs)
    return t, i


def _per_tile(program: FrameProgram, phase_cycles) -> list[int]:
    """Per tile of the tiled stages, in program order: ``phase_cycles(phase)`` summed over
    its phases (None counts nothing)."""
    return [sum(c for ph in tile.phases if (c := phase_cycles(ph)) is not None)
            for stage in program.stages if not stage.shared for tile in stage.tiles]


def _busiest(per_tile: list[int], program: FrameProgram) -> int:
    """Per-tile cycles as a frame has them: summed over the tiles of the pipeline that has
    most (a pinned scheduler's tile p runs on one pipeline, as the static one's); the
    dynamic scheduler's tiles go where a pipeline is free, so the mean over the pipelines."""
    if not per_tile:
        return 0
    if SCHEDULERS[program.scheduler].pinned and len(per_tile) % program.pipelines == 0:
        n = program.pipelines  # (every tiled stage has one tile per pipeline, in pipeline order)
        return max(sum(per_tile[p::n]) for p in range(n))
    return round(Fraction(sum(per_tile), program.pipelines))


def fill_and_drain(program: FrameProgram, arch: ArchConfig) -> list[int]:
    """Per tile of the tiled stages, in program order: the cycles its packets add to its
    Traversal/Intersection phases over what the same work would take in packets of one.

    A phase starts when the previous phase of its frame is done, so within a T/I phase
    the Intersection PM waits for the Traversal PM's first packet (the fill) and the
    Traversal PM has nothing left while the Intersection PM tests the last one (the
    drain). With packet k costing t_k on the Traversal PM and i_k on the Intersection PM
    (instructions, misses and flushes), the phase takes at least max over k of
    (t_1 + .. + t_k) + (i_k + .. + i_n) (a two-machine flow shop), while its work in
    packets of one takes at least max over the packet boundaries j = 0 .. n of
    (t_1 + .. + t_j) + (i_{j+1} + .. + i_n): the difference, at most the phase's largest
    i_k, summed over the tile's phases, is the tile's share. It is the packets' cost of whole hand-overs alone,
    not the imbalance of the two PMs within a phase (which packets of one have as well),
    computed from the program without a simulation; the FIFO's depth and the other image
    in flight are not in it (docs/architecture.md, "Packet size").
    """
    def extra(ph: PhaseSpec) -> int | None:
        costs = _ti_costs(ph, arch)
        if costs is None:
            return None
        t, i = costs
        done_t = np.cumsum(t)  # t_1 + .. + t_k
        left_i = np.cumsum(i[::-1])[::-1]  # i_k + .. + i_n
        packets = int((done_t + left_i).max())
        ones = max(int(done_t[-1]), int(left_i[0]), int((done_t[:-1] + left_i[1:]).max()) if t.size > 1 else 0)
        return packets - ones

    return _per_tile(program, extra)


FLOW_SHOP_CHUNK = 1 << 16  # packets whose cycles the Python flow_shop holds as Python ints at a time


def flow_shop(t: np.ndarray, i: np.ndarray, entries: np.ndarray | None, depth: int) -> int:
    """The cycles one Traversal/Intersection phase takes alone, from its start to its last
    packet tested: packet k costs ``t[k]`` on the Traversal PM and ``i[k]`` on the
    Intersection PM and takes ``max(1, min(entries[k], depth))`` entries of the FIFO
    (:meth:`tlm.arch.fifo.Fifo.slots`; one each without ``entries``).

    The model's rules, packet by packet: the Traversal PM works packet k once it has put
    packet k - 1 into the FIFO, and puts it in once its entries fit (once the packets
    before the first one that leaves room have been tested: they free their entries in
    order); the Intersection PM tests packet k once it is in the FIFO and packet k - 1 is
    tested. With one image in flight this is the simulated phase's length exactly (no
    other job shares the two PMs); with two, the other image's jobs fill some of its
    waits. Compiled (:func:`tlm.kernels._jit_flow.flow_shop`) unless ``TLM_KERNELS=numpy``,
    which runs :func:`flow_shop_python`, the reference: the same cycles either way.
    """
    n = int(t.shape[0])
    if int(i.shape[0]) != n or (entries is not None and int(np.shape(entries)[0]) != n):
        raise ValueError(f"flow_shop: {n} packets' traversal cycles, {int(i.shape[0])} intersection cycles"
                         + ("" if entries is None else f", {int(np.shape(entries)[0])} entries"))
    if n == 0:
        return 0
    depth = min(int(depth), INT64_MAX >> 1)  # (as deep as any: past every entry; ends - depth stays in int64)
    if engine() != "numba":
        return flow_shop_python(t, i, entries, depth)
    from tlm.kernels import _jit_flow

    t64 = np.ascontiguousarray(t, dtype=np.int64)
    i64 = np.ascontiguousarray(i, dtype=np.int64)
    e64 = t64 if entries is None else np.ascontiguousarray(entries, dtype=np.int64)  # (not read without entries)
    return int(_jit_flow.flow_shop(t64, i64, e64, entries is not None, int(depth)))


def flow_shop_python(t: np.ndarray, i: np.ndarray, entries: np.ndarray | None, depth: int) -> int:
    """:func:`flow_shop` as a Python loop over the packets (0.3 microseconds each here),
    their cycles made Python ints :data:`FLOW_SHOP_CHUNK` at a time, and of the cycles
    they were tested at only the last ``depth`` + 1 kept between chunks (a packet takes
    an entry at least, so none waits for one further back). The reference of the
    compiled one, run with ``TLM_KERNELS=numpy``."""
    n = int(t.shape[0])
    if n == 0:
        return 0
    depth = min(int(depth), INT64_MAX >> 1)  # (as deep as any: past every entry)
    slots = np.ones(n, dtype=np.int64) if entries is None else np.clip(np.asarray(entries, dtype=np.int64), 1, depth)
    ends = np.cumsum(slots)  # entries of packets 0..k
    before = np.concatenate(([0], ends))  # entries of the packets before m
    # packet k fits once the packets before w[k] are tested: w[k], the first m with ends[k] - before[m] <= depth
    # (at least k + 1 - depth: every packet takes an entry)
    w = np.searchsorted(before, ends - depth, side="left")
    tested = [0]  # tested[x]: the cycle packet base + x - 1 was tested (x = 0, base = 0: the phase's start)
    base = 0
    pushed = last = 0  # the cycle the Traversal PM put the previous packet in; the previous packet tested
    for s in range(0, n, FLOW_SHOP_CHUNK):
        e = min(n, s + FLOW_SHOP_CHUNK)
        for tk, ik, wk in zip(t[s:e].tolist(), i[s:e].tolist(), (w[s:e] - base).tolist(), strict=True):
            pushed += tk  # worked
            room = tested[wk]
            if room > pushed:
                pushed = room  # (fifo_full until then)
            last = (last if last > pushed else pushed) + ik  # (fifo_empty until it is in)
            tested.append(last)
        drop = e + 1 - depth - base  # the next packet looks back to tested[e + 1 - depth - base] at most
        if drop > 0:
            del tested[:drop]
            base += drop
    return last


FLOW_SHOP_LOOP_PACKETS = 1 << 16  # packets of an estimate's phases the Python loop takes (_FlowShops)
_KERNEL = "tlm.kernels._jit_flow"


class _FlowShops:
    """The flow shops of one estimate's phases (a call of :func:`ti_cycles` or
    :func:`fine_ti_cycles`): :func:`flow_shop_python` while those so far come to at most
    :data:`FLOW_SHOP_LOOP_PACKETS` packets and the compiled kernel is not loaded in this
    process, :func:`flow_shop` past them. The same cycles either way (the loop is the
    kernel's reference). The kernel's first call in a process imports numba and loads its
    compiled code from the cache: 0.5 to 2.5 s here (more on a cold cache), against 0.1 to
    0.5 microseconds a packet in the loop (at most about 35 ms for the estimate's packets).
    A frame whose work came from the functional cache runs no other kernel, so without
    this the first packet size above one of ``tlm granularity`` at 48x48 took 2 s of host
    time for the 0.07 s of its simulation."""

    def __init__(self) -> None:
        self.left = FLOW_SHOP_LOOP_PACKETS

    def __call__(self, t: np.ndarray, i: np.ndarray, entries: np.ndarray | None, depth: int) -> int:
        n = int(t.shape[0])
        if n <= self.left and _KERNEL not in sys.modules:
            self.left -= n
            return flow_shop_python(t, i, entries, depth)
        return flow_shop(t, i, entries, depth)


def _phase_cycles(ph: PhaseSpec, arch: ArchConfig, shops: _FlowShops) -> int | None:
    """A Traversal/Intersection phase's cycles alone (its flow shop, at ``arch.fifo_depth``,
    by ``shops``); None for any other phase."""
    costs = _ti_costs(ph, arch)
    return None if costs is None else shops(*costs, ph.jobs[0].entries, arch.fifo_depth)


def ti_cycles(program: FrameProgram, arch: ArchConfig) -> list[int]:
    """Per tile of the tiled stages, in program order: its Traversal/Intersection phases'
    cycles, each phase alone (:func:`flow_shop`, at ``arch.fifo_depth``; the Python loop
    for a small program's, :class:`_FlowShops`)."""
    shops = _FlowShops()
    return _per_tile(program, lambda ph: _phase_cycles(ph, arch, shops))


def fine_ti_cycles(fn: Functional, programs: Programs, arch: ArchConfig) -> list[int]:
    """:func:`ti_cycles` of ``frame_program(fn, programs, replace(arch, packet_size=1))``,
    without that program: its Traversal/Intersection phases alone, built one at a time
    (:func:`tlm.arch.frame_program.ti_phases`, the same phases) and each dropped once its
    flow shop is known, so at most one phase's per-ray costs are held."""
    one = replace(arch, packet_size=1)
    shops = _FlowShops()
    return [sum(c for ph in phases if (c := _phase_cycles(ph, one, shops)) is not None)
            for phases in ti_phases(fn, programs, one)]


def granularity_estimate(program: FrameProgram, arch: ArchConfig, throughput: int, slowest: int,
                         fine: FrameProgram | list[int] | None = None) -> dict:
    """A cheap estimate of how far the packet size moves TThru from packets of one
    (results.json ``timing.granularity``), without simulating packets of one.

    ``change_cycles`` (with ``fine``, the same frame's program in packets of one, or its
    :func:`ti_cycles` per tile as :func:`fine_ti_cycles` gives them): the
    Traversal/Intersection phases' cycles per frame in these packets minus in packets of
    one (:func:`ti_cycles`, summed over the tiles of the busiest pipeline as in
    :func:`fill_and_drain`'s total): positive where whole packets hand over late at the
    phase boundaries, negative where they pass the FIFO together, as a deeper FIFO would
    let packets of one (a packet with more addresses than the FIFO holds enters it empty
    and whole). With one image in flight it is the change in TThru exactly, the other
    PMs' cycles being the same in any packets; with two, the other image fills part of
    either. ``fill_drain_cycles``: the hand-overs' part alone (:func:`fill_and_drain`);
    ``over_slowest_pm``: TThru minus the slowest PM's cycles, which TThru in packets of
    one cannot go below either (the per-PM cycles hardly move with the packet size), so
    the packets cannot have added more (with two images in flight the other image's work
    fills the gaps of a run bound by one PM). ``share``: ``change_cycles``, at most
    ``over_slowest_pm``, over TThru (negative: faster than packets of one); without
    ``fine`` (a program built by hand: its packets of one are not known) the smaller of
    ``fill_drain_cycles`` and ``over_slowest_pm`` over TThru, and no ``change_cycles``.
    So with two images in flight ``share`` bounds neither the sign nor strictly the size of
    the change in TThru (on small frames the measured change is mostly smaller and can take
    the other sign: Cornell refract 32x32 at 256, +8.7%, measured -2.3%); ``over_slowest_pm``
    bounds what the packets add. :func:`tlm.experiments.run_warnings.granularity_line` words
    it so. Measured against ``tlm granularity`` in docs/architecture.md ("Packet size"), where
    ``tlm run``'s warning threshold (:data:`tlm.experiments.run_warnings.GRANULARITY_WARNING`) comes from.
    """
    fd = _busiest(fill_and_drain(program, arch), program)
    over = max(0, throughput - slowest)
    out: dict = {"fill_drain_cycles": fd}
    if fine is None:
        moved = min(fd, over)
    else:
        if fine is program:
            change = 0
        elif isinstance(fine, FrameProgram):
            change = _busiest(ti_cycles(program, arch), program) - _busiest(ti_cycles(fine, arch), fine)
        else:
            fine = list(fine)
            coarse = ti_cycles(program, arch)
            if len(fine) != len(coarse):
                raise ValueError(f"granularity_estimate: {len(fine)} tiles' cycles in packets of one for the "
                                 f"program's {len(coarse)} tiles")
            change = _busiest(coarse, program) - _busiest(fine, program)
        out["change_cycles"] = change
        moved = min(change, over)
    out["over_slowest_pm"] = over
    out["share"] = round(moved / throughput, 4) if throughput > 0 else 0.0
    return out


__all__ = ["FLOW_SHOP_CHUNK", "FLOW_SHOP_LOOP_PACKETS", "fill_and_drain", "fine_ti_cycles", "flow_shop",
           "flow_shop_python", "granularity_estimate", "ti_cycles"]
