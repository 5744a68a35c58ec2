"""The warnings the runs recorded (``results.json`` ``warnings``: a light that reaches
nothing, a black image, a stream too short for a steady state, a setting the run never
read, ...), at the top of the report, so that a table or figure drawn from such a run is
read with its caveat: each warning once, with the runs that recorded it (the first
:data:`SHOWN_WARNINGS` in the box, the rest one click below them, so that a page of many
sweeps keeps its first screens).

Warnings of a study's cells (a thesis cell, a sweep point) are the same lines ``tlm run``
prints for a run; the commands that run many of them print none, so the report is where
they are read.
"""

from __future__ import annotations

from tlm.report.collect import Inputs
from tlm.report.html import esc

SHOWN_RUNS = 4  # runs named per warning; the rest counted
SHOWN_WARNINGS = 8  # warnings listed in the box itself; the rest in a <details> under them (the page's first screens)


def recorded(inputs: Inputs) -> list[tuple[str, list[str]]]:
    """``(warning, labels of the runs that recorded it)`` in the order first met."""
    found: dict[str, list[str]] = {}
    for run in inputs.runs:
        lines = run.results.get("warnings") or []
        for line in lines if isinstance(lines, list) else [lines]:
            found.setdefault(str(line), []).append(run.label)
    return list(found.items())


def damaged_html(inputs: Inputs) -> str:
    """The damaged files among the inputs (:attr:`~tlm.report.collect.Inputs.damaged`), each with
    what to do and what the report leaves out for it; "" where none is."""
    if not inputs.damaged:
        return ""
    n = len(inputs.damaged)
    return (f"<p><strong>Damaged inputs.</strong> {n} damaged file{'s' if n > 1 else ''} could not be read; "
            "what each holds is left out of this report:</p><ul>"
            + "".join(f"<li>{esc(line)}</li>" for line in inputs.damaged) + "</ul>")


def warnings_html(inputs: Inputs) -> str:
    """The block under the report's inputs line: the damaged files left out (:func:`damaged_html`)
    and the warnings the runs recorded; empty when there are neither."""
    found = recorded(inputs)
    damaged = damaged_html(inputs)
    if not found:
        return f'<div class="warnings">{damaged}</div>' if damaged else ""
    total = len(inputs.runs)
    items = []
    for line, labels in found:
        named = ", ".join(labels[:SHOWN_RUNS]) + (f" and {len(labels) - SHOWN_RUNS} more" if len(labels) > SHOWN_RUNS
                                                  else "")
        whose = "" if total == 1 else " (every run)" if len(labels) == total else (
            f" ({len(labels)} of {total} runs: {named})")
        items.append(f"<li>{esc(line)}<span class=\"note\">{esc(whose)}</span></li>")
    runs = len({label for _, labels in found for label in labels})
    who = "The run" if total == 1 else f"{runs} of the {total} runs"
    shown, rest = items[:SHOWN_WARNINGS], items[SHOWN_WARNINGS:]
    more = (f"<details><summary>{len(rest)} more warning{'s' if len(rest) > 1 else ''}</summary><ul>"
            + "".join(rest) + "</ul></details>") if rest else ""
    return (f'<div class="warnings">{damaged}<p><strong>Warnings.</strong> {who} recorded {len(found)} '
            f"warning{'s' if len(found) > 1 else ''} (results.json <code>warnings</code>); read what is drawn "
            "from them with these in mind:</p><ul>" + "".join(shown) + "</ul>" + more + "</div>")
