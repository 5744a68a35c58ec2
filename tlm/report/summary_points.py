"""The summary's sentences on the sweeps' points (:mod:`tlm.report.summary` says them): their frame
rates where no run or thesis study has one to draw (:func:`fps_of_points`), their bottleneck PM, per sweep
and across them (:func:`sweep_bottlenecks`, :func:`bottleneck_of_points`), and their image error, with the
``tlm reference`` command for the photon-map points that have none (:func:`points_error`, their
references counted by :func:`references`).
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

from tlm.arch.steady import STEADY_SPREAD
from tlm.config_words import listing
from tlm.report.collect import Inputs, Run
from tlm.report.html import esc

PMS = ("vertex", "traversal", "intersection", "fragment")
PM_METRIC = {"vertex": "TVert", "traversal": "TTrav", "intersection": "Tisct", "fragment": "TFrag"}


# the words both this module and tlm.report.summary use (that module imports them from here)
def number(v) -> bool:
    """Whether ``v`` is a finite number (not a bool)."""
    return isinstance(v, int | float) and not isinstance(v, bool) and np.isfinite(v)


def count(n: int, what: str) -> str:
    """``1 point``, ``2 points``."""
    return f"{n} {what}{'s' * (n != 1)}"


def and_(items: list[str]) -> str:
    """``a``, ``a and b``, ``a, b and c`` (:func:`~tlm.config_words.listing`, every item)."""
    return listing(items)


def fps_of_points(inputs: Inputs) -> str:
    """What "How fast" says with no run or thesis study to draw: the sweep points' frame rates, where
    the inputs have any (§4 draws them against each factor), else that there is none."""
    points = [r for r in inputs.runs if r.kind == "sweep-point" and number(r.results.get("fps"))
              and r.results["fps"] > 0]
    if not points:
        return "No run, thesis study or finished sweep point among the inputs: no frame rate to show."
    lo, hi = min(points, key=lambda r: r.results["fps"]), max(points, key=lambda r: r.results["fps"])
    low, high = lo.results["fps"], hi.results["fps"]
    # (rates that print alike said apart, to as many figures as part them, and said to tie within the 1% rule's
    # tolerance where they do: h531's "from 27.6 FPS (#0) to 27.6 FPS (#1)")
    d = 3 if math.isclose(low, high, rel_tol=1e-9) else next(
        (d for d in range(3, 10) if f"{low:.{d}g}" != f"{high:.{d}g}"), 10)
    tie = (f", within {STEADY_SPREAD:.0%} of each other (a tie, as for points within {STEADY_SPREAD:.0%} of the "
           "best)" if low >= high * (1 - STEADY_SPREAD) else "")
    rng = (f"at {low:.3g} FPS" if lo is hi or math.isclose(low, high, rel_tol=1e-9) else
           f"from {low:.{d}g} FPS ({esc(lo.label)}) to {high:.{d}g} FPS ({esc(hi.label)}){tie}")
    return (f"<b>How fast:</b> no run or thesis study among the inputs to draw per scene and mode; the "
            f"{count(len(points), 'sweep point')} run{'s' * (len(points) == 1)} {rng} (§4 draws them against each "
            "factor).")


# what a "busy" share of the sweep points' bottleneck is (HTML: no angle brackets): not sweep.csv's busy.<pm>, the
# mean over the pipelines, which is lower where the pipelines' tiles take unequal work
BUSIEST = "busy: the PM's busiest pipeline's share of the time; sweep.csv's busy.* columns are means over the pipelines"


def busy_shares(results: dict) -> dict[str, float] | None:
    """The busy share of each PM that a run's ``results`` record, a PM's busiest pipeline's (as ``cycles.<pm>``
    is its slowest pipeline's, the one the frame waits for, and ``timing.throughput_estimate.slowest_pm`` the PM
    of the most of those): the most ``timing.units.pipe<i>.<pm>.fractions.busy`` over the pipelines; None where
    a PM has none, or one that is not a number."""
    units = (results.get("timing") or {}).get("units") or {}
    busy: dict[str, float] = {}
    for name, unit in units.items():
        pipe, _, pm = str(name).partition(".")
        if pm not in PMS or not pipe.startswith("pipe") or not pipe[4:].isdigit():
            continue
        v = unit.get("fractions", {}).get("busy") if isinstance(unit, dict) and isinstance(
            unit.get("fractions"), dict) else None
        if not number(v):
            return None
        busy[pm] = max(busy.get(pm, v), v)
    return busy if len(busy) == len(PMS) else None


def _busy(r: Run) -> dict[str, float] | None:
    """The busy share of each PM that ``r`` records (:func:`busy_shares`); None where it lacks one."""
    return busy_shares(r.results)


def sweep_bottlenecks(inputs: Inputs, moving: bool = False) -> list[str]:
    """Per sweep whose finished points record their busy fractions, its points' bottleneck PM in words:
    ``scal: TVert in all 14 points, busy 43–97%``, or where it moves across the sweep, each PM's count and
    the first point it limits (``TFrag in 3 (first at arch.pipelines = 1), TVert in 5 (first at ...)``).
    ``moving``: the sweeps where it moves alone."""
    texts = []
    for sw in inputs.sweeps:
        tops: dict[str, list[tuple[Run, float]]] = defaultdict(list)
        for r in sw.runs:
            b = _busy(r)
            if b is not None:
                pm = max(PMS, key=lambda p: b[p])  # (the first of PM order on a tie)
                tops[pm].append((r, b[pm]))
        if not tops:
            continue
        n = sum(len(v) for v in tops.values())
        first = {pm: next(i for i, r in enumerate(sw.runs) if r is tops[pm][0][0]) for pm in tops}
        order = sorted(tops, key=lambda p: (-len(tops[p]), first[p]))  # (the most points first, then sweep order)
        if len(order) == 1:
            if moving:
                continue
            pm = order[0]
            texts.append(f"{esc(sw.label)}: {PM_METRIC[pm]} in {'all ' if n > 1 else ''}{count(n, 'point')}, busy "
                         f"{_percent_range([v for _, v in tops[pm]])}")
        else:
            each = ", ".join(f"{PM_METRIC[pm]} in {len(tops[pm])} (busy {_percent_range([v for _, v in tops[pm]])}"
                             + (f"; first at {esc(tops[pm][0][0].factors_text)}" if tops[pm][0][0].factors else "")
                             + ")" for pm in order)
            texts.append(f"{esc(sw.label)}: the bottleneck moves across its {n} points: {each}")
    return texts


def bottleneck_of_points(inputs: Inputs) -> str:
    """What "What limits it" says with no run or thesis cell to draw: the bottleneck PM of the sweep
    points that record their busy fractions, where any do, else that none does."""
    busy = [b for r in inputs.runs if r.kind == "sweep-point" and (b := _busy(r)) is not None]
    if not busy:
        return "No run, thesis cell or sweep point records its units' busy fractions: no bottleneck to show."
    tops = defaultdict(list)
    for b in busy:
        pm = max(PMS, key=lambda p: b[p])  # (the first of PM order on a tie)
        tops[pm].append(b[pm])
    each = "; ".join(f"{PM_METRIC[pm]} in {len(tops[pm])}, busy {_percent_range(tops[pm])}"
                     for pm in sorted(tops, key=lambda p: (-len(tops[p]), PMS.index(p))))
    moves = sweep_bottlenecks(inputs, moving=True)  # (where it moves within a sweep: at which points)
    return (f"<b>What limits it:</b> no run or thesis study among the inputs to draw; the bottleneck PM of the "
            f"{count(len(busy), 'sweep point')}: {each} of the time ({BUSIEST})."
            + (f" Within a sweep: {'; '.join(moves)}." if moves else ""))


def _percent_range(shares: list[float]) -> str:
    low, high = f"{100 * min(shares):.0f}", f"{100 * max(shares):.0f}"
    return f"{low if low == high else f'{low}–{high}'}%"


def references(keys: list) -> str:
    """``their reference`` where the errors are against one reference, ``their 2 references`` else."""
    n = len(set(keys))
    return "their reference" if n <= 1 else f"their {n} references"


def _point_errors(sw) -> tuple[list[tuple[float, str]], list]:
    """A sweep's finished photon-map points: ``(relative MSE, reference key)`` of those that measured
    their image error (sweep.csv's ``error.rel_mse``), and the runs of those that have none (no
    reference cached: ``results.json`` ``error.available`` false)."""
    measured, unmeasured = [], []
    for row in sw.rows:
        if row.get("status") != "ok":
            continue
        run = sw.run_of(row)
        error = run.results.get("error") if run is not None else None
        if number(row.get("error.rel_mse")):
            measured.append((float(row["error.rel_mse"]), str((error or {}).get("reference"))))
        elif isinstance(error, dict) and error.get("available") is False:
            unmeasured.append(run)
    return measured, unmeasured


def _unmeasured_command(sw, runs: list) -> str:
    """The ``tlm reference`` commands that compute the references the unmeasured points ``runs`` of the sweep
    ``sw`` need (one a reference key), as the sweep printed them on stderr: its base config file with the
    sweep's ``--set`` strings and what its ``set`` and the point's factors give of the keys a reference reads
    (:data:`~tlm.experiments.reference.KEY_READS`); for a sweep whose base is a mapping in the sweep file, which
    no command names, or whose base file is not found from here as the sweep read it (:func:`_base_config`),
    the first point's ``config.resolved.yaml`` (every setting of the point)."""
    import json

    from tlm.experiments.reference import KEY_READS
    from tlm.experiments.run import reference_command  # (tlm run's rule, as images.py's)

    by_key: dict[str, object] = {}
    for run in runs:
        by_key.setdefault(str((run.results.get("error") or {}).get("reference")), run)
    base = _base_config(sw)
    commands = []
    for run in by_key.values():
        if base is None:
            commands.append(reference_command(str((run.path / "config.resolved.yaml").absolute())))
            continue
        given = [k for k in (*(sw.spec.get("set") or {}), *run.factors)
                 if any(k == r or k.startswith(r + ".") or r.startswith(k + ".") for r in KEY_READS)]
        sets = [*sw.overrides, *(f"{k}={json.dumps(_dotted(run.config, k))}" for k in given)]
        commands.append(reference_command(base, sets))
    return "; ".join(commands)


