"""Section: the stiff and extreme cases of ``tlm extreme``, expected against measured.

One table per ``tlm extreme`` folder, grouped by category: the case, the behaviour it
expects, what was measured, and whether that is what was expected. A path in what was
measured (a bad-input case's error names the scene file, as it was on the machine that ran
it) is shown as :func:`tlm.report.names.shown_path` shows it: a built-in scene or experiment file by its
place in the repository (``configs/extreme.yaml``, from an installed copy too), a file of the study's folder
relative to it.
"""

from __future__ import annotations

from pathlib import Path

from tlm.report.collect import Inputs
from tlm.report.common import Section, count
from tlm.report.html import esc
from tlm.report.names import shown_paths


def extreme_section(inputs: Inputs, out: Path) -> Section:
    sec = Section("extreme", "Stiff and extreme cases: the behaviour expected against the result measured")
    parts = []
    for st in inputs.of_kind("extreme"):
        failed = [r["case"] for r in st.rows if not r["passed"]]
        parts.append(f"<h3>{esc(st.path.name)}</h3><p>{count(len(st.rows), 'case')}, {len(st.rows) - len(failed)} as "
                     f"expected" + (f", <strong>not as expected: {esc(', '.join(failed))}</strong>" if failed else "")
                     + f". Each case's run folder: {esc(st.path / 'cases')}/&lt;case&gt;.</p>")
        parts.append('<table><tr><th class="l">category</th><th class="l">case</th><th class="l">expected</th>'
                     '<th class="l">measured</th><th class="l">result</th><th>host s</th></tr>')
        for r in sorted(st.rows, key=lambda r: r["category"]):
            verdict = "as expected" if r["passed"] else "<strong>NOT as expected</strong>"
            measured = shown_paths(str(r["measured"]), st.path)  # (no path of the machine that ran it)
            parts.append(f'<tr><td class="l">{esc(r["category"])}</td><td class="l">{esc(r["case"])}</td>'
                         f'<td class="l">{esc(r["expect"])}</td><td class="l">{esc(measured)}</td>'
                         f'<td class="l">{verdict}</td><td>{r["seconds"]:.2f}</td></tr>')
        parts.append("</table>")
    sec.html = "\n".join(parts)
    if not parts:
        sec.absent = ("no 'tlm extreme' folder among the inputs ('tlm extreme extreme' runs the built-in cases, "
                      "from any folder)")
    return sec
