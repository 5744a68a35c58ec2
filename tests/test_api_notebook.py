"""The Python API as a notebook uses it: an ArchConfig given whole to simulate is checked as a
mapping of its keys is, to_srgb takes numpy scalars as the exposure, arguments of the wrong
kind are one-line InputErrors naming the argument, load_scene takes the resolution arrays
load_config takes, and a Config shows as one short line."""

from __future__ import annotations

import dataclasses
from fractions import Fraction

import numpy as np
import pytest

import tlm
from tlm import api

SMALL = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"spp": 1, "light_samples": 1}}


@pytest.fixture(scope="module")
def res(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(tmp_path_factory.mktemp("cache")))
        return tlm.render_image(SMALL)


BAD_ARCH = [  # (a key's value, the message simulate gives for it as a mapping)
    ({"clock_hz": float("nan")}, r"arch\.clock_hz: nan is not finite"),
    ({"clock_hz": 0.0}, r"arch\.clock_hz: 0\.0 must be >= 1\.0"),
    ({"memory": "nope"}, r"arch\.memory: nope is not one of swap, copy"),
    ({"tiles_per_pipeline": 0}, r"arch\.tiles_per_pipeline: 0 must be >= 1"),
    ({"frames": 0}, r"arch\.frames: 0 must be >= 1"),
    ({"pipelines": 0}, r"arch\.pipelines: 0 must be >= 1"),
    ({"pipelines": 2.5}, r"arch\.pipelines: 2\.5 is not an int"),
    ({"packet_size": 0}, r"arch\.packet_size: 0 must be >= 1"),
    ({"fifo_depth": 0}, r"arch\.fifo_depth: 0 must be >= 1"),
    ({"images_in_flight": 0}, r"arch\.images_in_flight: 0 must be >= 1"),
]


def test_an_archconfig_given_whole_is_checked_as_its_keys_are(res):
    for change, message in BAD_ARCH:
        whole = dataclasses.replace(res.cfg.arch, **change)
        with pytest.raises(tlm.InputError, match=rf"^\(simulate: arch\): {message}") as got:
            tlm.simulate(res, whole)
        with pytest.raises(tlm.InputError) as as_mapping:  # the same line as the mapping's
            tlm.simulate(res, change)
        assert str(got.value) == str(as_mapping.value) and "\n" not in str(got.value)
    # a good one simulates as its keys do
    assert tlm.simulate(res, res.cfg.arch).cycles == tlm.simulate(res).cycles
    two = dataclasses.replace(res.cfg.arch, pipelines=2, clock_hz=np.float64(3e8))
    assert tlm.simulate(res, two).to_dict() == tlm.simulate(res, {"pipelines": 2, "clock_hz": 3e8}).to_dict()


def test_to_srgb_takes_numpy_scalars_and_refuses_what_is_not_real():
    img = np.random.default_rng(0).random((4, 4, 3)).astype(np.float32)
    plain = tlm.to_srgb(img, 2.0)
    for exposure in (np.float32(2.0), np.int64(2), np.float16(2.0), np.uint8(2), Fraction(2)):
        assert np.array_equal(tlm.to_srgb(img, exposure), plain), exposure
    assert tlm.to_srgb(img, np.percentile(img, 99)).dtype == np.uint8
    for exposure in (np.float32("nan"), np.float64("inf"), np.int64(-1), np.bool_(True), 10**400, 2j, "2"):
        with pytest.raises(tlm.InputError, match=r"^exposure: .* is not a finite number >= 0"):
            tlm.to_srgb(img, exposure)
    with pytest.raises(tlm.InputError, match=r"^radiance: an array of shape \(2, 2, 3\) and dtype complex128 is not "
                                             r"RGB radiance"):
        tlm.to_srgb(np.ones((2, 2, 3), dtype=complex))


def test_arguments_of_the_wrong_kind_are_named(res, tmp_path):
    with pytest.raises(tlm.InputError, match=r"^programs: 123 is not an instruction-cost table"):
        tlm.simulate(res, programs=123)
    with pytest.raises(tlm.InputError, match=r"^out: None is not a folder's path"):
        tlm.run(SMALL, None)
    sweep = tmp_path / "s.yaml"
    sweep.write_text("base: {scene: cornell, mode: rcast, resolution: [8, 8]}\ngrid:\n  arch.pipelines: [1, 2]\n")
    for jobs in (1.5, "2", True):
        with pytest.raises(tlm.InputError, match=rf"^jobs: {jobs!r} is not a whole number of worker processes"):
            tlm.sweep(sweep, tmp_path / "out", jobs=jobs)
    with pytest.raises(tlm.InputError, match=r"^out: None is not a folder's path"):
        tlm.run_sweep(sweep, None, jobs=1)
    assert not (tmp_path / "out").exists()


def test_load_scene_takes_the_resolutions_load_config_takes():
    for resolution in (np.array([8, 6]), (8, 6), [np.int64(8), np.int64(6)]):
        camera = tlm.load_scene("cornell", resolution=resolution).camera
        assert (camera.width, camera.height) == (8, 6)
        assert tlm.load_config({"scene": "cornell", "resolution": resolution}).resolution == (8, 6)
    with pytest.raises(tlm.InputError, match=r"^\(load_scene\): resolution: \[8\.5, 8\.0\] is not \[width, height\]"):
        tlm.load_scene("cornell", resolution=np.array([8.5, 8]))


def test_a_config_shows_as_one_short_line():
    cfg = tlm.load_config("cornell", {"mode": "reflect", "resolution": [16, 16], "render.spp": 1,
                                      "render.light_samples": 1, "seed": 3})
    text = repr(cfg)
    assert "\n" not in text and len(text) < 300
    assert text.startswith(f"Config(source={cfg.source!r}, overrides=[mode=\"reflect\", resolution=[16, 16], ")
    assert text.endswith("... 1 more], scene='cornell', mode='reflect', resolution=[16, 16], seed=3)")
    assert repr(api.load_config({"scene": "ring"})) == "Config(source=None, scene='ring', mode='refract', " \
                                                        "resolution=[320, 240] (the scene's), seed=0)"
