"""The report page: one self-contained HTML file.

Every figure is embedded (a base64 PNG) and also links to its PNG file beside the page,
so the page opens anywhere on its own and the figures stay usable one by one (the link is the
file's name, percent-encoded). Where the report also wrote the figure as PDF or SVG
(``tlm report --formats``), its caption ends with a link to each of those files. The page
references nothing else: no scripts, no style sheets, no fonts from the network. Its one style
sheet, :data:`CSS`, is in its head, the thesis tables' rules (``.tlm-tables``) too: a ``<style>`` in
the body is not HTML, and text copied from the page would carry it. Mailed alone, the page shows every
figure; its links to the figures' files need its folder beside it.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path
from urllib.parse import quote

from tlm.report.common import Section, current_output

CSS = """
body { font-family: sans-serif; margin: 2em auto; max-width: 72em; color: #111; line-height: 1.4; }
h1 { font-size: 1.6em; margin-bottom: .3em; }
h2 { border-bottom: 1px solid #999; padding-bottom: .2em; margin: 1.4em 0 .4em; font-size: 1.3em; }
figure { margin: .6em 0; } figure img { max-width: 100%; max-height: 24em; border: 1px solid #ccc; }
figcaption { font-size: .85em; color: #333; }
.figs { display: grid; grid-template-columns: repeat(auto-fit, minmax(26em, 1fr)); gap: 0 1.2em; }
.summary .figs figure img { max-height: 17em; }
.lead { font-size: 1.02em; }
table { border-collapse: collapse; margin: .8em 0; font-size: .85em; }
th, td { border: 1px solid #aaa; padding: .25em .5em; text-align: right; vertical-align: top; }
th { background: #eee; } td.l, th.l { text-align: left; }
.alt { white-space: nowrap; }
.absent { font-style: italic; color: #444; } .note { font-size: .9em; color: #333; }
pre { background: #f6f6f6; padding: .6em; overflow-x: auto; font-size: .8em; }
details { margin: .4em 0; } summary { cursor: pointer; }
nav ol { columns: 2; }
.tlm-tables table { border-collapse: collapse; margin: .6em 0 .3em 0; font-size: .9em; }
.tlm-tables th, .tlm-tables td { border: 1px solid #888; padding: .2em .5em; text-align: right; vertical-align: top; }
.tlm-tables caption { text-align: left; font-weight: bold; padding-bottom: .3em; }
.tlm-tables .thesis { color: #555; } .tlm-tables .err { font-style: italic; }
.tlm-tables .not-comparable { color: #a00; font-weight: normal; } .tlm-tables td.calibrated { background: #eee; }
"""


def esc(x) -> str:
    return html.escape(str(x), quote=True)


def other_files(folder: Path, file: str) -> str:
    """Links to the figure ``file``'s PDF and SVG files (of the same stem), those of the formats set
    (:func:`~tlm.report.common.figure_output`) that are beside it; "" where none are."""
    stem = Path(file).with_suffix("")
    links = [f'<a href="{esc(quote(str(stem.with_suffix("." + fmt))))}">{fmt.upper()}</a>'
             for fmt in current_output().extra() if (Path(folder) / stem.with_suffix("." + fmt)).is_file()]
    return f' <span class="alt">[{" ".join(links)}]</span>' if links else ""


def figure_html(folder: Path, file: str, title: str, caption: str) -> str:
    data = base64.b64encode((Path(folder) / file).read_bytes()).decode("ascii")
    cap = f"<strong>{esc(title)}.</strong> {esc(caption)}" if caption else f"<strong>{esc(title)}</strong>"
    cap += other_files(folder, file)
    return (f'<figure><a href="{esc(quote(file))}"><img alt="{esc(title)}" src="data:image/png;base64,{data}"></a>'
            f"<figcaption>{cap}</figcaption></figure>")


def figures_html(folder: Path, figures) -> str:
    """Figures side by side in a grid (two to a row on a wide screen)."""
    return '<div class="figs">' + "".join(figure_html(folder, f.file, f.title, f.caption) for f in figures) + "</div>"


def details(label: str, body: str) -> str:
    return f"<details><summary>{esc(label)}</summary>{body}</details>"


def section_html(i: int | None, s: Section, folder: Path) -> str:
    """One section: its lead and first figures open, the rest of it collapsed."""
    num = f"{i}. " if i is not None else ""
    parts = [f'<section id="{esc(s.key)}"><h2>{num}{esc(s.title)}</h2>']
    if s.absent:
        parts.append(f'<p class="absent">Nothing to show: {esc(s.absent)}</p>')
    if s.lead:
        parts.append(f'<p class="lead">{s.lead}</p>')
    if s.figures[: s.shown]:
        parts.append(figures_html(folder, s.figures[: s.shown]))
    rest = s.figures[s.shown:]
    if rest:
        parts.append(details(f"{len(rest)} more figure{'s' * (len(rest) > 1)}", figures_html(folder, rest)))
    if s.html:
        parts.append(s.html if s.html_open else details(s.html_label, s.html))
    if s.notes:
        body = "".join(f'<p class="note">{esc(n)}</p>' for n in s.notes)
        parts.append(details(f"Notes ({len(s.notes)}): what was left out and why", body))
    parts.append("</section>")
    return "\n".join(parts)


def page(title: str, intro: str, sections: list[Section], folder: Path, summary: Section | None = None,
         notice: str = "") -> str:
    """The whole page; ``folder`` holds the sections' PNG files. ``summary``, when given,
    comes first, unnumbered: what the model found, on the first screen; ``notice`` (HTML:
    the runs' warnings) under it, open."""
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{esc(title)}</title><style>{CSS}</style></head><body>",
        f"<h1>{esc(title)}</h1>",
    ]
    if summary is not None:
        parts.append('<div class="summary">' + section_html(None, summary, folder) + "</div>")
    if notice:
        parts.append(notice)
    parts.append("<nav><ol>" + "".join(f'<li><a href="#{esc(s.key)}">{esc(s.title)}</a></li>' for s in sections)
                 + "</ol></nav>")
    parts.append(details("About these inputs", intro))
    for i, s in enumerate(sections, 1):
        parts.append(section_html(i, s, folder))
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"
