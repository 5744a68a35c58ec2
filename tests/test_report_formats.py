"""``tlm report --formats png,pdf,svg --dpi N``: the report's figures as vector files for a paper.

Every figure was a PNG at 110 dpi, and nothing else: a researcher had to redraw each figure for a
paper. Now ``--formats pdf,svg`` also writes each figure as a PDF and an SVG beside its PNG (same
stem), linked from its caption; ``--dpi`` sets the PNG's resolution. The default report is as before.

The sweep folders here hold the rows only (``sweep.yaml``, ``sweep.jsonl``): all that the sweep
figures read.
"""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml
from matplotlib.figure import Figure as MplFigure
from PIL import Image

import tlm.report.common as common
from tlm.cli import main
from tlm.errors import InputError
from tlm.report import build_report
from tlm.report.common import line_style, new_figure, save

PACKETS = (1, 16, 256)
SVG = "{http://www.w3.org/2000/svg}"


def sweep_folder(folder: Path) -> Path:
    """A 3-point sweep over the packet size (two figures: the points' FPS and the summary's)."""
    folder.mkdir(parents=True)
    (folder / "sweep.yaml").write_text(yaml.safe_dump({"sweep": "s3.yaml", "description": "16x16 Cornell RCast",
                                                       "grid": {"arch.packet_size": list(PACKETS)}}))
    rows = [{"point": i, "hash": f"h{i:02d}", "status": "ok", "arch.packet_size": p, "scene": "cornell",
             "mode": "rcast", "fps": 100.0 + p, "cycles.throughput": 6e8 / (100.0 + p)} for i, p in enumerate(PACKETS)]
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


def files(folder: Path, suffix: str) -> set[str]:
    return {p.stem for p in folder.glob(f"*.{suffix}")}


def test_pdf_and_svg_are_written_beside_each_png_and_linked_from_the_page(tmp_path, capsys):
    sw = sweep_folder(tmp_path / "sw")
    assert main(["report", str(sw), "--out", str(tmp_path / "plain")]) == 0
    assert main(["report", str(sw), "--out", str(tmp_path / "rep"), "--formats", "pdf,svg"]) == 0
    assert capsys.readouterr().err == ""
    rep = tmp_path / "rep"
    stems = files(rep, "png")
    assert stems and files(rep, "pdf") == stems and files(rep, "svg") == stems
    assert stems == files(tmp_path / "plain", "png")  # the same figures as the default report, of the same names
    assert not files(tmp_path / "plain", "pdf") and not files(tmp_path / "plain", "svg")  # (the default: PNG only)
    page = (rep / "report.html").read_text(encoding="utf-8")
    assert "Each figure links to its PNG, PDF and SVG files." in page
    for stem in stems:
        pdf = (rep / f"{stem}.pdf").read_bytes()
        assert pdf.startswith(b"%PDF-") and b"%%EOF" in pdf[-32:]
        assert b"/FontFile2" in pdf and b"/Type3" not in pdf  # the fonts embedded as TrueType, not Type 3
        assert b"/CreationDate" not in pdf  # (no date: the same inputs, the same bytes)
        svg = ET.parse(rep / f"{stem}.svg").getroot()
        assert svg.tag == f"{SVG}svg"
        assert any((t.text or "").strip() for t in svg.iter(f"{SVG}text"))  # the labels are text, not paths
        # the page embeds the PNG, links it, and links the PDF and SVG from the caption
        figure = re.search(rf'<figure><a href="{stem}\.png"><img [^>]*src="data:image/png;base64,[^"]*"></a>'
                           r"<figcaption>(.*?)</figcaption></figure>", page)
        assert figure, stem
        assert f'<a href="{stem}.pdf">PDF</a> <a href="{stem}.svg">SVG</a>' in figure.group(1)
    # the PNG is the default report's PNG
    for stem in stems:
        assert (rep / f"{stem}.png").read_bytes() == (tmp_path / "plain" / f"{stem}.png").read_bytes()


def png_widths(folder: Path) -> dict[str, tuple[int, int]]:
    sizes = {}
    for p in folder.glob("*.png"):
        with Image.open(p) as im:
            sizes[p.name] = im.size
    return sizes


