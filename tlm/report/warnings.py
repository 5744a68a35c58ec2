"""The warnings the runs recorded (``results.json`` ``warnings``: a light that reaches
nothing, a black image, a stream too short for a steady state, a setting the run never
read, ...), at the top of the report, so that a table or figure drawn from such a run is
read with its caveat: each warning once, with the runs that recorded it (the first
:data:`SHOWN_WARNINGS` in the box, the rest one click below them, so that a page of many
sweeps keeps its first screens).

Warnings of a study's cells (a thesis cell, a sweep point) are the same lines ``tlm run``
prints for a run; the commands that run many of them print none, so the report is where
they are read. A study's own warnings, said once for the study on stderr (``tlm thesis``'s
``--set`` no cell reads), are the ``warnings`` list of its file (``thesis_summary.json``; any
study record with one: :data:`STUDY_FILES`), listed in the same box once each, attributed to
the study; so is a granularity study's (its ``granularity_summary.json``: the overrides' lines and the
frame's own, ``granularity: the camera faces nothing ...``) and an error-vs-cost study's (its ``reference.json``
``warnings``: the overrides' lines, the frame's camera, the reference not converged or not cached, a black reference
or ground truth, the truth's few samples: h417). (``tlm extreme`` writes no such list; an error-vs-cost study written
before that list has its reference not converged listed from its ``reference.json`` ``reference_converged`` false,
:func:`reference_line`; either way it is said in the axis label, title and caption of each of the study's
error figures, :func:`tlm.report.tradeoff.reference_words`.)

A Dask sweep's events on its workers (a worker left out, why, its points sent again and where they ran: its
``workers.json``) are listed in the same block (:func:`workers_html`).

Inputs whose results different tlm code made (their code fingerprints differ, or one records none: an
older tlm) are said first, naming which folders are of which code (:func:`code_line`); what is drawn
is not changed.
"""

from __future__ import annotations

from collections import Counter

from tlm.config_words import listing, number_form
from tlm.experiments.sweep_rows import WORKERS_FILE, read_worker_events
from tlm.report.collect import Inputs
from tlm.report.html import esc

SHOWN_RUNS = 4  # runs named per warning; the rest counted
SHOWN_WARNINGS = 8  # warnings listed in the box itself; the rest in a <details> under them (the page's first screens)
# a study's records (Study.meta key -> its file) whose ``warnings`` list is the study's own; "" is the
# meta itself (a thesis study's meta is its thesis_summary.json)
STUDY_FILES = {"": "thesis_summary.json", "reference": "reference.json", "provenance": "provenance.json",
               "granularity_summary": "granularity_summary.json"}


def recorded(inputs: Inputs) -> list[tuple[str, list[str]]]:
    """``(warning, labels of the runs that recorded it)`` in the order first met."""
    found: dict[str, list[str]] = {}
    for run in inputs.runs:
        lines = run.results.get("warnings") or []
        for line in lines if isinstance(lines, list) else [lines]:
            found.setdefault(str(line), []).append(run.label)
    return list(found.items())


def study_label(study) -> str:
    """How the warnings box names a study: ``the thesis study T``."""
    return f"the {study.kind} study {study.path}"


def reference_line(study) -> str | None:
    """The warning of an error-vs-cost study whose reference did not converge (``reference.json``
    ``reference_converged``, else ``converged``, false), as the study printed it; None for any other, and for
    one whose ``reference.json`` keeps its ``warnings`` (h417: the line the study said is among them)."""
    ref = study.meta.get("reference") if study.kind == "error-vs-cost" and isinstance(study.meta, dict) else None
    if not isinstance(ref, dict) or isinstance(ref.get("warnings"), list):
        return None
    converged = ref.get("reference_converged", ref.get("converged"))
    if converged is not False:
        return None
    err, rounds, tol = (ref.get(k) for k in ("relative_standard_error", "rounds", "tolerance"))
    num = (int, float)
    return (f"error-vs-cost: the photon-map reference {ref.get('key', '')} is NOT converged: relative standard error "
            f"{f'{err:.4f}' if isinstance(err, num) else 'n/a'} after {rounds} rounds"
            + (f", above its tolerance {tol}" if isinstance(tol, num) else "")
            + "; every row's rmse and rel_mse include its noise")


