"""h505: photon paths that ``photons.max_bounces`` ends with power still travelling are said. The trace records
the power its photons still carried then (``results.json`` ``photons.cut_power``, RGB, summed exactly: the same
whichever threads and chunks traced them) and its luminance's share of the lights' power (``photons.cut_share``);
past :data:`~tlm.experiments.photon_warnings.CUT_SHARE` a run warns, naming photons.max_bounces and the share, and,
with final gathering and an error measured, that the run gathers one bounce past its reference (h500: a closed
box of albedo 0.8 at 8 bounces loses 0.8^8 of its light, and its frame was 0.877 of a path tracer's, unsaid)."""

from __future__ import annotations

import json

import pytest

import tlm
from tlm.config import config_from_dict
from tlm.experiments.frames import cached_render
from tlm.experiments.loading import load_frame
from tlm.experiments.photon_warnings import CUT_SHARE, cut_warnings
from tlm.experiments.run_warnings import reference_warnings
from tlm.kernels import threads
from tlm.kernels.photons import trace_photons

BOX = """name: box08
geometry:
  - shape: box
    name: room
    params: {min: [0.0, 0.0, 0.0], max: [1.0, 1.0, 1.0]}
materials:
  white: {type: lambertian, albedo: [0.8, 0.8, 0.8]}
parts: {room: white}
lights:
  - {type: quad, corner: [0.4, 0.999, 0.4], edge_u: [0.2, 0.0, 0.0], edge_v: [0.0, 0.0, 0.2], power: [3.0, 3.0, 3.0]}
camera: {eye: [0.5, 0.5, 0.05], target: [0.5, 0.5, 1.0], up: [0.0, 1.0, 0.0], vfov: 100.0}
resolution: [8, 8]
photons: 2000
"""
LINE = "photons.max_bounces {} ends photon paths that still carry {} of the lights' power"
PAST = "this run gathers one bounce past its reference"


@pytest.fixture
def box(tmp_path):
    path = tmp_path / "box08.yaml"
    path.write_text(BOX)
    frame = load_frame(config_from_dict({"scene": str(path), "mode": "pmap"}))
    return frame.scene, frame.accel


def _trace(box, n: int, **kw):
    return trace_photons(*box, n, seed=1, **kw).photons


def test_a_closed_grey_box_keeps_albedo_to_the_bounces_of_its_power_in_flight(box):
    # (Russian roulette on a grey albedo keeps a photon's power: the photons alive after 8 hits, 0.8^8 of them,
    # carry that share of the light's 3 W; nothing leaves a closed box)
    eight = _trace(box, 20000).stats()
    assert eight["cut_share"] == pytest.approx(0.8 ** 8, abs=0.01)
    assert eight["cut_power"] == pytest.approx([3.0 * eight["cut_share"]] * 3, rel=1e-9)
    assert _trace(box, 20000, max_bounces=30).stats()["cut_share"] < 0.005
    none = _trace(box, 1000, max_bounces=0)  # (no bounce: every path ends where it starts, all its power in flight)
    assert none.stats()["cut_share"] == pytest.approx(1.0) and none.cut_power == pytest.approx((3.0, 3.0, 3.0))


def test_the_cut_power_is_the_same_bits_on_any_threads_and_chunks(box):
    with threads.using(1):
        one = _trace(box, 12000, global_map=True)
    with threads.using(2):
        two = _trace(box, 12000, global_map=True, batch_rays=1)  # (chunks of 4096 photons, on two threads)
    assert one.cut_power == two.cut_power and one.cut_share == two.cut_share > 0.1
    assert one.stats()["stored_power"] == two.stats()["stored_power"]


def _cfg(**estimate):
    return config_from_dict({"scene": "cornell", "mode": "pmap", "photons": {"max_bounces": 3},
                             "estimate": estimate})


def test_the_line_past_the_share_and_its_words_on_the_reference():
    fg = _cfg()
    error = {"available": True, "reference": "abc", "reference_converged": True}
    assert CUT_SHARE == 0.05
    [line] = cut_warnings({"emitted": 1000, "cut_share": 0.0832}, fg)
    assert line.startswith(LINE.format(3, "8.3%")) and "raise photons.max_bounces" in line and PAST not in line
    [measured] = cut_warnings({"cut_share": 0.0832}, fg, error)
    assert measured.startswith(line) and f"{PAST} abc" in measured and "(estimate.final_gather 16)" in measured
    # (no final gathering: the run reads the indirect map at the eye's point, as its reference does)
    assert PAST not in cut_warnings({"cut_share": 0.0832}, _cfg(final_gather=0), error)[0]
    assert PAST not in cut_warnings({"cut_share": 0.0832}, fg, {"available": False, "reference": "abc"})[0]
    for quiet in ({"cut_share": CUT_SHARE}, {"cut_share": 0.0}, {"emitted": 1000}, 1000, None, {"cut_share": None}):
        assert cut_warnings(quiet, fg, error) == []
    # (said among the reference's lines, with its error: so a cached frame says it as its error has it)
    assert reference_warnings(error, fg, {"emitted": 1000, "caustic": 0, "cut_share": 0.0832}) == [measured]


TINY = {"mode": "pmap", "resolution": [8, 8], "render.spp": 1, "render.light_samples": 1,
        "photons.count": 2000, "photons.max_bounces": 2, "reference.photons": 2000, "reference.k_nearest": 20,
        "reference.spp": 1, "reference.min_rounds": 2, "reference.max_rounds": 4, "arch.packet_size": 16,
        "arch.frames": 2}


def test_a_run_and_its_cached_frame_say_it(tmp_path, cache):
    cfg = tlm.load_config("cornell", TINY)
    got = tlm.run(cfg, tmp_path / "r", outputs="images")
    share = got["photons"]["cut_share"]
    assert share > 0.1 and got["error"]["available"] and len(got["photons"]["cut_power"]) == 3
    [line] = [w for w in got["warnings"] if w.startswith("photons.max_bounces")]
    assert line.startswith(LINE.format(2, f"{share:.1%}")) and f"{PAST} {got['error']['reference']}" in line
    assert json.loads((tmp_path / "r" / "results.json").read_text())["warnings"] == got["warnings"]
    first = cached_render(cfg.settings, cfg.base, cfg.label)
    again = cached_render(cfg.settings, cfg.base, cfg.label)
    assert again.cached and first.summary["photons"]["cut_share"] == share
    assert [w for w in again.summary["warnings"] if w.startswith("photons.max_bounces")] == [line]
    # (at 8 bounces the Cornell box keeps 1.28% of its light in flight at its 120000 photons: under the share)
    quiet = tlm.run(tlm.load_config("cornell", {**TINY, "photons.max_bounces": 8}), tmp_path / "q", outputs="images")
    assert quiet["photons"]["cut_share"] < CUT_SHARE
    assert not [w for w in quiet["warnings"] if w.startswith("photons.max_bounces")]
