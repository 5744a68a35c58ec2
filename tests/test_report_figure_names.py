"""The report's figure files: one name for one figure, safe in a shell, a URL and LaTeX.

* Two sweeps whose folders have the same name (``a/sw`` and ``b/sw``) got one
  ``sweep_sw_<factor>.png`` per factor: the later sweep's figure overwrote the earlier's, and
  both sweeps' places on the page showed it. Now each sweep has its own files.
* A folder named ``odd sweep (x&y)#2 é`` gave file names with spaces, ``( ) & #`` and ``é``; the
  page's link ended at the ``#``. Now every name is ASCII letters, digits, ``_``, ``-`` and ``.png``,
  and every link on the page leads to its file.
* Two runs whose labels agree in their first 60 characters got one ``pmap_error_<label>.png``.

The sweep folders here hold the rows only (``sweep.yaml``, ``sweep.jsonl``): all that the
sweep figures read.
"""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import yaml
from matplotlib.image import imread
from PIL import Image

from tlm.report import build_report
from tlm.report.collect import Run, read
from tlm.report.images import error_figure
from tlm.report.sweeps import sweeps_section

SAFE = re.compile(r"[A-Za-z0-9_-]+\.png")
PACKETS = (1, 16, 256)


def sweep_folder(folder: Path, scale: float) -> Path:
    """A 3-point sweep over the packet size whose point p ran at ``scale * (100 + p)`` FPS."""
    folder.mkdir(parents=True)
    grid = {"arch.packet_size": list(PACKETS)}
    (folder / "sweep.yaml").write_text(yaml.safe_dump({"sweep": "s3.yaml", "description": "16x16 Cornell RCast",
                                                       "grid": grid}))
    rows = []
    for i, p in enumerate(PACKETS):
        fps = scale * (100.0 + p)
        rows.append({"point": i, "hash": f"h{i:02d}", "status": "ok", "arch.packet_size": p, "scene": "cornell",
                     "mode": "rcast", "fps": fps, "cycles.throughput": 6e8 / fps})
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


def pixels(png: Path) -> np.ndarray:
    return np.asarray(imread(png))


def test_two_sweeps_of_one_name_get_a_figure_each(tmp_path):
    a = sweep_folder(tmp_path / "a" / "sw", 1.0)
    b = sweep_folder(tmp_path / "b" / "sw", 3.0)  # (its FPS 3 times a's: another figure)
    for name in ("both", "only_a"):
        (tmp_path / name).mkdir()
    both = sweeps_section(read([a, b]), tmp_path / "both")
    files = [f.file for f in both.figures]
    assert len(files) == 2 and len(set(files)) == 2, files  # one factor of 2 sweeps: 2 files
    # the first keeps the plain name, the second gets a suffix from its folder's path
    assert files[0] == "sweep_sw_arch_packet_size.png"
    assert re.fullmatch(r"sweep_sw_arch_packet_size_[0-9a-f]{8}\.png", files[1]), files[1]
    # sweep a's figure shows sweep a: the figure of a report of sweep a alone, not sweep b's
    c = sweep_folder(tmp_path / "c" / "sw", 5.0)  # (a third sweep named alike: sweep a is "a/sw" there too)
    own, _ = sweeps_section(read([a, c]), tmp_path / "only_a").figures
    assert both.figures[0].title == own.title
    assert np.array_equal(pixels(tmp_path / "both" / files[0]), pixels(tmp_path / "only_a" / own.file))
    assert not np.array_equal(pixels(tmp_path / "both" / files[0]), pixels(tmp_path / "both" / files[1]))


def page_figures(page: Path) -> list[tuple[str, bytes]]:
    """Each figure on the page: its link and the PNG it embeds."""
    text = page.read_text(encoding="utf-8")
    found = re.findall(r'<a href="([^"]*)"><img alt="[^"]*" src="data:image/png;base64,([^"]*)"></a>', text)
    return [(href, base64.b64decode(data)) for href, data in found]


