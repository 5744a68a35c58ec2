"""The report page (:mod:`tlm.report.html`): self-contained (every figure embedded and
linked), escaped, a section's lead and first figures open and the rest collapsed."""

from __future__ import annotations

import base64
import re

from tlm.report.common import Figure, Section
from tlm.report.html import esc, figure_html, page, section_html


def _pngs(folder, n):
    for i in range(n):
        (folder / f"f{i}.png").write_bytes(b"\x89PNG fake " + bytes([i]))
    return [Figure(f"f{i}.png", f"Fig <{i}>", "a & b" if i else "") for i in range(n)]


def test_esc_escapes_markup_and_quotes():
    assert esc('<a href="x">&\'') == "&lt;a href=&quot;x&quot;&gt;&amp;&#x27;"
    assert esc(3.5) == "3.5"


def test_a_figure_is_embedded_and_linked(tmp_path):
    (fig,) = _pngs(tmp_path, 1)
    out = figure_html(tmp_path, fig.file, "A <b>", "c & d")
    data = re.search(r'src="data:image/png;base64,([^"]+)"', out).group(1)
    assert base64.b64decode(data) == (tmp_path / "f0.png").read_bytes()
    assert '<a href="f0.png">' in out and 'alt="A &lt;b&gt;"' in out
    assert "<strong>A &lt;b&gt;.</strong> c &amp; d" in out
    assert "<strong>A &lt;b&gt;</strong></figcaption>" in figure_html(tmp_path, fig.file, "A <b>", "")


def test_a_section_shows_its_first_figures_and_collapses_the_rest(tmp_path):
    s = Section("sec", "Title & co", figures=_pngs(tmp_path, 3), html="<table></table>", notes=["n <1>"],
                lead="<b>found</b>", shown=1)
    out = section_html(4, s, tmp_path)
    assert out.startswith('<section id="sec"><h2>4. Title &amp; co</h2>') and out.endswith("</section>")
    assert '<p class="lead"><b>found</b></p>' in out  # the lead is HTML already
    open_part, _, collapsed = out.partition("<details>")
    assert open_part.count("<figure>") == 1 and collapsed.count("<figure>") == 2
    assert "<summary>2 more figures</summary>" in out and "<summary>Tables</summary><table></table>" in out
    assert "<summary>Notes (1): what was left out and why</summary>" in out and "n &lt;1&gt;" in out
    assert "Nothing to show" not in out
    s.html_open, s.shown = True, 3
    out = section_html(None, s, tmp_path)
    assert "<h2>Title &amp; co</h2>" in out and "more figure" not in out and "<summary>Tables</summary>" not in out
    absent = section_html(1, Section("e", "Empty", absent="no <inputs>"), tmp_path)
    assert '<p class="absent">Nothing to show: no &lt;inputs&gt;</p>' in absent and "<details>" not in absent


def test_the_page_puts_the_summary_first_then_numbered_sections(tmp_path):
    figs = _pngs(tmp_path, 1)
    sections = [Section("a", "First"), Section("b", "Second", figures=figs)]
    out = page("Report <x>", "<p>inputs</p>", sections, tmp_path, summary=Section("summary", "Found", lead="L"))
    assert out.startswith("<!DOCTYPE html>") and out.endswith("</body></html>\n")
    assert "<title>Report &lt;x&gt;</title>" in out and "<h1>Report &lt;x&gt;</h1>" in out
    order = [out.index(t) for t in ('<div class="summary">', "<nav>", "About these inputs", "<h2>1. First",
                                    "<h2>2. Second")]
    assert order == sorted(order)
    assert '<li><a href="#a">First</a></li><li><a href="#b">Second</a></li>' in out
    assert not re.search(r'(src|href)="(https?:)?//', out)  # nothing from the network
    assert '<div class="summary">' not in page("R", "", sections, tmp_path)
