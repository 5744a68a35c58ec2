"""h546 (from probe h544): the report's figures as a paper's author reads them.

1. A frame in a PDF/SVG keeps its pixels (imshow interpolation "none"): a 320x320 render was stored
   resampled to the figure's dpi (~200 px).
2. summary_scaling.png's y label fits in the figure ("(static tiles unless named)" is in the caption now);
   its legend is under the plot, clear of the x label.
3. The yellow palette slot (1.3:1 on white) draws its markers with dark edges.
4. The granularity figure's packet-size labels do not overlap.
5./7. summary_tradeoff.png: its legend out of the axes, its frame time in ms as in §4's figures.
6. A sweep's x axis names the key and its unit where tlm knows them.
"""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgb

from tests.helpers_figures import capture
from tlm.cli import main
from tlm.config import describe
from tlm.report import common, images, summary, sweeps, tradeoff
from tlm.report.collect import Inputs, Study, read
from tlm.report.common import FigureName, figure_output, line_style


def _boxes(fig):
    FigureCanvasAgg(fig).draw()
    return fig.canvas.get_renderer()


def _under_the_x_label(ax, renderer) -> bool:
    """The axes' legend is under its x label (and so under its data and tick labels), inside the figure."""
    legend = ax.get_legend().get_window_extent(renderer)
    return ax.figure.bbox.y0 <= legend.y0 and legend.y1 <= ax.xaxis.label.get_window_extent(renderer).y0


# ------------------------------------------------------------------ 1: frames keep their pixels in vector formats


def test_a_frame_keeps_its_pixels_in_an_svg(tmp_path):
    frame = np.random.default_rng(3).integers(0, 256, (320, 320, 3), dtype=np.uint8)
    rows = [images.Row("r1", "320x320", [images.Panel(m, frame if m == images.MODES[0] else None)
                                          for m in images.MODES])]
    with figure_output(("png", "svg")):
        images._draw(rows, "frames", tmp_path, FigureName(("frames",)), "")
    (svg,) = tmp_path.glob("*.svg")
    sizes = re.findall(r'<image[^>]*?width="([\d.]+)"[^>]*?height="([\d.]+)"', svg.read_text())
    assert sizes == [("320", "320")], sizes  # (was ~163 x 163: resampled to the figure's dpi)


# ------------------------------------------------------------------ 2: the scaling figure's labels fit


@pytest.fixture(scope="module")
def n_sweep(tmp_path_factory):
    root = tmp_path_factory.mktemp("h546_scaling")
    base = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
            "arch": {"frames": 2, "trace": False}}
    (root / "n.yaml").write_text(yaml.safe_dump({"base": base, "grid": {"arch.pipelines": [1, 2]}}))
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        assert main(["sweep", str(root / "n.yaml"), "--out", str(root / "n"), "--jobs", "1", "--no-progress",
                     "--no-report"]) == 0
    return root / "n"


def test_the_scaling_figure_clips_no_label_and_its_legend_covers_none(n_sweep, tmp_path, monkeypatch):
    figs = capture(monkeypatch, summary)
    sec = summary.summary_section(read([n_sweep]), tmp_path)
    (i,) = [k for k, f in enumerate(sec.figures) if f.file == "summary_scaling.png"]
    fig, record = figs[i], sec.figures[i]
    renderer = _boxes(fig)
    whole = fig.bbox
    (ax,) = fig.axes
    for label in (ax.xaxis.label, ax.yaxis.label):
        box = label.get_window_extent(renderer)
        assert whole.x0 <= box.x0 and box.x1 <= whole.x1 and whole.y0 <= box.y0 and box.y1 <= whole.y1, (
            label.get_text(), box, whole)
    assert "static tiles" not in ax.get_ylabel() and "static tiles" in record.caption
    assert _under_the_x_label(ax, renderer)  # (was inside the axes, at loc "best")


# ------------------------------------------------------------------ 3: the yellow slot's markers


def _contrast_on_white(c) -> float:
    lin = [x / 12.92 if x <= 0.04045 else ((x + 0.055) / 1.055) ** 2.4 for x in to_rgb(c)]
    return 1.05 / (0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2] + 0.05)


def test_every_line_style_has_markers_edged_in_a_colour_that_shows_on_white():
    for i in range(len(common.COLOURS)):
        style = line_style(i)
        assert _contrast_on_white(style.get("markeredgecolor", style["color"])) >= 2.0, (i, style)


# ------------------------------------------------------------------ 4: the granularity figure's labels apart


def test_the_granularity_figure_labels_do_not_overlap(tmp_path, monkeypatch):
    figs = capture(monkeypatch, tradeoff)
    rows = [{"packet_size": n, "max_abs_rel_error": e, "simulate_seconds": s}
            for n, e, s in ((1, 0.0, 9.0), (256, 0.004, 1.0), (4096, 0.0201, 0.52), (16384, 0.02, 0.5))]
    tradeoff.granularity_figure([Study("granularity", Path("g"), rows)], tmp_path, "g.png", [])
    renderer = _boxes(figs[-1])
    (ax,) = figs[-1].axes
    boxes = [t.get_window_extent(renderer) for t in ax.texts if t.get_visible()]
    assert len(boxes) == 4
    assert not any(a.overlaps(b) for a, b in itertools.combinations(boxes, 2))
    assert _under_the_x_label(ax, renderer)


# ------------------------------------------------------------------ 5 and 7: the summary's error against frame time


def test_the_summary_tradeoff_figure_draws_ms_and_its_legend_out_of_the_axes(tmp_path, monkeypatch):
    from tests.test_report_honest_captions import _evc_rows

    figs = capture(monkeypatch, summary)
    rows = _evc_rows()
    summary.summary_section(Inputs([], studies=[Study("error-vs-cost", tmp_path / "ec", rows)]), tmp_path)
    (ax,) = figs[-1].axes
    assert ax.get_xlabel() == "simulated frame time TThru / clock (ms)"  # (as §4's figures: one unit)
    xs = sorted(x for line in ax.get_lines() for x in line.get_xdata() if line.get_label()[:1] != "_")
    assert xs == sorted(r["frame_seconds"] * 1e3 for r in rows)
    assert _under_the_x_label(ax, _boxes(figs[-1]))


# ------------------------------------------------------------------ 6: a sweep's axis names its key and unit


def test_a_sweep_axis_names_the_key_and_its_unit(tmp_path, monkeypatch):
    from tests.test_report_sweep_legend import sweep_folder

    figs = capture(monkeypatch, sweeps)
    sw = sweep_folder(tmp_path / "s", lambda p, f, s: 300.0 + p + 7.0 * f)
    sweeps.factor_figure(read([sw]).sweeps[0], "arch.fifo_depth", tmp_path, [])
    assert figs[-1].axes[0].get_xlabel() == "FIFO depth (arch.fifo_depth, entries)"
    keys = {k for k, _, _ in describe()}
    assert set(sweeps.AXIS_NAMES) <= keys, set(sweeps.AXIS_NAMES) - keys
    assert sweeps.axis_label("seed") == "seed"  # (a key tlm has no name for: the key alone)
