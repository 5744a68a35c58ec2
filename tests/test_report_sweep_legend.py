"""The FPS-against-a-factor figure of a sweep whose lines coincide: laid out, no matplotlib warning.

A sweep of 24 points at 16x16 over the packet size, the FIFO depth and the seed draws,
against the packet size, 8 combinations of the other two that give one line: their
legend label named all 8 and was wider than the figure, so that matplotlib's constrained
layout gave up ("axes sizes collapsed to zero") and printed a UserWarning to the user's
terminal, and the PNG showed a sliver of a plot. The sweep folders here hold the rows
only (``sweep.yaml``, ``sweep.jsonl``): all that the figure reads.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import yaml
from matplotlib.image import imread

from tlm.report import build_report
from tlm.report.collect import read
from tlm.report.sweeps import factor_figure

PACKETS = (1, 16, 256)
FIFOS = (1, 16, 256, 4096)
SEEDS = (0, 1)


def sweep_folder(folder: Path, fps_of) -> Path:
    """A 24-point sweep (packet size x FIFO depth x seed) whose point (p, f, s) ran at ``fps_of(p, f, s)``."""
    folder.mkdir(parents=True)
    grid = {"arch.packet_size": list(PACKETS), "arch.fifo_depth": list(FIFOS), "seed": list(SEEDS)}
    (folder / "sweep.yaml").write_text(yaml.safe_dump({"sweep": "s24.yaml", "description": "16x16 Cornell RCast",
                                                       "grid": grid}))
    rows = []
    for i, (p, f, s) in enumerate((p, f, s) for p in PACKETS for f in FIFOS for s in SEEDS):
        fps = fps_of(p, f, s)
        rows.append({"point": i, "hash": f"h{i:02d}", "status": "ok", "arch.packet_size": p, "arch.fifo_depth": f,
                     "seed": s, "scene": "cornell", "mode": "rcast", "fps": fps, "cycles.throughput": 6e8 / fps,
                     "cycles.traversal": 1000, "cycles.intersection": 900})
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


def plot_size(png: Path) -> tuple[int, int]:
    """Height and width in pixels of the PNG's plot, between the sides of the axes' black frame: the
    first and last pixel rows (columns) that are dark over at least a quarter of the image's width
    (height). A plot squeezed to a sliver has no such sides."""
    px = np.asarray(imread(png), dtype=float)[..., :3].mean(axis=2)
    dark = px < 0.2
    cols = np.flatnonzero(dark.sum(axis=0) > 0.25 * dark.shape[0])  # the frame's vertical sides
    rows = np.flatnonzero(dark.sum(axis=1) > 0.25 * dark.shape[1])  # its horizontal sides
    assert cols.size >= 2 and rows.size >= 2, f"{png.name}: no axes frame"
    return int(rows[-1] - rows[0]), int(cols[-1] - cols[0])


def build_quietly(folder: Path, out: Path) -> Path:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a UserWarning from the layout engine fails the report
        return build_report([folder], out)


def test_identical_lines_of_a_24_point_sweep_are_laid_out_without_warning(tmp_path):
    sw = sweep_folder(tmp_path / "s24", lambda p, f, s: 414.35 + 0.01 * p)  # FIFO and seed change nothing
    build_quietly(sw, tmp_path / "rep")
    png = tmp_path / "rep" / "sweep_s24_arch_packet_size.png"
    h, w = plot_size(png)
    assert h > 250 and w > 550, f"{png.name}: the plot is {w} x {h} pixels"
    assert "sweep_s24_arch_packet_size.png" in (tmp_path / "rep" / "report.html").read_text(encoding="utf-8")


def test_the_figure_alone_warns_nothing(tmp_path):
    """The figure by itself (as ``tlm sweep`` draws it in its report), warnings as errors."""
    sw = sweep_folder(tmp_path / "s24", lambda p, f, s: 414.35 + 0.01 * p)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fig = factor_figure(read([sw]).sweeps[0], "arch.packet_size", tmp_path, [])
    assert fig is not None and (tmp_path / fig.file).is_file()


def test_a_long_irregular_label_is_wrapped_under_the_plot(tmp_path):
    """7 of the 8 combinations coincide but are not every combination of some values: their label
    lists all 7 (about 200 characters) and is wrapped; the plot keeps its size."""
    sw = sweep_folder(tmp_path / "odd", lambda p, f, s: 300.0 + p + (5.0 if (f, s) == (4096, 1) else 0.0))
    build_quietly(sw, tmp_path / "rep")
    png = tmp_path / "rep" / "sweep_odd_arch_packet_size.png"
    h, w = plot_size(png)
    assert h > 250 and w > 550, f"{png.name}: the plot is {w} x {h} pixels"
    # for comparison: the same sweep with every combination identical, one line of one short label
    same = sweep_folder(tmp_path / "same", lambda p, f, s: 300.0 + p)
    build_quietly(same, tmp_path / "rep_same")
    plain = tmp_path / "rep_same" / "sweep_same_arch_packet_size.png"
    assert plain.is_file()
    assert abs(plot_size(plain)[0] - h) <= 2  # (the plot keeps its size: the legend is below it)
    assert imread(png).shape[0] > imread(plain).shape[0]  # the figure grew by the legend's lines


def test_the_legend_names_every_combination(tmp_path):
    from tlm.report.sweeps import _group_label

    others = ["arch.fifo_depth", "seed"]
    every = [(f, s) for f in FIFOS for s in SEEDS]
    assert _group_label(others, every) == "fifo_depth=1, 16, 256 or 4096; seed=0 or 1 (identical)"
    assert _group_label(others, [(16, 0), (16, 1)]) == "fifo_depth=16; seed=0 or 1 (identical)"
    odd = [(1, 0), (16, 1)]
    assert _group_label(others, odd) == "fifo_depth=1, seed=0 | fifo_depth=16, seed=1 (identical)"
    assert _group_label(others, [(1, 0)]) == "fifo_depth=1, seed=0"
