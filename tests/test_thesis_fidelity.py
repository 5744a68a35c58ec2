"""Agreement with the thesis's Tables I–III cannot regress silently.

Runs the committed thesis study (``configs/thesis.yaml``: three scenes x four modes at
the thesis's settings, about 25 s) and bounds the two figures docs/fidelity.md reports:
the median |relative error| over the held-out cells (every cell not fitted to the
thesis, i.e. every column but RCast's calibrated PMs) and the number of scene-modes whose
slowest PM is the thesis's. The bounds are the figures of the latest change to the
model or the scenes (docs/fidelity.md); a change that improves them should tighten them.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tlm.experiments.thesis import run_thesis

ROOT = Path(__file__).resolve().parents[1]
MAX_HELD_OUT_MEDIAN = 0.275  # docs/fidelity.md: 27.4% over the 63 held-out cells (cycles per record, 2026-11-25)
MIN_SLOWEST_PM_MATCHES = 9  # of 12 scene-modes


@pytest.mark.slow
def test_the_thesis_study_agrees_with_tables_one_to_three_at_least_as_well_as_documented(tmp_path, monkeypatch):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    s = run_thesis(ROOT / "configs" / "thesis.yaml", tmp_path / "thesis")["summary"]
    assert s["held_out_cells"] == 63 and s["scene_modes"] == 12
    assert s["median_abs_rel_error_held_out"] <= MAX_HELD_OUT_MEDIAN, s["median_abs_rel_error_held_out"]
    assert s["slowest_pm_matches"] >= MIN_SLOWEST_PM_MATCHES, s["slowest_pm"]
