"""Agreement with the thesis's Tables I–III cannot regress silently.

Runs the committed thesis study (``configs/thesis.yaml``: three scenes x four modes at
the thesis's settings, about 25 s) and bounds the two figures docs/fidelity.md reports:
the median |relative error| over the held-out cells (every cell not fitted to the
thesis, i.e. every column but RCast's calibrated PMs) that are predictions of their own (not
the Reflect and Refract TVert, the fitted RCast TVert again, nor FPS, 600 MHz / TThru: the
summary's ``not_predictions``) and the number of scene-modes whose
slowest PM is the thesis's. The bounds are the figures of the latest change to the
model or the scenes (docs/fidelity.md); a change that improves them should tighten them.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tlm.experiments.thesis import run_thesis

ROOT = Path(__file__).resolve().parents[1]
# docs/fidelity.md: 37.9% over the 45 held-out cells predicted on their own (27.4% over all 63 held-out cells, the bar
# until 2026-11-30: it counted the 6 Reflect/Refract TVert cells, copies of a fitted cell, and the 12 FPS cells, each
# its TThru again, as predictions; the model and scenes did not change, only what the headline counts)
MAX_PREDICTED_MEDIAN = 0.380
MIN_SLOWEST_PM_MATCHES = 9  # of 12 scene-modes


@pytest.mark.slow
def test_the_thesis_study_agrees_with_tables_one_to_three_at_least_as_well_as_documented(tmp_path, monkeypatch):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    s = run_thesis(ROOT / "configs" / "thesis.yaml", tmp_path / "thesis")["summary"]
    assert s["held_out_cells"] == 63 and s["predicted_cells"] == 45 and s["scene_modes"] == 12
    assert s["median_abs_rel_error_predicted"] <= MAX_PREDICTED_MEDIAN, s["median_abs_rel_error_predicted"]
    assert s["slowest_pm_matches"] >= MIN_SLOWEST_PM_MATCHES, s["slowest_pm"]