def _dotted(config: dict, dotted: str):
    """The value of the dotted key ``dotted`` in a point's resolved ``config``."""
    for part in dotted.split("."):
        config = config.get(part) if isinstance(config, dict) else None
    return config


def _base_config(sw) -> str | None:
    """A sweep's base config file as its command line names it (as ``tlm sweep`` printed it): its path from
    the working folder, a built-in one's name; None for a mapping in the sweep file (sweep.yaml ``base_file``
    null). The sweep file's folder is that of sweep.yaml's ``sweep`` (as given to ``tlm sweep``); None too where
    the base is not found from here, or its content is not sweep.yaml's ``base`` (the report made from another
    folder than the sweep, the file edited since: the command would name no file or another one), so that the
    caller names the point's ``config.resolved.yaml``."""
    import os
    from pathlib import Path

    from tlm.builtin import base_path
    from tlm.config import read_yaml
    from tlm.errors import InputError

    base, source = sw.spec.get("base_file"), sw.spec.get("sweep")
    if not isinstance(base, str) or not base.strip():
        return None
    try:
        folder = Path(str(source)).resolve().parent if isinstance(source, str) and source else Path.cwd()
        file, builtin = base_path(base, folder, str(source), "sweep file")
        if isinstance(sw.spec.get("base"), dict) and (read_yaml(file) or {}) != sw.spec["base"]:
            return None  # (another file than the sweep read, or one edited since: the point's own config)
        return str(file) if builtin else os.path.relpath(file)
    except (InputError, OSError, ValueError):
        return None


