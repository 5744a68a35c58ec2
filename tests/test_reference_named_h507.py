"""The reference an error is measured against is named where the error is shown (h507, an image-physics probe).

``results.json``'s ``error`` named the reference's key, rounds and standard error but not its photons a round
(``reference.photons: null`` is the scene's count) or its ``k_nearest``, nor its resolution; the ``tlm run``
report said no more, and the ``tlm error-vs-cost`` report named no reference at all (only its ``reference.json``
held its settings). Now ``error`` records ``reference_photons`` (resolved: a number), ``reference_k_nearest`` and
``reference_resolution`` beside ``reference_rounds``, ``reference.json`` its ``resolution``, and both reports say
key, photons a round, k_nearest, rounds and resolution in one line where they show the error.
"""

from __future__ import annotations

import html
import json

import numpy as np
import pytest

from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments import frames, run
from tlm.experiments.reference_cache import save_reference
from tlm.report.collect import Study

from .scenes import sphere_scene

# a reference of few rounds (the test's time), of the scene's photons (reference.photons null: 900, the scene's)
REFERENCE = {"k_nearest": 20, "tolerance": 0.5, "min_rounds": 2, "max_rounds": 2, "spp": 1}
LINE = "900 photons a round, k_nearest 20, 2 rounds"


def _scene(tmp_path):
    path = sphere_scene(tmp_path, n_seg=8, n_rings=4)
    path.write_text(path.read_text().replace("photons: 20000", "photons: 900"))
    return path


def _config(tmp_path) -> dict:
    _scene(tmp_path)
    return {"scene": str(tmp_path / "furnace.yaml"), "mode": "pmap", "resolution": [8, 6], "reference": REFERENCE,
            "photons": {"count": 700}, "estimate": {"final_gather": 0}, "arch": {"frames": 1, "trace": False}}


def _page(folder) -> str:
    return html.unescape((folder / "report" / "report.html").read_text(encoding="utf-8"))


def test_tlm_run_records_and_reports_the_references_photons_k_rounds_and_resolution(tmp_path, cache):
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(json.dumps(_config(tmp_path)))
    out = tmp_path / "out"
    assert main(["run", str(cfg), "--out", str(out), "--no-progress"]) == 0
    error = json.loads((out / "results.json").read_text())["error"]
    assert error["available"] is True
    # (the scene's 900, not null and not the run's 700 photons)
    assert (error["reference_photons"], error["reference_k_nearest"], error["reference_rounds"],
            error["reference_resolution"]) == (900, 20, 2, [8, 6])
    page = _page(out)
    # the lead, where the error is said, and the error figure's caption: one line each
    line = f"reference {error['reference']} ({LINE}, relative standard error "
    assert page.count(line) >= 2, page
    assert "8x6 pixels)" in page


def test_a_sweep_points_cached_frame_records_the_same_reference_settings(tmp_path, cache):
    cfg = config_from_dict(_config(tmp_path), str(tmp_path / "cfg.yaml"))
    first = frames.cached_render(cfg)
    assert first.summary["error"]["available"] is False
    save_reference(first.summary["error"]["reference"], np.full((6, 8, 3), 0.5, np.float32),
                   {"rounds": 12, "relative_standard_error": 0.01, "converged": True})
    again = frames.cached_render(cfg)
    assert again.cached
    res = run.render(cfg)
    fresh = run.photon_error(res.frame, res.radiance["pmap"].reshape(-1, 3))
    assert again.summary["error"] == fresh
    assert (fresh["reference_photons"], fresh["reference_k_nearest"], fresh["reference_rounds"],
            fresh["reference_resolution"]) == (900, 20, 12, [8, 6])


def test_error_vs_cost_keeps_the_resolution_and_its_report_names_the_reference(tmp_path, cache):
    _scene(tmp_path)
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({
        "base": {"scene": "furnace.yaml", "resolution": [8, 6], "reference": REFERENCE,
                 "photons": {"count": 700}, "estimate": {"final_gather": 0}},
        "points": [{"estimate.filter": ["disk", "mvoxel"]}],
    }))
    out = tmp_path / "out"
    assert main(["error-vs-cost", str(exp), "--out", str(out), "--truth-spp", "0", "--no-progress"]) == 0
    ref = json.loads((out / "reference.json").read_text())
    assert (ref["photons"], ref["k_nearest"], ref["rounds"], ref["resolution"]) == (900, 20, 2, [8, 6])
    page = _page(out)
    line = f"reference {ref['key']} ({LINE}, relative standard error "
    assert line in page, page
    assert "8x6 pixels)" in page


@pytest.mark.parametrize("meta", [{"reference": {"key": "abc", "photons": 4000, "k_nearest": 100, "rounds": 88,
                                                 "relative_standard_error": 0.0198, "resolution": [32, 16]}}])
def test_the_study_line_of_a_reference_json(tmp_path, meta):
    from tlm.report.tradeoff_studies import reference_line

    assert reference_line(Study("error-vs-cost", tmp_path, [], meta)) == (
        "reference abc (4,000 photons a round, k_nearest 100, 88 rounds, relative standard error 0.0198, "
        "32x16 pixels)")
    # (a study written before its resolution was kept: what it has; none: nothing)
    del meta["reference"]["resolution"]
    assert reference_line(Study("error-vs-cost", tmp_path, [], meta)).endswith("relative standard error 0.0198)")
    assert reference_line(Study("error-vs-cost", tmp_path, [], {})) == ""
