"""h529: ``photons.cut_share`` of the light that reached the scene, error-vs-cost's points and its line, and two of
the API's words.

* The share's denominator was all the power the global group emitted: in an open scene most of a directional
  light's disc (which covers the scene's bounding sphere) or a point light's cone misses the scene at once, so the
  share of the light cut at ``photons.max_bounces`` was understated (an open well of albedo 0.8 under a directional
  light: 2.2% said, under the warning's 5%, for 10.7% of the light that entered it). Now the power of the photons
  whose first ray hit something (:func:`tlm.kernels.photons.reached`), the same rule for every light.
* ``tlm error-vs-cost`` never carried the share: its rows now have ``cut_share`` and the study says, once, which
  points pass :data:`~tlm.experiments.photon_warnings.CUT_SHARE` (kept in ``reference.json``'s ``warnings``).
* ``results.json``'s ``error.hint`` named the command alone; ``Timing.to_dict()`` said ``events`` where
  ``results.json``'s ``timing`` says ``simpy_events`` (and had no ``event_bound``)."""

from __future__ import annotations

import csv
import json

import pytest

import tlm
from tests.test_installed_copy_leftovers import REFERENCE
from tlm.config import config_from_dict
from tlm.experiments import error_cost as ec
from tlm.experiments.loading import load_frame
from tlm.experiments.photon_warnings import CUT_SHARE, cut_warnings
from tlm.experiments.run import error_against
from tlm.experiments.run_warnings import emitted_photons
from tlm.kernels.photons import LUMINANCE, trace_photons

# a well open at the top, 1 x 2 x 1 (y up), grey: its only way out is its opening, y = 2, x and z in [0, 1]
WELL = """name: well
geometry:
  - {shape: quad, name: floor, params: {corner: [0, 0, 0], edge_u: [1, 0, 0], edge_v: [0, 0, 1]}}
  - {shape: quad, name: w0, params: {corner: [0, 0, 0], edge_u: [0, 2, 0], edge_v: [1, 0, 0]}}
  - {shape: quad, name: w1, params: {corner: [0, 0, 1], edge_u: [1, 0, 0], edge_v: [0, 2, 0]}}
  - {shape: quad, name: w2, params: {corner: [0, 0, 0], edge_u: [0, 0, 1], edge_v: [0, 2, 0]}}
  - {shape: quad, name: w3, params: {corner: [1, 0, 0], edge_u: [0, 2, 0], edge_v: [0, 0, 1]}}
materials:
  white: {type: lambertian, albedo: [0.8, 0.8, 0.8]}
parts: {floor: white, w0: white, w1: white, w2: white, w3: white}
lights:
  - LIGHT
camera: {eye: [0.5, 3.0, 0.5], target: [0.5, 0.0, 0.5], up: [0.0, 0.0, 1.0], vfov: 40.0}
resolution: [8, 8]
photons: 2000
"""
SUN = "{type: directional, direction: [0.0, -1.0, 0.0], irradiance: [2.0, 2.0, 2.0]}"
# half a unit above the opening's centre: the opening (2a x 2a, a = d = 0.5) takes 4 asin(a^2 / (a^2 + d^2)) =
# 2 pi / 3 of its 4 pi steradians, a sixth of its power; none of the rest reaches the well's outside
BULB = "{type: point, position: [0.5, 2.5, 0.5], power: [6.0, 6.0, 6.0]}"


def _well(tmp_path, light: str = SUN):
    path = tmp_path / "well.yaml"
    path.write_text(WELL.replace("LIGHT", light))
    return path


def _lum(rgb) -> float:
    return sum(w * x for w, x in zip(LUMINANCE, rgb, strict=True))


@pytest.mark.parametrize(("light", "entered"), [(SUN, 2.0), (BULB, 1.0)], ids=["directional", "point"])
def test_the_share_is_of_the_light_that_reached_the_scene_for_every_light(tmp_path, light, entered):
    frame = load_frame(config_from_dict({"scene": str(_well(tmp_path, light)), "mode": "pmap"}))
    ph = trace_photons(frame.scene, frame.accel, 40000, seed=1).photons
    # (the cut power over the light that entered the opening, as the geometry gives it: 2 W/m^2 x 1 m^2, 6 W / 6;
    # the old code's share was over the directional light's whole disc, 2.2%, and over the point light's cone about
    # the well's box, 4.9%: both unsaid)
    assert ph.cut_share == pytest.approx(_lum(ph.cut_power) / entered, rel=0.04)
    if light == SUN:
        assert 0.09 < ph.cut_share < 0.13 and ph.cut_share > CUT_SHARE
    # (no bounce: every path ends before its first ray, all its power in flight, none gone)
    assert trace_photons(frame.scene, frame.accel, 1000, seed=1, max_bounces=0).photons.cut_share == pytest.approx(1.0)


