"""Error-vs-cost keeps its warnings for the report (h417, from probe h409's D4): a study of a camera that faces
nothing said on stderr that its reference and ground truth are black but kept no warning in its folder, so ``tlm
report`` of it drew "the 2 points of the Pareto front" of RMSEs of 0 and never said the frame was black. Its
``reference.json`` now keeps the study's ``warnings`` (the frame's camera, the overrides', the reference's, a black
reference or truth), which the report's warnings box lists, and ``reference_black`` / ``truth_black``, by which the
error-vs-cost section says plainly that no relative error can be measured and draws no front. And a
functional-cache sidecar replaced by ``{}`` (JSON of no sidecar's shape) is said as a damaged one, as garbage is."""

from __future__ import annotations

import html
import json

import numpy as np

import tlm.api
import tlm.report.tradeoff as tradeoff
from tests.helpers_figures import capture
from tests.scenes import sphere_scene
from tests.test_installed_copy_leftovers import REFERENCE
from tlm.config import config_from_dict
from tlm.experiments import error_cost as ec
from tlm.experiments import frames
from tlm.report.collect import Study, read
from tlm.report.warnings import study_recorded, warnings_html

FACES_NOTHING = "error-vs-cost: the camera faces nothing: none of its 64 eye rays hits the scene"


def _experiment(tmp_path, away: bool = True, overrides: dict | None = None):
    """tests/scenes.py's furnace at 8 x 8 (its camera outside the sphere looking away where ``away``), one
    point of 800 photons, the small reference of tests/test_installed_copy_leftovers.py."""
    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    scene = tmp_path / "furnace.yaml"
    if away:
        scene.write_text(scene.read_text().replace("eye: [0.0, 0.0, 0.0], target: [0.0, 0.0, 1.0]",
                                                   "eye: [0.0, 0.0, 5.0], target: [0.0, 0.0, 9.0]"))
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({
        "base": {"scene": "furnace.yaml", "resolution": [8, 8], "photons": {"count": 800},
                 "reference": REFERENCE, "estimate": {"final_gather": 0}, "render": {"spp": 1}, **(overrides or {})},
        "points": [{"estimate.filter": ["disk", "mvoxel"]}],
    }))
    return exp


class BlackTruth(ec.Truth):
    """A ground truth of every pixel 0, without Mitsuba (FLIP said missing: no flip_evaluator called)."""

    def load(self, frame, g, progress=None):
        cam = frame.scene.camera
        return np.zeros((cam.height, cam.width, 3)), {"available": True, "flip_missing": "not in this test"}


def _study(out) -> Study:
    (study,) = read([out]).studies
    return study


def test_a_camera_facing_nothing_keeps_its_warnings_in_reference_json(tmp_path, cache):
    said: list[str] = []
    out = tmp_path / "out"
    rows = ec.run_error_vs_cost(_experiment(tmp_path), out, truth=BlackTruth(spp=4096), warned=said.append)
    assert all(r["rel_mse"] is None and r["truth_rel_mse"] is None for r in rows)
    ref = json.loads((out / "reference.json").read_text())
    assert ref["warnings"] == said and said[0] == FACES_NOTHING, said
    assert [w.split(" is black")[0] for w in said if " is black " in w] == [
        f"error-vs-cost: the photon-map reference {ref['key']}", "error-vs-cost: the ground truth"]
    assert ref["reference_black"] is True and ref["truth_black"] is True

    # the report: its warnings box lists them, attributed to the study and its reference.json
    study = _study(out)
    inputs = type("Inputs", (), {"studies": [study], "runs": [], "damaged": []})()
    listed = study_recorded(inputs)
    assert [line for line, _, _ in listed] == said
    assert {f for _, _, files in listed for f in files} == {"reference.json"}
    box = warnings_html(inputs)
    assert "the camera faces nothing" in box and "reference.json <code>warnings</code>" in box
    assert box.count("is black (every pixel 0)") == 2


def test_the_section_says_a_black_reference_and_truth_and_ranks_no_point(tmp_path, cache, monkeypatch):
    out = tmp_path / "out"
    ec.run_error_vs_cost(_experiment(tmp_path), out, truth=BlackTruth(spp=4096), warned=lambda line: None)
    study = _study(out)
    assert tradeoff.black_images(study) == (True, True)
    figs = capture(monkeypatch, tradeoff)
    report = tmp_path / "report"
    report.mkdir()
    sec = tradeoff.tradeoff_section(read([out]), report)
    lead = html.unescape(sec.lead)  # (said first, above the figures)
    assert "The photon-map reference is black" in lead and "no relative error can be measured" in lead
    assert "The ground truth is black" in lead
    frame = next(f for f in sec.figures if "simulated frame time" in f.title)
    assert "Pareto front" not in frame.caption.replace("no Pareto front", ""), frame.caption
    assert "no Pareto front: the reference is black" in frame.caption
    assert not [line for fig in figs for ax in fig.axes for line in ax.get_legend_handles_labels()[1]
                if line.startswith("Pareto front")]
    truth = next(f for f in sec.figures if "ground truth" in f.title)
    assert tradeoff.BLACK_TRUTH in truth.caption


