"""The report's difference panel (a run's PMap frame minus its reference) keeps the sign of the
difference in greyscale: its two ends differ in grey, its zero is a neutral grey between them,
and its colour bar is the map of the image it stands beside."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

import tlm.report.images as images
from tests.helpers_figures import capture
from tlm.experiments.reference import DIFFERENCE_COLOURS, DIFFERENCE_COLOURS_BEFORE, difference_image
from tlm.report.collect import Run

GREY = np.array([0.299, 0.587, 0.114])  # a greyscale print's (and PIL's "L") weights
SCALE = 0.5


def error_run(folder: Path, diff_rgb: np.ndarray) -> Run:
    """A run folder with a PMap frame, the difference image ``diff_rgb`` and a measured error."""
    (folder / "images").mkdir(parents=True)
    Image.fromarray(np.full(diff_rgb.shape, 128, np.uint8)).save(folder / "images" / "pmap.png")
    Image.fromarray(diff_rgb).save(folder / "images" / "pmap_error.png")
    error = {"available": True, "rel_mse": 0.01, "rmse": 0.02, "difference_scale": SCALE, "reference": "r",
             "reference_converged": True, "reference_rounds": 4, "reference_standard_error": 0.001}
    return Run(folder, "run1: cornell/pmap", "run", {"error": error, "scene": {"name": "cornell"}, "timing": {}}, {})


def ramp() -> np.ndarray:
    """(4, 9) luminance differences from -SCALE to +SCALE along each row."""
    return np.tile(np.linspace(-SCALE, SCALE, 9), (4, 1))


def drawn(tmp_path: Path, monkeypatch, diff_rgb: np.ndarray):
    """The matplotlib figure and the report's record of :func:`error_figure` of a run with ``diff_rgb``."""
    figs = capture(monkeypatch, images)
    (tmp_path / "rep").mkdir()
    record = images.error_figure(error_run(tmp_path / "run1", diff_rgb), tmp_path / "rep")
    return figs[0], record


def written(diff: np.ndarray) -> np.ndarray:
    """The difference image a run writes of the luminance differences ``diff``, at SCALE."""
    rgb, scale = difference_image(np.repeat(diff[..., None], 3, axis=2), np.zeros((*diff.shape, 3)), SCALE)
    assert scale == SCALE
    return rgb


def test_the_panels_two_ends_differ_in_grey_and_zero_is_a_neutral_grey_between(tmp_path, monkeypatch):
    fig, _ = drawn(tmp_path, monkeypatch, written(ramp()))
    panel = fig.axes[1].images[0]
    rgba = np.asarray(panel.to_rgba(panel.get_array()), dtype=np.float64)  # (the colours as drawn, 0-1 or 0-255)
    rgb = rgba[..., :3] / (255.0 if rgba.max() > 1.0 else 1.0)
    grey = rgb @ GREY
    low, zero, high = grey[0, 0], grey[0, 4], grey[0, -1]
    assert abs(high - low) > 0.4, (low, high)  # (the blue and red of before: 0.35 and 0.28)
    assert min(low, high) + 0.15 < zero < max(low, high) - 0.15, (low, zero, high)
    assert np.ptp(rgb[0, 4]) < 0.02, rgb[0, 4]  # zero: neutral, no hue
    steps = np.diff(grey[0])
    assert np.all(steps > 0) or np.all(steps < 0), grey[0]  # each grey one difference: the sign survives


def test_the_colour_bar_is_the_map_of_the_values_drawn(tmp_path, monkeypatch):
    fig, record = drawn(tmp_path, monkeypatch, written(ramp()))
    panel = fig.axes[1].images[0]
    assert panel.colorbar is not None  # (the bar is made from the panel itself: one map for both)
    assert panel.norm.vmin == -SCALE and panel.norm.vmax == SCALE
    values = np.asarray(panel.get_array(), dtype=np.float64)
    assert values.shape == (4, 9)
    assert np.allclose(values, ramp(), atol=SCALE / 100)  # (read back from the 8-bit image)
    assert "light yellow where brighter" in record.caption and "greyscale" in record.caption
    assert (tmp_path / "rep" / record.file).is_file()


def test_an_image_in_other_colours_is_shown_as_written_and_said(tmp_path, monkeypatch):
    odd = np.zeros((4, 9, 3), np.uint8)
    odd[..., 1] = 200  # (green: on no segment of the run's difference colours)
    fig, record = drawn(tmp_path, monkeypatch, odd)
    panel = fig.axes[1].images[0]
    assert panel.colorbar is None
    assert np.array_equal(np.asarray(panel.get_array()), odd)
    assert "as the run wrote it" in record.caption and "no colour bar" in record.caption


def test_signed_difference_reads_back_every_value_of_the_runs_map():
    diff = np.linspace(-SCALE, SCALE, 201)[None, :]
    back = images.signed_difference(written(diff), DIFFERENCE_COLOURS)
    assert back is not None and np.allclose(back * SCALE, diff, atol=SCALE / 100)
    assert images.signed_difference(np.zeros((0, 0, 3), np.uint8), DIFFERENCE_COLOURS) is None


def test_a_run_written_in_the_colours_of_before_is_read_back_and_drawn_in_the_new(tmp_path, monkeypatch):
    """A run folder made before the colours changed (blue, white, red) is read back with them
    and drawn in the new map, with its colour bar."""
    monkeypatch.setattr("tlm.experiments.reference.DIFFERENCE_COLOURS", DIFFERENCE_COLOURS_BEFORE)
    old = written(ramp())
    monkeypatch.undo()
    assert images.signed_difference(old, DIFFERENCE_COLOURS) is None
    fig, record = drawn(tmp_path, monkeypatch, old)
    panel = fig.axes[1].images[0]
    assert panel.colorbar is not None and np.allclose(np.asarray(panel.get_array(), dtype=np.float64), ramp(),
                                                       atol=SCALE / 100)
    assert "light yellow where brighter" in record.caption


def test_the_runs_own_difference_image_keeps_the_sign_in_grey():
    """images/pmap_error.png as a run writes it: its grey rises from -scale to +scale."""
    grey = written(ramp())[0].astype(np.float64) / 255.0 @ GREY
    assert np.all(np.diff(grey) > 0) and grey[-1] - grey[0] > 0.4, grey
