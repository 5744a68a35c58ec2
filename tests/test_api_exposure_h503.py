"""The API's image is the run's image (h503): ``tlm.to_srgb(res)`` is ``images/composite.png``'s pixels and
``tlm.to_srgb(res.radiance[p], res.exposure)`` ``images/<p>.png``'s, at the run's one exposure
(``RenderResult.exposure``: ``render.exposure``, else automatic over the pixels that do not see a light
directly), where a probe (h499) found ``tlm.to_srgb(res.composite)`` far darker than the PNG in a scene with a
light in view; and ``to_srgb`` of radiance partly infinite is quiet (numpy's "invalid value" RuntimeWarning
leaked)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from PIL import Image

import tlm
from tlm.experiments.run import write_run

SCENE = {"scene": "cornell", "mode": "reflect", "resolution": [16, 16], "render": {"spp": 1, "light_samples": 1}}


@pytest.mark.slow
@pytest.mark.parametrize("exposure", [None, 1.7])
def test_the_api_image_is_the_png_of_the_run(tmp_path, cache, exposure):
    res = tlm.render_image({**SCENE, "render": {**SCENE["render"], "exposure": exposure}})
    assert res.primary.sees_light.any()  # (a light in view: the exposure over all pixels is not the run's)
    out = tmp_path / "run"
    write_run(res, out, outputs=())
    png = {p.stem: np.asarray(Image.open(p).convert("RGB")) for p in (out / "images").glob("*.png")}
    recorded = json.loads((out / "results.json").read_text())["image"]["exposure"]
    assert res.exposure == recorded == (exposure or recorded)
    rgb = tlm.to_srgb(res)
    assert rgb.dtype == np.uint8 and rgb.shape == (16, 16, 3)
    assert np.array_equal(rgb, png["composite"])
    for name in ("rcast", "reflect"):
        assert np.array_equal(tlm.to_srgb(res.radiance[name], res.exposure), png[name]), name
    assert np.array_equal(tlm.to_srgb(res, 0.5), tlm.to_srgb(res.composite, 0.5))  # (an exposure given: that one)


def test_to_srgb_of_partly_infinite_radiance_warns_of_nothing():
    rad = np.full((4, 4, 3), 0.25)
    rad[0, 0] = np.inf
    rad[1, 1] = np.inf
    rad[2, 2] = [np.inf, -np.inf, 0.5]  # (inf - inf in the luminance)
    for exposure in (None, 0.0, 2.0):  # (automatic: inf - inf in the percentile; 0: inf * 0)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            rgb = tlm.to_srgb(rad, exposure)
        assert rgb.dtype == np.uint8 and rgb.shape == (4, 4, 3)
        assert (rgb[0, 0] == (0 if exposure == 0.0 else 255)).all(), exposure  # (infinite: white, but at 0)