def study_recorded(inputs: Inputs) -> list[tuple[str, list[str], list[str]]]:
    """``(warning, labels of the studies that recorded it, their files)`` in the order first met:
    the ``warnings`` lists of the studies' own records (:data:`STUDY_FILES`)."""
    found: dict[str, tuple[list[str], list[str]]] = {}
    for study in getattr(inputs, "studies", None) or []:
        line = reference_line(study)
        if line is not None:
            whose, files = found.setdefault(line, ([], []))
            whose.append(study_label(study))
            files.append("reference.json:reference_converged")  # (file:key, where no warnings list holds it)
        for key, name in STUDY_FILES.items():
            record = study.meta if not key else study.meta.get(key)
            if (key == "" and study.kind != "thesis") or not isinstance(record, dict):
                continue
            lines = record.get("warnings") or []
            for line in lines if isinstance(lines, list) else [lines]:
                whose, files = found.setdefault(str(line), ([], []))
                if study_label(study) not in whose:
                    whose.append(study_label(study))
                    files.append(name)
    return [(line, whose, files) for line, (whose, files) in found.items()]


def folder_codes(inputs: Inputs) -> dict[str, dict[str | None, int]]:
    """The code each input folder's results came from, by folder, each with how many of its results
    (a sweep's points; a run's, a study's: 1) it made: the ``code_fingerprint`` its records hold
    (:func:`tlm.experiments.provenance.code_state`; a run's and each sweep point's ``results.json``, a
    study's ``provenance.json``), None for one written by a tlm older than those records; a sweep with
    no finished point (nothing of it drawn) is not listed."""
    def code(record) -> str | None:
        found = record.get("code_fingerprint") if isinstance(record, dict) else None
        return str(found) if found else None

    out: dict[str, dict[str | None, int]] = {}
    for sw in getattr(inputs, "sweeps", None) or []:
        if sw.runs:
            out[str(sw.path)] = dict(Counter(code(run.results) for run in sw.runs))
    for study in getattr(inputs, "studies", None) or []:
        out[str(study.path)] = {code(study.meta.get("provenance")): 1}
    for run in inputs.runs:
        if getattr(run, "kind", None) == "run":
            out[str(run.path)] = {code(run.results): 1}
    return out


def code_line(inputs: Inputs) -> str | None:
    """Where the inputs' results come from different tlm code (their code fingerprints differ, or some
    record none: an older tlm), the line that says which folders are of which code; None where one code
    made them all (or none records its code: nothing to tell them apart by). What is drawn is not changed."""
    groups: dict[str | None, list[str]] = {}
    for folder, codes in folder_codes(inputs).items():
        for c, n in codes.items():  # (a sweep resumed by another tlm: each code with how many of its points)
            groups.setdefault(c, []).append(folder if len(codes) == 1 else f"{folder} ({n} of {sum(codes.values())} "
                                                                          "points)")
    if len(groups) < 2:
        return None

    parts = [f"code {c}: {listing(f, SHOWN_RUNS)}" for c, f in groups.items() if c is not None]
    if None in groups:
        parts.append(f"no code recorded (an older tlm): {listing(groups[None], SHOWN_RUNS)}")
    return ("these inputs come from different tlm code, so their numbers may differ by the code alone, whatever "
            "their settings (" + "; ".join(parts) + "); run them again with one tlm to compare them")


def damaged_html(inputs: Inputs) -> str:
    """The damaged files among the inputs (:attr:`~tlm.report.collect.Inputs.damaged`), each with
    what to do and what the report leaves out for it; "" where none is."""
    if not inputs.damaged:
        return ""
    n = len(inputs.damaged)
    return (f"<p><strong>Damaged inputs.</strong> {n} damaged file{'s' if n > 1 else ''} could not be read; "
            "what each holds is left out of this report:</p><ul>"
            + "".join(f"<li>{esc(line)}</li>" for line in inputs.damaged) + "</ul>")


