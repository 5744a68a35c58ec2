"""The report page: one self-contained HTML file.

Every figure is embedded (a base64 PNG) and also links to its PNG file beside the page,
so the page opens anywhere on its own and the figures stay usable one by one. The page
references nothing else: no scripts, no style sheets, no fonts from the network.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path

from tlm.report.common import Section

CSS = """
body { font-family: sans-serif; margin: 2em auto; max-width: 72em; color: #111; line-height: 1.4; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #999; padding-bottom: .2em; margin-top: 2em; }
figure { margin: 1.2em 0; } figure img { max-width: 100%; border: 1px solid #ccc; }
figcaption { font-size: .9em; color: #333; }
table { border-collapse: collapse; margin: .8em 0; font-size: .85em; }
th, td { border: 1px solid #aaa; padding: .25em .5em; text-align: right; vertical-align: top; }
th { background: #eee; } td.l, th.l { text-align: left; }
.absent { font-style: italic; color: #444; } .note { font-size: .9em; color: #333; }
pre { background: #f6f6f6; padding: .6em; overflow-x: auto; font-size: .8em; }
details { margin: .4em 0; } summary { cursor: pointer; }
nav ol { columns: 2; }
"""


def esc(x) -> str:
    return html.escape(str(x), quote=True)


def figure_html(folder: Path, file: str, title: str, caption: str) -> str:
    data = base64.b64encode((Path(folder) / file).read_bytes()).decode("ascii")
    cap = f"<strong>{esc(title)}.</strong> {esc(caption)}" if caption else f"<strong>{esc(title)}</strong>"
    return (f'<figure><a href="{esc(file)}"><img alt="{esc(title)}" src="data:image/png;base64,{data}"></a>'
            f"<figcaption>{cap}</figcaption></figure>")


def page(title: str, intro: str, sections: list[Section], folder: Path) -> str:
    """The whole page; ``folder`` holds the sections' PNG files."""
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{esc(title)}</title><style>{CSS}</style></head><body>",
        f"<h1>{esc(title)}</h1>",
        intro,
        "<nav><ol>" + "".join(f'<li><a href="#{esc(s.key)}">{esc(s.title)}</a></li>' for s in sections)
        + "</ol></nav>",
    ]
    for i, s in enumerate(sections, 1):
        parts.append(f'<section id="{esc(s.key)}"><h2>{i}. {esc(s.title)}</h2>')
        if s.absent:
            parts.append(f'<p class="absent">Nothing to show: {esc(s.absent)}</p>')
        for n in s.notes:
            parts.append(f'<p class="note">{esc(n)}</p>')
        if s.html:
            parts.append(s.html)
        for f in s.figures:
            parts.append(figure_html(folder, f.file, f.title, f.caption))
        parts.append("</section>")
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"
