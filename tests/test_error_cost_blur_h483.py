"""h483: ``tlm error-vs-cost`` says when its reference is blurrier than its points (found by the review h478).

``tlm run`` warns where its reference's k-NN kernel gathers over more than BLUR_RATIO x the area of its own on a
photon map (tlm.experiments.run_warnings.blur_warnings), but the study, where a blurry reference matters most,
never said it: its points did not go through that check and its reference.json kept no such warning. Now one line,
once per study after its points ran (tlm.experiments.error_cost_blur.StudyBlur), names how many points pass the
ratio and the worst (its photons, the map, the ratio, the reference.photons to give); it is said on stderr as
the study's other warnings are and kept in reference.json's ``warnings``, which the report's warnings box lists.
The committed configs/error_vs_cost.yaml stays silent (its worst point, knn of 120,000 photons and k_nearest 25,
is at 4.0x, not past it)."""

from __future__ import annotations

import json
from pathlib import Path

import tlm.experiments.error_cost as ec
from tests.scenes import sphere_scene
from tests.test_installed_copy_leftovers import REFERENCE
from tlm.cli import main
from tlm.config import apply_overrides, config_from_dict
from tlm.experiments.error_cost_blur import StudyBlur
from tlm.report.collect import read
from tlm.report.warnings import study_recorded

BLUR = "measured against a reference"  # (how the study's blur line goes on, after its count of points)


def _experiment(tmp_path: Path, counts: list[int]) -> Path:
    """tests/scenes.py's furnace (no mirror or glass: every photon the indirect map) at 16 x 16, seen from
    inside, a point per photon count, against the small reference of tests/test_installed_copy_leftovers.py
    (800 photons a round, k_nearest 20); each point's density rule holds 100 photons (radius_photons), so a
    point's ratio is 20 x its count / (800 x 100): past 4x from 16,000 photons on."""
    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({
        "base": {"scene": "furnace.yaml", "resolution": [16, 16], "reference": REFERENCE,
                 "estimate": {"final_gather": 0}, "render": {"spp": 1}},
        "points": [{"photons.count": counts}]}))
    return exp


def _blur(lines: list[str]) -> list[str]:
    return [line for line in lines if BLUR in line]


def test_a_study_whose_reference_is_blurrier_than_its_points_says_so_once(tmp_path, cache):
    said: list[str] = []
    out = tmp_path / "out"
    rows = ec.run_error_vs_cost(_experiment(tmp_path, [800, 20000, 40000]), out, truth=ec.Truth(spp=0),
                                warned=said.append)
    assert len(rows) == 3
    ref = json.loads((out / "reference.json").read_text())
    (line,) = _blur(said)  # (once for the study, not once per point: 2 points pass)
    assert line.startswith(f"error-vs-cost: 2 of the 3 points are {BLUR} {ref['key']} "), line
    assert "the worst, point 2 (photons.count=40000): its indirect map gets 40000 of the 40000 photons it emits" \
        in line, line
    assert "that map of the reference gets 800 a round (reference.photons 800)" in line, line
    assert "(20 photons: reference.k_nearest) gathers over 10.00x the area of its gathers of 100 " \
           "(estimate.radius_photons)" in line, line
    assert "raise the base's reference.photons to 2000 or more" in line, line  # (800 x 10 / 4: every point within)
    # kept where the study keeps its warnings, once, and listed by the report's warnings box
    assert _blur(ref["warnings"]) == [line]
    (study,) = read([out]).studies
    inputs = type("Inputs", (), {"studies": [study], "runs": [], "damaged": []})()
    assert _blur([text for text, _, _ in study_recorded(inputs)]) == [line]


def test_a_study_under_the_ratio_says_nothing(tmp_path, cache, monkeypatch):
    made: list[StudyBlur] = []  # (the study's weighing: each of its points weighed, none past the ratio)
    monkeypatch.setattr(ec, "StudyBlur", lambda *a, **k: made.append(StudyBlur(*a, **k)) or made[-1])
    said: list[str] = []
    out = tmp_path / "out"
    ec.run_error_vs_cost(_experiment(tmp_path, [800, 16000]), out, truth=ec.Truth(spp=0), warned=said.append)
    assert _blur(said) == [] and _blur(json.loads((out / "reference.json").read_text())["warnings"]) == []
    (blur,) = made
    assert blur.seen == 2 and blur.passed == [] and blur.line() is None  # (16,000 photons: 4.0x, not past it)


def test_only_the_points_past_the_ratio_are_counted(tmp_path, cache):
    said: list[str] = []
    ec.run_error_vs_cost(_experiment(tmp_path, [800, 16000, 16400]), tmp_path / "out", truth=ec.Truth(spp=0),
                         warned=said.append)
    (line,) = _blur(said)
    assert line.startswith(f"error-vs-cost: 1 of the 3 points is {BLUR} "), line
    assert "point 2 (photons.count=16400)" in line and " 4.10x the area " in line, line
    assert "reference.photons to 820 or more" in line, line


def test_the_cli_says_it_once_on_stderr(tmp_path, cache, capsys):
    out = tmp_path / "out"
    assert main(["error-vs-cost", str(_experiment(tmp_path, [20000, 40000])), "--out", str(out), "--truth-spp", "0",
                 "--no-report", "--no-progress"]) == 0
    (line,) = _blur(capsys.readouterr().err.splitlines())
    assert line.startswith(f"tlm: warning: error-vs-cost: 2 of the 2 points are {BLUR} "), line
    assert _blur(json.loads((out / "reference.json").read_text())["warnings"]) == [line.removeprefix("tlm: warning: ")]


def test_the_committed_study_is_under_the_ratio():
    """configs/error_vs_cost.yaml's points, weighed by their traced photons (each distinct map traced once) against
    its reference (the scene's 120,000 photons, k_nearest 100): none past the ratio, the worst at 4.0x."""
    from tlm.experiments.loading import load_frame
    from tlm.render.frame import Frame
    from tlm.render.pmap import trace_photon_map

    base, points, folder = ec.load_experiment(Path(__file__).resolve().parents[1] / "configs" / "error_vs_cost.yaml")
    cfg0 = config_from_dict({**base, "mode": "pmap"}, "error_vs_cost")
    frame = load_frame(cfg0, folder, "error_vs_cost")
    blur, traced = StudyBlur(frame.scene.photons, "key"), {}
    for i, p in enumerate(points):
        cfg = config_from_dict({**apply_overrides(base, ec._override_strings(p)), "mode": "pmap"}, "error_vs_cost")
        got = (cfg.photons.count, cfg.photons.caustic_count, cfg.estimate.final_gather > 0)
        if got not in traced:
            traced[got] = trace_photon_map(Frame.create(frame.scene, frame.accel, cfg)).photons
        blur.add(i, ec.factors_text(p), cfg, traced[got])
    assert blur.seen == len(points) and blur.passed == [] and blur.line() is None