def test_dpi_220_gives_pngs_twice_as_wide_in_pixels(tmp_path):
    sw = sweep_folder(tmp_path / "sw")
    assert main(["report", str(sw), "--out", str(tmp_path / "plain")]) == 0
    assert main(["report", str(sw), "--out", str(tmp_path / "fine"), "--dpi", "220"]) == 0
    plain, fine = png_widths(tmp_path / "plain"), png_widths(tmp_path / "fine")
    assert plain and set(plain) == set(fine)
    for name, (w, h) in plain.items():
        assert fine[name][0] == 2 * w, (name, plain[name], fine[name])
        assert abs(fine[name][1] - 2 * h) <= 1, (name, plain[name], fine[name])


@pytest.mark.parametrize(("args", "said"), [
    (["--formats", "pdf,jpg"], "--formats: unknown format 'jpg': the formats are png, pdf, svg"),
    (["--formats", "pdf,,svg"], "--formats: an empty format in 'pdf,,svg'"),
    (["--dpi", "49"], "--dpi: 49 dots per inch is out of range: from 50 to 1200"),
    (["--dpi", "1201"], "--dpi: 1201 dots per inch is out of range: from 50 to 1200"),
    (["--dpi", "nan"], "--dpi: 'nan' is not a whole number of dots per inch (from 50 to 1200)"),
    (["--dpi", "150.5"], "--dpi: '150.5' is not a whole number of dots per inch"),
])
def test_a_bad_format_or_dpi_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, args, said):
    sw = sweep_folder(tmp_path / "sw")
    assert main(["report", str(sw), "--out", str(tmp_path / "rep"), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("tlm: error: ") and said in err, err
    assert not (tmp_path / "rep").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sw"]  # (no temporary folder left either)


def test_the_python_api_refuses_the_same_values_before_writing(tmp_path):
    sw = sweep_folder(tmp_path / "sw")
    with pytest.raises(InputError, match=r"^--formats: unknown format 'eps': the formats are png, pdf, svg$"):
        build_report([sw], tmp_path / "rep", formats=["pdf", "eps"])
    with pytest.raises(InputError, match=r"^--dpi: 40 dots per inch is out of range: from 50 to 1200$"):
        build_report([sw], tmp_path / "rep", dpi=40)
    assert not (tmp_path / "rep").exists()
    page = build_report([sw], tmp_path / "rep", formats=("svg",), dpi=55)
    assert files(page.parent, "svg") == files(page.parent, "png") and not files(page.parent, "pdf")
    assert "Each figure links to its PNG and SVG files." in page.read_text(encoding="utf-8")


def _figure() -> MplFigure:
    fig = new_figure(3.0, 2.0)
    ax = fig.add_subplot()
    for i in range(2):
        ax.plot([1, 10, 100], np.array([1.0, 20.0, 300.0]) * (i + 1), label=f"series {i}", **line_style(i))
    ax.set(xscale="log", yscale="log", xlabel="x", ylabel="y")
    ax.legend()
    return fig


def test_the_other_formats_are_saved_from_the_one_laid_out_figure(tmp_path, monkeypatch):
    """The layout runs once; each file is one draw of the laid-out figure; the PNG is the PNG alone's."""
    save(_figure(), tmp_path, "alone.png", "t")
    fig = _figure()
    laid, drawn = [], []
    engine = fig.get_layout_engine()
    execute = type(engine).execute
    monkeypatch.setattr(type(engine), "execute", lambda self, f: laid.append(f) or execute(self, f))
    draw = MplFigure.draw
    monkeypatch.setattr(MplFigure, "draw", lambda f, renderer: drawn.append(renderer) or draw(f, renderer))
    with common.figure_output("svg,pdf"):
        rec = save(fig, tmp_path, "both.png", "t")
    assert rec.file == "both.png"
    assert len(laid) == 1 and len(drawn) == 3, (laid, drawn)
    assert (tmp_path / "both.png").read_bytes() == (tmp_path / "alone.png").read_bytes()
    assert (tmp_path / "both.pdf").read_bytes().startswith(b"%PDF-")
    root = ET.parse(tmp_path / "both.svg").getroot()
    assert root.get("width") == "216pt" and root.get("height") == "144pt"  # 3 x 2 inches
    assert common.current_output() == common.Output(("png",), common.DPI)  # (set for the block only)
