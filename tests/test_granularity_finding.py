"""The report's granularity finding (tlm.report.summary.study_findings): the largest packet up
to which every size keeps within 1% of packets of one, not a lucky size on a curve that does
not fall steadily, and the default size's error (h90's tlm_granularity: 4 -> 1.61%, 64 -> 0.11%,
256 -> 6.09%)."""

from pathlib import Path

from tlm.config import ArchConfig
from tlm.report.collect import Inputs, Study
from tlm.report.summary import study_findings

# tlm granularity tlm_granularity (h90, 2026-11-30): packet size, max |cycle error|, simulate seconds
H90 = ((1, 0.0, 20.58), (4, 0.016073, 5.67), (16, 0.022366, 1.83), (64, 0.001107, 0.4375), (256, 0.060919, 0.1989),
       (1024, 0.060417, 0.0704), (4096, 0.052477, 0.0531), (16384, 0.0481, 0.043), (102400, 0.089866, 0.0358))


def _finding(points) -> str:
    rows = [{"packet_size": n, "max_abs_rel_error": e, "simulate_seconds": s} for n, e, s in points]
    (text,) = study_findings(Inputs([], studies=[Study("granularity", Path("g"), rows)]))
    return text


def test_a_lucky_size_past_one_off_by_more_is_not_the_finding():
    assert ArchConfig().packet_size == 256
    assert _finding(H90) == (
        "<b>Granularity g:</b> packets of 4, the next size above 1, are already 1.61% off the cycles of packets "
        "of 1 (more than 1%); packets of 64 (0.11%) come back within 1% past a smaller size that does not: the "
        "error does not fall steadily with the packet size, so such a size is luck, not a setting to trust; the "
        "default packets of 256 (arch.packet_size) are 6.09% off, in 0.199 s of simulation against 20.6 s.")


def test_the_finding_is_the_largest_size_every_smaller_one_keeps_within():
    points = ((1, 0.0, 8.0), (4, 0.002, 4.0), (16, 0.009, 2.0), (64, 0.03, 1.0), (256, 0.004, 0.5))
    assert _finding(points) == (
        "<b>Granularity g:</b> packets of 16 stay within 1% of the cycles of packets of 1 (error 0.90%), as every "
        "size below it does (at most 0.90%), in 2 s of simulation against 8 s; packets of 256 (0.40%) come back "
        "within 1% past a smaller size that does not: the error does not fall steadily with the packet size, so "
        "such a size is luck, not a setting to trust; the default packets of 256 (arch.packet_size) are 0.40% "
        "off, in 0.5 s of simulation against 8 s.")


def test_the_default_size_is_said_when_it_is_not_the_finding():
    points = ((1, 0.0, 8.0), (16, 0.005, 2.0), (256, 0.02, 0.5), (4096, 0.05, 0.1))
    assert _finding(points).endswith(
        "packets of 16 stay within 1% of the cycles of packets of 1 (error 0.50%), in 2 s of simulation against "
        "8 s; the default packets of 256 (arch.packet_size) are 2.00% off, in 0.5 s of simulation against 8 s.")
    within = ((1, 0.0, 8.0), (16, 0.005, 2.0), (256, 0.008, 0.5), (4096, 0.05, 0.1))
    assert "default" not in _finding(within)  # (the finding is the default size: said once)