def test_a_render_of_the_open_well_under_the_sun_says_it(tmp_path, cache):
    cfg = tlm.load_config(str(_well(tmp_path)), {"mode": "pmap", "photons.count": 20000, "render.spp": 1})
    res = tlm.render_image(cfg)
    photons = emitted_photons(res)
    assert photons["cut_share"] > CUT_SHARE
    [line] = cut_warnings(photons, cfg.settings)
    assert line.startswith(f"photons.max_bounces 8 ends photon paths that still carry {photons['cut_share']:.1%} of "
                           "the lights' power that reached the scene (results.json photons.cut_share)")


def test_an_error_vs_cost_study_carries_the_share_and_says_its_points_once(tmp_path, cache):
    _well(tmp_path)
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({
        "base": {"scene": "well.yaml", "resolution": [8, 8], "photons": {"count": 4000}, "reference": REFERENCE,
                 "render": {"spp": 1}},
        "points": [{"estimate.final_gather": [0, 4]}],
    }))
    said: list[str] = []
    out = tmp_path / "out"
    rows = ec.run_error_vs_cost(exp, out, truth=ec.Truth(spp=0), warned=said.append)
    assert ec.COLUMNS[-1] == "cut_share"  # (appended: the columns before keep their places)
    frame = load_frame(config_from_dict({"scene": str(tmp_path / "well.yaml"), "mode": "pmap",
                                         "photons": {"count": 4000}}))
    share = trace_photons(frame.scene, frame.accel, 4000, seed=0).photons.cut_share
    assert [r["cut_share"] for r in rows] == [share, share] and share > CUT_SHARE  # (with a global map or not)
    with open(out / "rows.csv", newline="") as fh:
        cells = list(csv.DictReader(fh))
    assert [float(c["cut_share"]) for c in cells] == [share, share]
    [line] = [w for w in said if "photons.max_bounces" in w]
    assert line.startswith(f"error-vs-cost: 2 of the 2 points are traced with photon paths that photons.max_bounces 8 "
                           f"ends still carrying more than 5% of the lights' power that reached the scene (rows' "
                           f"cut_share), points 0 and 1; the most, point 0 (estimate.final_gather=0): {share:.1%}; ")
    ref = json.loads((out / "reference.json").read_text())
    assert f"with final gathering (point 1) a point gathers one bounce past its reference {ref['key']}" in line
    assert ref["warnings"].count(line) == 1


def test_the_study_line_names_only_the_points_past_the_share():
    from tlm.experiments.photon_warnings import study_cut_line

    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "photons": {"max_bounces": 3}})
    rows = [{"point": 0, "factors": "photons.count=1000", "cut_share": 0.02, "final_gather": 16},
            {"point": 1, "factors": "photons.count=2000", "cut_share": 0.081, "final_gather": 0},
            {"point": 2, "factors": "photons.count=3000"},  # (a row of an older study: not weighed)
            {"point": 3, "factors": "photons.count=4000", "cut_share": 0.07, "final_gather": 0}]
    line = study_cut_line(rows, cfg, "abc")
    assert line.startswith("error-vs-cost: 2 of the 3 points are traced with photon paths that photons.max_bounces 3")
    assert "points 1 and 3; the most, point 1 (photons.count=2000): 8.1%; their photon-map frames" in line
    assert "final gathering" not in line  # (point 0, gathered, is under the share)
    assert study_cut_line(rows[:1], cfg, "abc") is None and study_cut_line([], cfg, "abc") is None


def test_the_hint_names_the_command_and_the_api_call():
    hint = error_against("abc", None, None, None, None)["hint"]
    assert "'tlm reference CONFIG'" in hint and "tlm.reference(config)" in hint
    assert callable(tlm.reference)


def test_timing_to_dict_names_its_figures_as_results_json_does(tmp_path, cache):
    cfg = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1},
           "arch": {"trace": False, "packet_size": 16, "frames": 2}}
    got = tlm.run(cfg, tmp_path / "r", outputs="images")
    timing = got["timing"]
    mine = json.loads(json.dumps(tlm.simulate(tlm.render_image(cfg)).to_dict()))  # (as results.json's JSON)
    assert mine["simpy_events"] == mine["events"] == timing["simpy_events"] > 0
    assert mine["event_bound"] == timing["event_bound"] > 0
    shared = set(mine) & set(timing)
    assert shared == set(mine) - {"cycles", "fps", "events"}  # (those three: results.json's top, and the old name)
    assert set(timing) - shared == {"clock_hz", "packet_size", "frames", "frames_asked", "images_in_flight", "memory",
                                    "programs"}  # (the config's, which no Timing holds)
    assert {k: mine[k] for k in shared} == {k: timing[k] for k in shared}
    assert mine["cycles"] == got["cycles"] and mine["fps"] == got["fps"]
