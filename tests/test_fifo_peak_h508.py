"""h508 (from the timing-model probe h498): the FIFO's stress case stresses the FIFO, and its peak
says what it held.

1. ``configs/extreme.yaml``'s ``fifo-depth-1`` ran at packets of 256, where a packet of tens of
   thousands of addresses enters only an empty FIFO at any depth: depth 1 ran cycle for cycle as
   1024 (9,053,027 both) and its ``>=`` passed on the equality. At packets of one ray the depth
   binds: it now runs there and is strictly slower than ``packet-1`` (the same packets at 1024).
2. ``timing.fifo.peak_entries`` counts slots (a packet takes one per address, the whole depth at
   most), so at depth 1 it read 1 and the warning said "no FIFO held more than 1 entries" while one
   packet carried 429,926 addresses (Cornell RCast 32x32). ``peak_addresses`` keeps the addresses
   held at once, not cut to the depth, and the warning and the report's caption say both.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import simpy
import yaml

from tlm.arch.fifo import Fifo, fifo_depth_alike, fifo_peaks
from tlm.arch.model import FrameProgram, JobSpec, PhaseSpec, simulate_program
from tlm.config import ArchConfig, config_from_dict
from tlm.experiments.run_warnings import timing_inert

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ArchConfig()


def _ti(t, i, entries, depth):
    """One Traversal/Intersection phase, T ``t`` and I ``i`` cycles a packet of ``entries`` addresses."""
    def job(pm, role):
        norm = np.full(len(entries), t if pm == "traversal" else i, dtype=np.int64)
        return JobSpec(pm, "test", role, norm, np.zeros_like(norm), np.zeros_like(norm), np.ones_like(norm),
                       np.asarray(entries, dtype=np.int64))
    prog = FrameProgram.linear([PhaseSpec("ti", (job("traversal", 0), job("intersection", 1)), 0)])
    arch = config_from_dict({"arch": {"frames": 3, "fifo_depth": depth, "trace": False}}, "h508").arch
    return simulate_program(prog, arch), arch


def test_a_fifo_keeps_the_addresses_it_held_beside_its_slots():
    one = Fifo(simpy.Environment(), depth=1)
    assert one.try_push(0, one.slots(5), 5)  # 5 addresses in the one slot
    assert (one.peak_entries, one.peak_addresses, one.peak_packets) == (1, 5, 1)
    one.try_pop()
    one.free(1, 5)
    assert one.try_push(1, one.slots(0), 0)  # no address: its end marker, one entry
    assert (one.peak_entries, one.peak_addresses) == (1, 5) and one.addresses == 1
    eight = Fifo(simpy.Environment(), depth=8, pipe=1)
    assert eight.try_push(0, 3, 3) and eight.try_push(1, 2, 2)
    assert (eight.peak_entries, eight.peak_addresses) == (5, 5)
    for slots in (3, 2):
        eight.try_pop()
        eight.free(slots, slots)
    assert eight.try_push(2, eight.slots(20), 20)  # more than the depth: an empty FIFO, whole
    assert (eight.peak_entries, eight.peak_addresses) == (8, 20)
    peaks = fifo_peaks([one, eight], 8, 2)
    assert (peaks["peak_entries"], peaks["peak_addresses"]) == (8, 20)
    assert [(p["peak_entries"], p["peak_addresses"]) for p in peaks["pipelines"]] == [(1, 5), (8, 20)]


def test_at_depth_1_the_warning_says_one_entry_and_the_addresses_it_held():
    """Four packets of 600 addresses, the Intersection PM slower: each waits for the one held (1200
    addresses, more than 1024), so depth 1 runs as 1024, and the line says so in the right units."""
    timing, arch = _ti(1, 5, [600] * 4, 1)
    peaks = timing.fifo
    assert (peaks["peak_entries"], peaks["peak_addresses"], peaks["peak_packets"]) == (1, 600, 1)
    assert fifo_depth_alike(peaks, 1, DEFAULT.fifo_depth)
    why = timing_inert(timing, arch)["arch.fifo_depth"]
    assert why.startswith("no FIFO held more than 1 packet, entries 1 of 1 (an entry a triangle address, a packet "
                          "the whole FIFO at most) or triangle addresses 600 (not cut to the depth) at once "
                          "(timing.fifo: peak_packets, peak_entries, peak_addresses); "), why
    assert "1 entries" not in why


def test_the_caption_says_the_addresses_and_an_older_record_leaves_them_out():
    from tlm.arch.fifo import fifo_held
    from tlm.report.cycles import fifo_caption

    timing, _ = _ti(1, 5, [600] * 4, 64)
    held = ("1 packet, entries 64 of 64 (an entry a triangle address, a packet the whole FIFO at most) "
            "or triangle addresses 600 (not cut to the depth)")
    assert fifo_caption(timing.fifo) == (f" Traversal-to-Intersection FIFOs: none held more than {held} at once; "
                                         f"{timing.fifo['waited']} puts waited for room (timing.fifo).")
    old = {k: v for k, v in timing.fifo.items() if k != "peak_addresses"}  # a results.json from before h508
    assert fifo_held(old) == ("1 packet or entries 64 of 64 (an entry a triangle address, a packet the whole "
                              "FIFO at most)")


def _committed():
    raw = yaml.safe_load((ROOT / "configs" / "extreme.yaml").read_text())
    return raw, {c["name"]: c for c in raw["cases"]}


def test_the_depth_1_case_runs_where_the_depth_binds_and_is_judged_strictly():
    raw, cases = _committed()
    case = cases["fifo-depth-1"]
    arch = {**raw["base"].get("arch", {}), **case["config"].get("arch", {})}
    assert arch["packet_size"] == 1 and arch["fifo_depth"] == 1
    (check,) = [c for c in case["checks"] if isinstance(c, dict) and c.get("compare") == "cycles.throughput"]
    assert check["op"] == ">"
    other = cases[check["case"]]["config"]
    assert other["arch"].get("packet_size") == 1 and other["arch"].get("fifo_depth", DEFAULT.fifo_depth) == 1024
    assert {k: v for k, v in other.items() if k != "arch"} == {k: v for k, v in case["config"].items() if k != "arch"}
    names = list(cases)
    assert names.index(check["case"]) < names.index("fifo-depth-1")


@pytest.mark.slow
def test_the_depth_1_case_and_its_comparison_come_out_as_expected(tmp_path, cache):
    from tlm.experiments.extreme import run_extreme

    raw, cases = _committed()
    check = next(c for c in cases["fifo-depth-1"]["checks"] if isinstance(c, dict) and "compare" in c)
    keep = dict.fromkeys(["timing-reference", check["case"], "fifo-depth-1"])  # (the reference: its same image)
    path = tmp_path / "cases.yaml"
    path.write_text(yaml.safe_dump({"base": raw["base"], "cases": [cases[n] for n in keep]}, sort_keys=False))
    rows = {r["case"]: r for r in run_extreme(path, tmp_path / "out")}
    assert all(r["passed"] for r in rows.values()), {n: r["measured"] for n, r in rows.items()}
    measured = rows["fifo-depth-1"]["measured"]
    assert "cycles.throughput: " in measured and " > " in measured and "timing.fifo.peak_entries = 1" in measured