def test_the_page_shows_each_sweeps_own_figure(tmp_path):
    a = sweep_folder(tmp_path / "a" / "sw", 1.0)
    b = sweep_folder(tmp_path / "b" / "sw", 3.0)
    page = build_report([a, b], tmp_path / "rep")
    shown = [(href, png) for href, png in page_figures(page) if href.startswith("sweep_")]
    assert len(shown) == 2 and len({href for href, _ in shown}) == 2
    assert len({png for _, png in shown}) == 2  # two different pictures
    for href, png in shown:
        assert (page.parent / unquote(href)).read_bytes() == png


def test_an_odd_folder_name_gives_safe_file_names_and_links_that_resolve(tmp_path):
    odd = sweep_folder(tmp_path / "odd sweep (x&y)#2 é", 1.0)
    page = build_report([odd], tmp_path / "rep")
    pngs = sorted(p.name for p in page.parent.glob("*.png"))
    assert "sweep_odd_sweep_x_y_2_e_arch_packet_size.png" in pngs, pngs
    bad = [n for n in pngs if not SAFE.fullmatch(n)]
    assert not bad, bad
    figures = page_figures(page)
    assert len(figures) == len(pngs)  # (every figure written is on the page)
    for href, png in figures:
        parts = urlsplit(href)  # (as a browser reads the link: a '#' would start a fragment)
        assert not parts.fragment and not parts.query and not parts.scheme, href
        target = page.parent / unquote(parts.path)
        assert target.is_file() and target.read_bytes() == png, href


def error_run(folder: Path, label: str) -> Run:
    """A run folder with a PMap frame and its difference image, and a measured error."""
    (folder / "images").mkdir(parents=True)
    grey = np.full((16, 16, 3), 128, np.uint8)
    Image.fromarray(grey).save(folder / "images" / "pmap.png")
    Image.fromarray(grey // 2).save(folder / "images" / "pmap_error.png")
    error = {"available": True, "rel_mse": 0.01, "rmse": 0.02, "difference_scale": 0.1, "reference": "r",
             "reference_converged": True, "reference_rounds": 4, "reference_standard_error": 0.001}
    return Run(folder, label, "run", {"error": error, "scene": {"name": "cornell"}, "timing": {}}, {})


def test_two_run_labels_alike_in_60_characters_get_two_error_figures(tmp_path):
    long = "x" * 60
    (tmp_path / "rep").mkdir()
    one = error_figure(error_run(tmp_path / "one", f"{long}_one: cornell/pmap"), tmp_path / "rep")
    two = error_figure(error_run(tmp_path / "two", f"{long}_two: cornell/pmap"), tmp_path / "rep")
    assert one.file != two.file
    assert (tmp_path / "rep" / one.file).is_file() and (tmp_path / "rep" / two.file).is_file()
    assert SAFE.fullmatch(one.file) and SAFE.fullmatch(two.file)


def test_figure_names_are_bounded_and_stable(tmp_path):
    from tlm.report.common import NAME_MAX, figure_name

    parts = ("sweep", "é" * 5 + " a folder name of " + "many words " * 30, "arch.fifo_depth")
    first = figure_name(tmp_path, *parts, key="one")
    (tmp_path / first).write_bytes(b"")
    second = figure_name(tmp_path, *parts, key="two")
    assert first != second and len(first) <= NAME_MAX and len(second) <= NAME_MAX
    assert SAFE.fullmatch(first) and SAFE.fullmatch(second)
    assert figure_name(tmp_path, *parts, key="two") == second  # (the same figure: the same name)
    assert figure_name(tmp_path / "other", *parts, key="two") == first  # (another report: its own names)


def test_a_written_report_leaves_no_record_of_its_names(tmp_path):
    """The names a report took are forgotten once it is written: a long session (a notebook)
    writing report after report keeps no record of them, and a report written again into the
    same folder gives its figures the same names."""
    from tlm.report import common

    a = sweep_folder(tmp_path / "coll" / "a", 1.0)
    before = dict(common._TAKEN)
    first = build_report([a], tmp_path / "rep")
    names = sorted(p.name for p in first.parent.glob("*.png"))
    assert before == common._TAKEN
    again = build_report([a], tmp_path / "rep")
    assert sorted(p.name for p in again.parent.glob("*.png")) == names and before == common._TAKEN
