"""h425: the FIFOs' peak occupancy is recorded (``timing.fifo``: :func:`tlm.arch.fifo.fifo_peaks`),
and an ``arch.fifo_depth`` that binds nothing says so from those peaks, exactly: where
:func:`tlm.arch.fifo.fifo_depth_alike` holds, the run at the default depth is the same run
(checked here by simulating both), and where a put could wait at one depth and not at the
other there is no word. Probe h421 (item 6): depths 1, 4, 64 against 1024 at packets of 16 or
256 gave identical cycles with no word, and no occupancy was recorded anywhere."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import simpy

from tlm.arch.fifo import Fifo, fifo_depth_alike
from tlm.arch.model import FrameProgram, JobSpec, PhaseSpec, simulate, simulate_program
from tlm.config import ArchConfig, RunConfig, config_from_dict
from tlm.experiments.run_warnings import fifo_depth_lines, stream_warnings, timing_inert

DEFAULT = ArchConfig().fifo_depth


def _job(pm, norm, entries, role):
    norm = np.asarray(norm, dtype=np.int64)
    return JobSpec(pm, "test", role, norm, np.zeros_like(norm), np.zeros_like(norm), np.ones_like(norm),
                   np.asarray(entries, dtype=np.int64))


def _ti(t, i, entries, depth):
    """One Traversal/Intersection phase, T ``t`` and I ``i`` cycles a packet, three frames."""
    n = len(entries)
    prog = FrameProgram.linear([PhaseSpec("ti", (_job("traversal", [t] * n, entries, 0),
                                                 _job("intersection", [i] * n, entries, 1)), 0)])
    arch = config_from_dict({"arch": {"frames": 3, "fifo_depth": depth, "trace": False}}, "test").arch
    return simulate_program(prog, arch), prog, arch


def _same(a, b) -> bool:
    """Two timings alike in everything but the FIFOs' record (which names the depth)."""
    da, db = a.to_dict(), b.to_dict()
    da.pop("fifo")
    db.pop("fifo")
    return da == db


def test_a_fifo_keeps_its_peaks():
    fifo = Fifo(simpy.Environment(), depth=8)
    assert fifo.try_push(0, 3, 3)  # empty: no peak_shared
    assert fifo.peak_shared == 0 and (fifo.peak_entries, fifo.peak_packets) == (3, 1)
    assert fifo.try_push(1, 2, 2)  # beside packet 0: 5 addresses
    assert fifo.peak_shared == 5 and (fifo.peak_entries, fifo.peak_packets) == (5, 2)
    assert not fifo.try_push(2, 8, 20) and not fifo.try_push(2, 8, 20)  # no room, two packets held; one put
    assert (fifo.waited, fifo.waited_on_many, fifo.least_waited) == (1, 1, 0)
    fifo.try_pop()
    fifo.free(3, 3)
    assert not fifo.try_push(3, 8, 20)  # one packet held (2 addresses): 22 with it
    assert (fifo.waited, fifo.waited_on_many, fifo.least_waited) == (2, 1, 22)
    fifo.try_pop()
    fifo.free(2, 2)
    assert fifo.try_push(3, 8, 20) and fifo.addresses == 20 and fifo.peak_entries == 8
    assert fifo.peak_shared == 5 and fifo.peak_packets == 2