def _point_words(sent: dict, points: dict[str, str]) -> str:
    """A point sent again from a worker left out (``workers.json``'s ``sent_again``): its number in the sweep (else
    its hash), where it ran then and how it ended."""
    h = str(sent.get("hash"))
    ran = sent.get("ran_on")
    where = f" ran again on {ran}" + (f" on host {sent['host']}" if sent.get("host") else "") if ran else ""
    return f"{points.get(h, h[:12])}{where} ({sent.get('status', 'not run')})"


def worker_events(inputs: Inputs) -> list[tuple[str, str]]:
    """``(line, whose)`` for each event a Dask sweep among the inputs kept on its workers (its ``workers.json``:
    :func:`tlm.experiments.sweep_rows.keep_worker_events`): a worker left out of it, why, and its points sent again
    (where each ran then: it ran twice), one re-admitted, one that left the cluster while it held points; one
    that cannot be read, a line saying so."""
    out = []
    for sw in getattr(inputs, "sweeps", None) or []:
        path = sw.path / WORKERS_FILE
        if not path.is_file():
            continue
        whose = f"the sweep {sw.label}"
        try:
            events = read_worker_events(path)["events"]
        except (OSError, ValueError) as e:  # (UnicodeDecodeError among them)
            out.append((f"{path} could not be read ({e}): what the sweep kept of its Dask workers (one left out, "
                        "points sent again) is not shown", whose))
            continue
        points = {str(r.get("hash")): f"#{r['point']}" for r in sw.rows if isinstance(r, dict) and "point" in r}
        for event in (e for e in events if isinstance(e, dict)):
            line = event.get("line")
            if not isinstance(line, str):
                line = f"the Dask worker {event.get('worker')}: {event.get('event')} ({event.get('why')})"
            sent = event.get("sent_again")
            again = [_point_words(p, points) for p in sent if isinstance(p, dict)] if isinstance(sent, list) else []
            if again:
                line += f"; point{'s' * (len(again) > 1)} sent again: " + ", ".join(again)
            out.append((line, whose + (f", {event['when']}" if isinstance(event.get("when"), str) else "")))
    return out


def workers_html(inputs: Inputs) -> str:
    """The events the Dask sweeps among the inputs kept on their workers (:func:`worker_events`), a paragraph and a
    list; "" where there are none."""
    found = worker_events(inputs)
    if not found:
        return ""
    n = len(found)
    return (f"<p><strong>Dask workers.</strong> The sweeps shown kept {n} event{'s' * (n > 1)} on their Dask "
            f"workers ({esc(WORKERS_FILE)} <code>events</code>); a point sent again ran twice, and its row is "
            "its later run (or a run since, where the sweep ran again into its folder):</p><ul>"
            + "".join(f"<li>{esc(line)}<span class=\"note\"> ({esc(whose)})</span></li>" for line, whose in found)
            + "</ul>")


