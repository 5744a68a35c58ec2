"""The summary's sentences on the sweeps' points (:mod:`tlm.report.summary` says them): their frame
rates where no run or thesis study has one to draw (:func:`fps_of_points`), their bottleneck PM, per sweep
and across them (:func:`sweep_bottlenecks`, :func:`bottleneck_of_points`), and their image error, with the
``tlm reference`` command for the photon-map points that have none (:func:`points_error`, their
references counted by :func:`references`).
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

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
    """``a``, ``a and b``, ``a, b and c``."""
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} and {items[-1]}"


def fps_of_points(inputs: Inputs) -> str:
    """What "How fast" says with no run or thesis study to draw: the sweep points' frame rates, where
    the inputs have any (§4 draws them against each factor), else that there is none."""
    points = [r for r in inputs.runs if r.kind == "sweep-point" and number(r.results.get("fps"))
              and r.results["fps"] > 0]
    if not points:
        return "No run, thesis study or finished sweep point among the inputs: no frame rate to show."
    lo, hi = min(points, key=lambda r: r.results["fps"]), max(points, key=lambda r: r.results["fps"])
    rng = (f"{lo.results['fps']:.3g} FPS" if lo is hi else
           f"from {lo.results['fps']:.3g} FPS ({esc(lo.label)}) to {hi.results['fps']:.3g} FPS ({esc(hi.label)})")
    return (f"<b>How fast:</b> no run or thesis study among the inputs to draw per scene and mode; the "
            f"{count(len(points), 'sweep point')} run {rng} (§4 draws them against each factor).")


def _busy(r: Run) -> dict[str, float] | None:
    """The busy share of each PM of pipeline 0 that ``r`` records; None where it lacks one."""
    units = (r.results.get("timing") or {}).get("units") or {}
    busy = {pm: units[f"pipe0.{pm}"]["fractions"].get("busy") for pm in PMS
            if isinstance(units.get(f"pipe0.{pm}"), dict) and isinstance(units[f"pipe0.{pm}"].get("fractions"), dict)}
    return busy if len(busy) == len(PMS) and all(number(v) for v in busy.values()) else None


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
            f"{count(len(busy), 'sweep point')}: {each} of the time."
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
    runs = {r.path.name: r for r in sw.runs}
    measured, unmeasured = [], []
    for row in sw.rows:
        if row.get("status") != "ok":
            continue
        run = runs.get(str(row.get("hash")))
        error = run.results.get("error") if run is not None else None
        if number(row.get("error.rel_mse")):
            measured.append((float(row["error.rel_mse"]), str((error or {}).get("reference"))))
        elif isinstance(error, dict) and error.get("available") is False:
            unmeasured.append(run)
    return measured, unmeasured


def _unmeasured_command(runs: list) -> str:
    """The ``tlm reference`` commands that compute the references the unmeasured points ``runs`` need
    (one a reference key, from its first point's ``config.resolved.yaml``: every setting of the point),
    as the sweep printed them on stderr."""
    from tlm.experiments.run import reference_command  # (tlm run's rule, as images.py's)

    by_key: dict[str, object] = {}
    for run in runs:
        by_key.setdefault(str((run.results.get("error") or {}).get("reference")), run)
    return "; ".join(reference_command(str((run.path / "config.resolved.yaml").absolute())) for run in by_key.values())


def points_error(inputs: Inputs) -> str:
    """A sentence (after a space) on the image error of the finished sweep points that measured it against
    their reference (sweep.csv's ``error.rel_mse``; §4's points tables list it): how many of how many, of
    which sweeps, and the range; then one on the photon-map points that have none (no reference cached), with
    the ``tlm reference`` command that computes it; "" where no point has a photon-map error or lacks one."""
    found, missing = {}, {}
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
        said += (f" {len(runs)} of {n} photon-map points of {esc(label)} have no image error: no reference is cached "
                 f"for them, and a sweep computes none; <code>{esc(_unmeasured_command(runs))}</code> computes "
                 f"{'it' if len(keys) == 1 else f'these {len(keys)} references'}, and the same 'tlm sweep' run again "
                 f"into {esc(str(path))} measures them from their cached frames.")
    return said