@pytest.mark.parametrize("t, i, entries, depth, alike", [
    (5, 1, [3, 5, 2, 4], 8, True),  # T slower: every put finds the FIFO empty (no old rule held: 14 > 8, 2 < 1024)
    (1, 5, [600] * 4, 64, True),  # I slower: each put waits for the one packet held, 1200 > 1024 addresses
    (1, 5, [3] * 6, 4, False),  # I slower: a put waits at 4 for a packet it fits beside at 1024
    (1, 5, [300, 900, 300, 900], 64, True),  # each waits for the one held: 1200 addresses, too many at 1024 as well
    (1, 5, [300, 300, 900, 900], 64, False),  # the second 300 waits at 64, enters beside the first at 1024
    (4, 5, [2] * 10, 16, True),  # packets pile up beside others (peak_shared) within 16: none waits
    (2, 3, [2] * 12, 16, False),  # ... until they overflow 16 and wait beside several: not judged
])
def test_the_peaks_tell_exactly_when_the_default_depth_runs_the_same(t, i, entries, depth, alike):
    timing, prog, arch = _ti(t, i, entries, depth)
    peaks = timing.fifo
    assert peaks["depth"] == depth and peaks["fifos"] == 3 and len(peaks["pipelines"]) == 1
    assert peaks["peak_packets"] >= 1 and 1 <= peaks["peak_entries"] <= depth
    assert fifo_depth_alike(peaks, depth, DEFAULT) is alike
    default = simulate_program(prog, dataclasses.replace(arch, fifo_depth=DEFAULT))
    assert _same(timing, default) is alike  # the claim, checked by running the default
    why = timing_inert(timing, arch).get("arch.fifo_depth")
    if not alike:
        assert why is None
        return
    n, e = peaks["peak_packets"], peaks["peak_entries"]  # (h508: packets, entries of the depth, addresses)
    assert why.startswith(f"no FIFO held more than {n} packet{'s' if n != 1 else ''}, entries {e} of {depth} (an ")
    assert f" or triangle addresses {peaks['peak_addresses']} (not cut to the depth) at once" in why
    assert ("no put ever waited" in why) is (peaks["waited"] == 0)
    assert (f"{peaks['least_waited']} triangle addresses or more" in why) is (peaks["waited"] > 0)
    (line,) = [w for w in stream_warnings(timing, RunConfig(arch=arch)) if w.startswith("arch.fifo_depth")]
    assert line == f"arch.fifo_depth = {depth} has no effect in this run: {why}"


def test_a_run_whose_cycles_the_depth_leaves_alone_says_so_beside_the_estimate():
    """h421's case: Cornell RCast 16x16 in packets of 16 at depth 64; every put waits for the one
    (large) packet held at either depth: the cycles, stalls and frame times are the default's, and
    only timing.granularity (the packets-of-one estimate) reads the depth: a warning, not 'unread'."""
    from tlm.arch.costs import load_programs
    from tlm.experiments.run import render, timing_dict

    cfg = config_from_dict({"scene": "cornell", "mode": "rcast", "resolution": [16, 16],
                            "render": {"spp": 1, "light_samples": 1},
                            "arch": {"trace": False, "packet_size": 16, "fifo_depth": 64}}, "h425")
    fn, programs = render(cfg).functional(), load_programs()
    timing = simulate(fn, programs, cfg.arch)
    default = simulate(fn, programs, dataclasses.replace(cfg.arch, fifo_depth=DEFAULT))
    assert fifo_depth_alike(timing.fifo, 64, DEFAULT)
    a, b = timing.to_dict(), default.to_dict()
    assert {k for k in a if a[k] != b[k]} <= {"fifo", "granularity"} and a["cycles"] == b["cycles"]
    assert a["units"] == b["units"] and a["frame_times"] == b["frame_times"] and a["events"] == b["events"]
    assert "arch.fifo_depth" not in timing_inert(timing, cfg.arch)
    (line,) = fifo_depth_lines(timing, cfg.arch)
    assert line.startswith(f"arch.fifo_depth = 64 changes no simulated cycle in this run (cycles, stalls and frame "
                           f"times are those of the default {DEFAULT}): no FIFO held more than 1 packet, entries 64 "
                           "of 64")
    assert line in stream_warnings(timing, cfg)
    assert timing_dict(timing, cfg.arch, programs)["fifo"]["peak_entries"] == 64  # results.json timing.fifo
    fine = dataclasses.replace(cfg.arch, packet_size=1)  # packets of one: the depth matters, no word
    fine_timing = simulate(fn, programs, fine)
    assert not fifo_depth_alike(fine_timing.fifo, 64, DEFAULT) and fifo_depth_lines(fine_timing, fine) == []
    assert "arch.fifo_depth" not in timing_inert(fine_timing, fine)
    assert not _same(fine_timing, simulate(fn, programs, dataclasses.replace(fine, fifo_depth=DEFAULT)))


def test_the_report_says_the_peaks_under_the_cycle_breakdown():
    from tlm.report.cycles import fifo_caption

    timing, _, _ = _ti(1, 5, [600] * 4, 64)
    assert fifo_caption(timing.fifo) == (" Traversal-to-Intersection FIFOs: none held more than 1 packet, entries "
                                         "64 of 64 (an entry a triangle address, a packet the whole FIFO at most) or "
                                         "triangle addresses 600 (not cut to the depth) at once; "
                                         f"{timing.fifo['waited']} puts waited for room (timing.fifo).")
    assert fifo_caption(None) == ""  # (a results.json written before timing.fifo)