def warnings_html(inputs: Inputs) -> str:
    """The block under the report's inputs line: inputs of different tlm code (:func:`code_line`), the
    damaged files left out (:func:`damaged_html`), the events the Dask sweeps kept on their workers
    (:func:`workers_html`) and the warnings the runs recorded; empty when there are none of these."""
    found = recorded(inputs)
    studies = study_recorded(inputs)
    damaged = damaged_html(inputs) + workers_html(inputs)
    mixed = code_line(inputs)
    if mixed is not None:  # (said first: it bears on every number of the page)
        damaged = f"<p><strong>Different code.</strong> {esc(mixed[0].upper() + mixed[1:])}.</p>" + damaged
    if not found and not studies:
        return f'<div class="warnings">{damaged}</div>' if damaged else ""
    total = len(inputs.runs)
    items: list[tuple[str, int]] = []  # (an item of the box, how many of the lines it says: :func:`folded`)
    for line, whose_studies, _ in studies:  # (a study's own first: said once for all its cells)
        items.append((f"<li>{esc(line)}<span class=\"note\"> ({esc(', '.join(whose_studies))})</span></li>", 1))
    said = {line for line, _, _ in studies}
    kept = [(line, labels) for line, labels in found if line not in said]  # (a cell of an older study recorded
    # the study's line too: once, the study's)

    def whose(labels: list[str]) -> str:  # (which runs said it; "" of a page of one run)
        return "" if total == 1 and not studies else "every run" if len(labels) == total else (
            f"{len(labels)} of {total} runs: {listing(labels, SHOWN_RUNS)}")

    def note(*words: str) -> str:
        said = "; ".join(filter(None, words))
        return f"<span class=\"note\"> ({esc(said)})</span>" if said else "<span class=\"note\"></span>"
    for wordings in folded(kept):
        (line, labels), others = wordings[0], wordings[1:]
        if not others:
            items.append((f"<li>{esc(line)}{note(whose(labels))}</li>", 1))
            continue
        every = list(dict.fromkeys(label for _, ls in wordings for label in ls))
        mine = whose(labels)  # (the runs of the wording shown, not only of its kind: each line with its runs)
        items.append((f"<li>{esc(line)}"
                      + note(f"in {len(wordings)} wordings that differ only in their numbers, the first met shown",
                             whose(every), mine and f"this one by {mine}")
                      + f"<details><summary>its {len(others)} other wording{'s' * (len(others) > 1)}</summary><ul>"
                      + "".join(f"<li>{esc(other)}{note(whose(ls))}</li>" for other, ls in others)
                      + "</ul></details></li>", len(wordings)))
    runs = len({label for _, labels in kept for label in labels})
    study_names = list(dict.fromkeys(s for _, whose, _ in studies for s in whose))
    files = list(dict.fromkeys(f for _, _, fs in studies for f in fs))
    who = " and ".join(filter(None, (
        ("The run" if total == 1 else f"{runs} of the {total} runs") if kept else "",
        (study_names[0] if len(study_names) == 1 else f"{len(study_names)} studies") if studies else "")))
    who = who[0].upper() + who[1:]
    named = [f.partition(":") for f in [*(["results.json"] if kept else []), *files]]
    where = (esc(listing(name for name, _, _ in named)) + " <code>warnings</code>"  # (their warnings lists)
             if not any(key for _, _, key in named) else  # (else each file's key: reference.json's is another)
             listing(f"{esc(name)} <code>{esc(key or 'warnings')}</code>" for name, _, key in named))
    n = len(studies) + len(kept)  # (== the lines its items say: each once, however many recorded it)
    said_all = sum(len(set(labels)) for _, labels in kept) + sum(len(whose) for _, whose, _ in studies)
    count = (f"{n} warning{'s' if n > 1 else ''} ({where})" if said_all == n else  # (each line by one: a count)
             f"1 warning, the same in each ({where})" if n == 1 else
             f"{n} different warnings ({where}; {said_all} in all)")  # (h509: 89 lines of 144 runs, not 89 warnings)
    kinds = ("" if len(items) == n else f" of {len(items)} kind{'s' * (len(items) > 1)} (lines that differ only in "
             "their numbers are one kind, listed once)")  # (:func:`folded`)
    shown, rest = items[:SHOWN_WARNINGS], items[SHOWN_WARNINGS:]
    hidden = sum(k for _, k in rest)  # (a folded item past the first ones says its wordings there too)
    more = (f"<details><summary>{len(rest)} more "
            + (f"warning{'s' * (len(rest) > 1)}" if hidden == len(rest) else
               f"kind{'s' * (len(rest) > 1)}, {hidden} warnings")
            + "</summary><ul>" + "".join(item for item, _ in rest) + "</ul></details>") if rest else ""
    return (f'<div class="warnings">{damaged}<p><strong>Warnings.</strong> {esc(who)} recorded {count}'
            f"{esc(kinds)}; read what is drawn "
            "from them with these in mind:</p><ul>" + "".join(item for item, _ in shown) + "</ul>" + more + "</div>")


def folded(found: list[tuple[str, list[str]]]) -> list[list[tuple[str, list[str]]]]:
    """The runs' warnings (``(line, labels)``, :func:`recorded`) grouped by :func:`tlm.config_words.number_form`,
    each group in the order first met (its first wording first): ``arch.fifo_depth = 16 changes no simulated
    cycle ... the 3065 puts that waited ...`` and ``... the 2985 puts ...`` of two sweep points are one item of the
    box, said once with its other wordings one click below (a sweep over many points would fill the first
    screens with lines that differ only in their figures)."""
    groups: dict[str, list[tuple[str, list[str]]]] = {}
    for line, labels in found:
        groups.setdefault(number_form(line), []).append((line, labels))
    return list(groups.values())
