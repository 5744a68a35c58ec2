"""The pixels error-vs-cost compares with Mitsuba's truth (h472): a highlight our few eye rays miss
but Mitsuba's box filter sees is left out, and one pixel carrying most of the error is named."""

from __future__ import annotations

import numpy as np

from tlm.config import config_from_dict
from tlm.kernels.traverse import build_accel
from tlm.oracle import mitsuba as om
from tlm.oracle.masks import light_footprint
from tlm.render.frame import Frame, cast
from tlm.render.passes import sees_a_light
from tlm.scenes.loader import load_scene


def _frame(size: int = 24) -> Frame:
    scene = load_scene("cornell", resolution=[size, size])
    cfg = config_from_dict({"scene": "cornell", "resolution": [size, size], "render": {"spp": 1}})
    return Frame.create(scene, build_accel(scene.triangles), cfg)


def test_footprint_finds_the_light_seen_between_the_samples():
    frame = _frame()
    cam = frame.scene.camera
    centre = sees_a_light(frame, cast(frame, np.arange(cam.width * cam.height), record=False))
    centre = centre.reshape(cam.height, cam.width)
    fine = light_footprint(frame, 4)
    assert np.all(fine[centre])  # (every pixel one centre ray shows a light at is in)
    assert fine.sum() > centre.sum()  # (and the light's and highlights' edge pixels the centres miss)
    keep = om.truth_mask(frame, centre)
    assert keep.sum() < om.away_from_lights(centre).sum() and not np.any(keep & fine)


def test_one_pixel_carrying_the_error_is_named():
    truth = np.full((30, 40, 3), 0.2)
    ours = truth * 1.01
    assert om.dominant_pixel(ours, truth, np.ones((30, 40), dtype=bool)) is None
    truth[18, 15] = 4.1  # (the light in the mirror sphere, in the truth only: h466)
    line = om.dominant_pixel(ours, truth, np.ones((30, 40), dtype=bool))
    assert line is not None and "(x 15, y 18)" in line and "4.1" in line
    keep = np.ones((30, 40), dtype=bool)
    keep[18, 15] = False
    assert om.dominant_pixel(ours, truth, keep) is None
