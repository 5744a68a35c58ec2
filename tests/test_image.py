"""Radiance to pictures (:mod:`tlm.render.image`): the exposure, the sRGB curve and the PNG file."""

from __future__ import annotations

import numpy as np
from PIL import Image

from tlm.render.image import auto_exposure, to_srgb8, write_png


def test_auto_exposure_maps_the_percentile_of_luminance_to_one():
    img = np.zeros((4, 5, 3))
    assert auto_exposure(img) == 1.0  # black: nothing to scale
    img[0, 0] = (2.0, 2.0, 2.0)  # luminance 2 (the weights sum to 1); the black pixels do not count
    assert auto_exposure(img) == 0.5
    img[1, :] = (0.0, 4.0, 0.0)  # luminance 0.7152 * 4, five pixels of six lit
    assert np.isclose(auto_exposure(img, percentile=50), 1.0 / (0.7152 * 4.0))
    assert np.isclose(auto_exposure(img, percentile=100), 1.0 / (0.7152 * 4.0))
    assert np.isclose(auto_exposure(img, percentile=0), 0.5)
    with np.errstate(invalid="ignore"):  # numpy's percentile of infinities is inf - inf
        assert auto_exposure(np.full((2, 2, 3), np.inf)) == 1.0  # an infinite level is no scale
    assert auto_exposure(-np.ones((2, 2, 3))) == 1.0  # nothing lit


def test_to_srgb8_applies_exposure_the_srgb_curve_and_clips():
    lin = np.array([[[0.0, 0.001, 0.5], [1.0, 2.0, -1.0], [np.nan, np.inf, -np.inf]]])
    out = to_srgb8(lin, 1.0)
    assert out.dtype == np.uint8 and out.shape == lin.shape
    half = round(255 * (1.055 * 0.5 ** (1 / 2.4) - 0.055))  # 188
    assert out.tolist() == [[[0, round(255 * 12.92 * 0.001), half], [255, 255, 0], [0, 255, 0]]]
    assert to_srgb8(np.full((1, 1, 3), 0.25), 2.0).tolist() == [[[half] * 3]]  # exposure scales first


def test_write_png_writes_the_pixels_exactly(tmp_path):
    rng = np.random.default_rng(1)
    rgb = rng.integers(0, 256, size=(3, 7, 3), dtype=np.uint8)
    write_png(tmp_path / "a.png", rgb[:, ::-1])  # a non-contiguous view is written as it reads
    with Image.open(tmp_path / "a.png") as im:
        assert im.format == "PNG" and im.mode == "RGB" and im.size == (7, 3)
        assert np.array_equal(np.asarray(im), rgb[:, ::-1])


def test_to_srgb8_in_blocks_is_the_whole_image_conversion(monkeypatch):
    from tlm.render import image

    rng = np.random.default_rng(3)
    lin = rng.random((7, 5, 3)) * 2.0
    lin[0, 0, 0], lin[3, 2, 1], lin[6, 4, 2] = np.nan, np.inf, -0.5
    whole = to_srgb8(lin, 0.8)
    monkeypatch.setattr(image, "SRGB_BLOCK", 4)  # blocks that cut pixels apart
    assert np.array_equal(image.to_srgb8(lin, 0.8), whole)
    assert image.to_srgb8(np.zeros((0, 3, 3)), 1.0).shape == (0, 3, 3)