def test_a_study_written_before_keeps_its_black_reference_read_from_its_rows(tmp_path):
    rows = [{"point": i, "filter": "disk", "final_gather": 0, "photons": 800, "rmse": 0.0, "rel_mse": None,
             "frame_seconds": 0.001 * (i + 1), "trace_seconds": 0.01 * (i + 1), "gather_seconds": 0.0,
             "truth_rmse": None, "truth_rel_mse": None, "reference_converged": True} for i in range(3)]
    old = Study("error-vs-cost", tmp_path / "evc", rows, {"reference": {"reference_converged": True}})
    assert tradeoff.black_images(old) == (True, False)  # (no truth_rmse: no ground truth, not a black one)
    lit = Study("error-vs-cost", tmp_path / "evc", [{**r, "rel_mse": 0.1, "rmse": 0.2} for r in rows],
                {"reference": {"reference_converged": True}})
    assert tradeoff.black_images(lit) == (False, False)
    sec = tradeoff.evc_figure(old, tmp_path, "x.png", "frame", notes := [], "evc")
    assert "no Pareto front: the reference is black" in sec.caption and not notes


def test_a_lit_study_keeps_an_empty_list_and_its_front(tmp_path, cache):
    out = tmp_path / "out"
    said: list[str] = []
    ec.run_error_vs_cost(_experiment(tmp_path, away=False), out, truth=ec.Truth(spp=0), warned=said.append)
    ref = json.loads((out / "reference.json").read_text())
    assert ref["warnings"] == said and ref["reference_black"] is False and ref["truth_black"] is False
    assert not [w for w in said if "faces nothing" in w or "is black" in w], said
    assert tradeoff.black_images(_study(out)) == (False, False)


def test_a_not_converged_line_is_listed_once_from_the_studys_own_list(tmp_path):
    line = "error-vs-cost: the photon-map reference k is NOT converged: ..."
    ref = {"reference_converged": False, "relative_standard_error": 0.5, "rounds": 2, "tolerance": 0.1,
           "warnings": [line]}
    study = Study("error-vs-cost", tmp_path / "evc", [], {"reference": ref})
    inputs = type("Inputs", (), {"studies": [study], "runs": [], "damaged": []})()
    assert [got for got, _, _ in study_recorded(inputs)] == [line]


def test_the_api_returns_the_same_lines(tmp_path, cache):
    rows = tlm.api.error_vs_cost(_experiment(tmp_path), tmp_path / "api", truth_spp=0)
    ref = json.loads((tmp_path / "api" / "reference.json").read_text())
    assert rows.attrs["warnings"] == ref["warnings"] and rows.attrs["warnings"][0] == FACES_NOTHING


# ---------------------------------------------------------------- a '{}' sidecar of the functional cache

CFG = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1},
       "arch": {"frames": 2, "trace": False}}


def test_a_sidecar_of_no_sidecars_shape_is_said_as_damaged(cache, capsys):
    cfg = config_from_dict(CFG, "test")
    clean = frames.cached_render(cfg)
    side = frames.cache_dir() / f"{clean.key}.json"
    whole = side.read_text()
    for text, why in (("{}", "(no format: not a functional-cache sidecar)"),
                      ('{"format": 5, "scene": {}}', "(format 5: not a functional-cache sidecar's)"),
                      ('{"format": "something/6"}', "(format \"something/6\": not a functional-cache sidecar's)")):
        side.write_text(text)
        capsys.readouterr()
        again = frames.cached_render(cfg)
        err = capsys.readouterr().err.strip().splitlines()
        assert err == [f"tlm: warning: damaged functional cache entry {side} {why}: removed, rendering it again"], err
        assert not again.cached and json.loads(side.read_text())["format"] == frames.SUMMARY_FORMAT
    side.write_text(json.dumps({**json.loads(whole), "format": "functional-summary/1"}))  # (an older tlm's: quiet)
    capsys.readouterr()
    assert not frames.cached_render(cfg).cached and capsys.readouterr().err == ""
