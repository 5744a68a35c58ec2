"""Review of ba0f1b0 (h302): the architect's findings, tried at their edges.

1. The thesis tables' link to docs/fidelity.md was relative to the report folder wherever it was: a report in
   /tmp/r got ``../../work/main/docs/fidelity.md#by-cell``, the checkout's place on this machine, which leads
   nowhere once the folder is copied, moved or opened elsewhere. A link now only from inside the checkout
   (``plots/``: ``../docs/fidelity.md``, moving with it); elsewhere the page's name, as an installed copy says.
2. A fit of two values of N whose two points leave B undetermined (the same sum_i max / N at both: a slowest
   pipeline holding all the work, B = 1 taken) has an error of 225%, which the legend called "exact by
   construction" and ``tlm scaling`` "two points fit A and B exactly".
3. At arch.clock_hz = 1e12 a 500-cycle stream's timeline read "0.5 ns" (1 cycle: 0.001 ns): its unit is ps now.
"""

from __future__ import annotations

import re
import shutil

import pytest

from tlm.cli_tables import print_scaling
from tlm.experiments.scaling import fit_both
from tlm.report import tables
from tlm.report.cycles import time_axis
from tlm.report.scaling import error_text


def _checkout(tmp_path, monkeypatch):
    doc = tmp_path / "checkout" / "docs" / "fidelity.md"
    doc.parent.mkdir(parents=True)
    doc.write_text("# Fidelity\n\n## By cell\n", encoding="utf-8")
    monkeypatch.setattr(tables, "FIDELITY_DOC", doc)
    return doc.parents[1]


def test_a_report_outside_the_checkout_names_the_page_without_a_link_that_breaks_when_moved(tmp_path, monkeypatch):
    checkout = _checkout(tmp_path, monkeypatch)
    out = tmp_path / "elsewhere" / "report"
    out.mkdir(parents=True)
    line = tables.fidelity_html(out)
    assert "<a " not in line and "docs/fidelity.md, “By cell” in tlm's source" in line, line
    inside = checkout / "plots"  # (the committed report: a link that moves with the checkout)
    inside.mkdir()
    assert 'href="../docs/fidelity.md#by-cell"' in tables.fidelity_html(inside)
    shutil.move(checkout, tmp_path / "moved")
    assert (tmp_path / "moved" / "plots" / "../docs/fidelity.md").is_file()


def _points(slowest_holds_all: bool) -> list[dict]:
    """N = 1 and 4: at 4 the mean pipeline has a quarter of the work, the slowest all of it (or a quarter)."""
    top = 12000 if slowest_holds_all else 3000
    return [{"pipelines": 1, "throughput": 13000, "T_vert0": 1000, "sum_max": 12000, "max_max": 12000},
            {"pipelines": 4, "throughput": 4000, "T_vert0": 1000, "sum_max": 12000, "max_max": top}]


def test_a_two_n_fit_with_an_error_is_not_said_to_be_exact(tmp_path, capsys):
    f = fit_both(_points(True), "throughput")
    assert f["max_abs_rel_error"] == 0 and f["slowest"]["B"] == 1.0 and f["slowest"]["max_abs_rel_error"] > 2
    assert error_text(f).endswith("(N = 1 and 4 alone: exact by construction)")
    slowest = error_text({**f["slowest"], "rows": f["rows"]})
    assert slowest == "225.0% (N = 1 and 4 alone: A and B not both determined)", slowest
    fit = {"scene": "ring", "mode": "rcast", "scheduler": "static", "target": "throughput", "A": f["A"], "B": f["B"],
           "max_abs_rel_error": f["max_abs_rel_error"], "slowest": f["slowest"], "pipelines": [1, 4]}
    exact = fit_both(_points(False), "throughput")
    print_scaling({"notes": [], "fits": [fit, {**fit, "slowest": exact["slowest"]}]}, tmp_path)
    undetermined, both = capsys.readouterr().out.splitlines()[1:3]
    assert "exactly" not in undetermined, undetermined
    assert undetermined.endswith("(N = 1, 4 alone, a test of nothing: eq. 5.2 exact by construction; slowest-pipeline "
                                 "variant: A and B not both determined)"), undetermined
    assert both.endswith("(N = 1, 4 alone: two points fit A and B exactly, a test of nothing)"), both


def test_a_terahertz_timeline_of_a_few_cycles_is_in_picoseconds():
    for cycles in (1, 500):
        k, label = time_axis(cycles, 1e12)
        assert label == "time (ps at 1 THz)" and cycles * k == pytest.approx(cycles), (label, cycles * k)
    assert re.fullmatch(r"time \(ns at 600 MHz\)", time_axis(500, 600e6)[1])