def points_error(inputs: Inputs) -> str:
    """A sentence (after a space) on the image error of the finished sweep points that measured it against
    their reference (sweep.csv's ``error.rel_mse``; §4's points tables list it): how many of how many, of
    which sweeps, and the range; then one on the photon-map points that have none (no reference cached), with
    the ``tlm reference`` command that computes it; "" where no point has a photon-map error or lacks one."""
    found, missing = {}, {}
    sweeps = {sw.label: sw for sw in inputs.sweeps}
    for sw in inputs.sweeps:
        measured, unmeasured = _point_errors(sw)
        if measured:
            found[sw.label] = (measured, len(measured) + len(unmeasured))
        if unmeasured:
            missing[sw.label] = (unmeasured, len(measured) + len(unmeasured), sw.path)
    said = ""
    if found:
        every = [v for vs, _ in found.values() for v, _ in vs]
        lo, hi = f"{min(every):.3g}", f"{max(every):.3g}"
        refs = references([k for vs, _ in found.values() for _, k in vs])
        if all(len(vs) == n for vs, n in found.values()):  # (every photon-map point measured it)
            said += (f" The {count(len(every), 'sweep point')} of {esc(and_(list(found)))} that measured their image "
                     f"error have a relative MSE of {lo if lo == hi else f'{lo}–{hi}'} against {refs} (§4 lists each).")
        else:
            parts = [f"{len(vs)} of {n} points of {label}" if len(vs) < n else f"the {count(n, 'point')} of {label}"
                     for label, (vs, n) in found.items()]
            said += (f" {esc(and_(parts))} measured their image error: relative MSE "
                     f"{lo if lo == hi else f'{lo}–{hi}'} against {refs} (§4 lists each).")
    for label, (runs, n, path) in missing.items():
        keys = {str((r.results.get("error") or {}).get("reference")) for r in runs}
        command = _unmeasured_command(sweeps[label], runs)
        said += (f" {len(runs)} of {n} photon-map points of {esc(label)} have no image error: no reference is cached "
                 f"for them, and a sweep computes none; <code>{esc(command)}</code> computes "
                 f"{'it' if len(keys) == 1 else f'these {len(keys)} references'}, and the same 'tlm sweep' run again "
                 f"into {esc(str(path))} measures them from their cached frames.")
    return said
