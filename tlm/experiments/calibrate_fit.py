"""How well ``tlm calibrate``'s fit is determined, and the table it writes (out of :mod:`tlm.experiments.thesis`).

The fit (:func:`tlm.experiments.thesis.calibrate`) is, per PM, non-negative least squares on the relative
error of the RCast cells: Vertex one parameter (``scale``), Traversal and Fragment two (``scale`` and
``record_cycles``), each on one cell per scene. With three scenes that leaves 2, 1 and 1 degrees of freedom,
so :func:`fit_statistics` says how poorly it may be determined: the in-sample residuals (median and max
|relative error|), the degrees of freedom, each parameter's standard error (from the Jacobian of the
relative residuals, ``sqrt(s^2 diag((J^T J)^-1))`` with ``s^2`` the residual sum of squares over the degrees
of freedom; a parameter on its bound, 0, is named: its error is the unconstrained linearisation's) and the
condition number of ``J`` with its columns scaled to unit length (so independent of the
parameters' units: scale, cycles per record). ``tlm calibrate`` prints them
(:func:`tlm.cli_tables.fit_lines`), :func:`write_calibrated` records them in the table's ``calibration.fit`` block,
and ``--leave-one-out`` prints a leave-one-scene-out check (:func:`tlm.experiments.thesis.leave_one_out`,
:func:`tlm.cli_tables.held_out_lines`).
"""

from __future__ import annotations

import datetime
import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from tlm.arch.costs import DEFAULT_PATH, PROGRAMMABLE, Programs
from tlm.arch.model import simulate
from tlm.experiments.thesis_tables import FIT_PMS, FIT_RECORDS, thesis_value
from tlm.experiments.thesis_tables import ours as _ours
from tlm.storage import write_file


def fit_scale(n: np.ndarray, m: np.ndarray, y: np.ndarray) -> float:
    """argmin_s sum(((s n + m - y) / y)^2), s >= 0: the scale of one PM's instructions."""
    a, b = n / y, (y - m) / y
    denom = float(a @ a)
    return max(float(a @ b) / denom, 0.0) if denom > 0 else 1.0


def fit_scale_and_records(n: np.ndarray, k: np.ndarray, m: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """argmin over s, c >= 0 of sum(((s n + c k + m - y) / y)^2): a PM's scale and record cycles."""
    from scipy.optimize import nnls

    a = np.column_stack([n / y, k / y])
    (scale, cycles), _ = nnls(a, (y - m) / y)
    return float(scale), float(cycles)


def fitted_parameters() -> list[str]:
    return [f"{pm}.scale" for pm in FIT_PMS] + [f"{pm}.record_cycles" for pm in FIT_RECORDS]


def fit_statistics(columns: dict[str, np.ndarray], values: dict[str, float], y: np.ndarray,
                   fitted: np.ndarray) -> dict:
    """One PM's fit: ``columns``, each fitted parameter -> its cycles per unit on each cell (instructions, or
    records, per frame); ``values`` the parameters as fitted; ``y`` the thesis's cells, ``fitted`` ours after
    the fit (cycles). The relative residuals ``(fitted - y) / y``: their median and max absolute value, the
    degrees of freedom (cells less parameters), each parameter's standard error (None without a degree of
    freedom, or where ``J^T J`` is singular), those on their bound (0) and the condition number of ``J`` with
    its columns scaled to unit length (independent of each parameter's units; inf where a column is 0)."""
    y = np.asarray(y, dtype=float)
    r = (np.asarray(fitted, dtype=float) - y) / y
    names = list(columns)
    jac = np.column_stack([np.asarray(columns[p], dtype=float) / y for p in names])
    dof = len(y) - len(names)
    norms = np.linalg.norm(jac, axis=0)
    # (of J with each column scaled to unit length: a parameter's units, cycles or kilocycles a record, move
    # J's own condition number (561 against 4.5 for traversal's fit) but not how well the fit is determined)
    cond = float(np.linalg.cond(jac / np.where(norms > 0, norms, 1.0))) if np.all(norms > 0) else float("inf")
    se: dict[str, float | None] = dict.fromkeys(names)
    if dof > 0 and np.isfinite(cond) and cond < 1e12:
        cov = float(r @ r) / dof * np.linalg.inv(jac.T @ jac)
        se = {p: float(np.sqrt(max(cov[i, i], 0.0))) for i, p in enumerate(names)}
    return {"cells": len(y), "parameters": {p: float(values[p]) for p in names}, "dof": dof,
            "median_abs_rel_error": float(np.median(np.abs(r))), "max_abs_rel_error": float(np.max(np.abs(r))),
            "standard_errors": se, "on_bound": [p for p in names if values[p] <= 0.0], "condition_number": cond}


def _g(v: float | None) -> str:
    return "none" if v is None else f"{v:.4g}"


def _cond(v: float) -> str:
    """A condition number as YAML reads it back as a number: a singular fit's infinite one as ``.inf`` (``inf``
    is YAML's string 'inf')."""
    return ".inf" if np.isinf(v) else ".nan" if np.isnan(v) else f"{v:.4g}"


def summary(errors: list[float]) -> dict:
    a = np.abs(np.asarray(errors, dtype=float))
    return {"median": float(np.median(a)), "max": float(np.max(a)), "cells": len(a)}


def _fit_block(stats: dict[str, dict]) -> str:
    rows = []
    for pm, s in stats.items():
        se = ", ".join(f"{p.split('.', 1)[1]}: {_g(v)}" for p, v in s["standard_errors"].items())
        bound = ", ".join(p.split(".", 1)[1] for p in s["on_bound"])
        rows.append(f"    {pm}: {{median: {s['median_abs_rel_error']:.4g}, max: {s['max_abs_rel_error']:.4g}, "
                    f"dof: {s['dof']}, se: {{{se}}}, on_bound: [{bound}], cond: {_cond(s['condition_number'])}}}")
    return ("  fit:  # per PM: in-sample |rel error| median and max, degrees of freedom, standard errors, "
            "parameters on their bound, condition number\n" + "\n".join(rows) + "\n")


def write_calibrated(programs: Programs, report: dict, target: Path, command: str) -> None:
    """Rewrite the table's ``scale`` and ``record_cycles`` values and ``calibration`` block, keeping its comments."""
    source = Path(programs.source) if Path(programs.source).exists() else DEFAULT_PATH
    text = source.read_text(encoding="utf-8")  # (as load_programs reads it, and write_file writes it: UTF-8)
    for pm in PROGRAMMABLE:
        section = re.search(rf"^{pm}:\n(?:(?:[ \t].*|)\n)*", text, re.MULTILINE)
        if section is None:
            raise ValueError(f"{source}: no '{pm}:' section")
        body = section.group(0)
        for name, value in (("scale", programs.scale[pm]), ("record_cycles", programs.record_cycles[pm])):
            body, n = re.subn(rf"^(  {name}: )[^\n#]*?(?=[ \t]*(?:#|$))", lambda m, v=value: m.group(1) + f"{v:.6g}",
                              body, count=1, flags=re.MULTILINE)
            if n != 1 and name == "record_cycles":  # a table without the line: add it below the scale
                body, n = re.subn(r"^(  scale: [^\n]*\n)",
                                  lambda m, v=value: m.group(1) + f"  record_cycles: {v:.6g}\n",
                                  body, count=1, flags=re.MULTILINE)
            if n != 1:
                raise ValueError(f"{source}: cannot find '{pm}:' followed by its '{name}:' line")
        text = text[:section.start()] + body + text[section.end():]
    cells = "\n".join(
        f"    {s}: {{" + ", ".join(f"{m}: [{v['thesis']}, {v['ours']}]" for m, v in c.items()) + "}"
        for s, c in report["cells"].items())
    block = (
        "calibration:\n"
        f"  command: {json.dumps(command)}\n"
        f"  date: {datetime.date.today().isoformat()}\n"
        f"  fitted: [{', '.join(report.get('fitted', fitted_parameters()))}]\n"
        "  cells:  # RCast, millions of cycles: [thesis, ours after the fit]\n"
        f"{cells}\n"
        + (_fit_block(report["fit"]) if report.get("fit") else "")
    )
    text, n = re.subn(r"^calibration:[^\n]*\n(?:[ \t]+.*\n)*", block, text, count=1, flags=re.MULTILINE)
    if n != 1:  # a table without the block: it goes at the end
        text = text + ("" if text.endswith("\n") else "\n") + block
    write_file(target, text)  # (atomically, through a hidden temporary file of its own)


# -- the fit (tlm.experiments.thesis.calibrate and leave_one_out) ---------------------------------

def norm_per_frame(fns: dict, programs: Programs) -> dict[str, dict[str, float]]:
    """T_norm per frame of every PM and scene under ``programs``."""
    out: dict[str, dict[str, float]] = {}
    for s, (fn, cfg) in fns.items():
        sim = simulate(fn, programs, cfg.arch)
        out[s] = {pm: sim.units[f"pipe0.{pm}"]["T_norm"] / len(sim.frames) for pm in FIT_PMS}
    return out


def fit(inputs: dict, scenes: list[str], iterations: int, progress) -> tuple[Programs, list, dict, dict]:
    """The fit to ``scenes`` (of ``inputs``, :func:`_calibration_inputs`): the fitted table, the history of its
    iterations, each scene's simulation under it and, per PM, its :func:`fit_statistics`."""
    tables, fns, instructions, records = inputs["tables"], inputs["fns"], inputs["instructions"], inputs["records"]
    programs = inputs["programs"]
    # start from unit scales and no cycles per record where those are fitted (a PM
    # outside FIT_RECORDS keeps the table's record_cycles, a fixed part of its cost)
    programs = programs.with_scales(dict.fromkeys(PROGRAMMABLE, 1.0), dict.fromkeys(FIT_RECORDS, 0.0))
    history = []
    for it in range(iterations):
        sims = {s: simulate(fns[s][0], programs, fns[s][1].arch) for s in scenes}
        scales, cycles = {}, {}
        for pm, metric in FIT_PMS.items():
            y = np.array([thesis_value(tables[s], "rcast", metric) * 1e6 for s in scenes])
            frames = np.array([len(sims[s].frames) for s in scenes], dtype=float)
            norm = np.array([sims[s].units[f"pipe0.{pm}"]["T_norm"] for s in scenes], dtype=float) / frames
            other = np.array([sims[s].cycles[pm] for s in scenes], dtype=float) - norm
            n = np.array([instructions[s][pm] for s in scenes])
            k = np.array([records[s][pm] for s in scenes])
            if pm in FIT_RECORDS:
                scales[pm], cycles[pm] = fit_scale_and_records(n, k, other, y)
            else:  # T_norm's record part is fixed here: it joins the rest
                cycles[pm] = programs.record_cycles[pm]
                scales[pm] = fit_scale(n, other + cycles[pm] * k, y)
        params = {**{f"{p}.scale": v for p, v in scales.items()},
                  **{f"{p}.record_cycles": cycles[p] for p in FIT_RECORDS}}
        history.append({"iteration": it, "parameters": params,
                        "cells": {tables[s]: _ours(sims[s].cycles, sims[s].fps) for s in scenes}})
        if progress is not None:
            progress(it, params)
        converged = all(abs(scales[p] - programs.scale[p]) <= 1e-6 * max(scales[p], 1e-12)
                        and abs(cycles[p] - programs.record_cycles[p]) <= 1e-6 * max(cycles[p], 1e-12)
                        for p in scales)
        programs = programs.with_scales(scales, cycles)
        if converged:
            break
    sims = {s: simulate(fns[s][0], programs, fns[s][1].arch) for s in scenes}
    stats = {}
    for pm, metric in FIT_PMS.items():
        columns = {f"{pm}.scale": np.array([instructions[s][pm] for s in scenes])}
        if pm in FIT_RECORDS:
            columns[f"{pm}.record_cycles"] = np.array([records[s][pm] for s in scenes])
        values = {f"{pm}.scale": programs.scale[pm], f"{pm}.record_cycles": programs.record_cycles[pm]}
        stats[pm] = fit_statistics(columns, values, np.array([thesis_value(tables[s], "rcast", metric) * 1e6
                                                              for s in scenes]),
                                   np.array([sims[s].cycles[pm] for s in scenes], dtype=float))
    return programs, history, sims, stats


def held_out(inputs: dict, iterations: int = 4, progress=None) -> dict:
    """:func:`tlm.experiments.thesis.leave_one_out` of a study's checked, rendered ``inputs``
    (:func:`tlm.experiments.thesis._calibration_inputs`): for each scene the fit to the others and its cells."""
    scenes, tables, fns = inputs["scenes"], inputs["tables"], inputs["fns"]
    _, _, sims, _ = fit(inputs, scenes, iterations, None)
    out: dict[str, Any] = {"scenes": {}}
    inside, held = [], []
    for left in scenes:
        # (the left-out scene by its table's name, as the result lines and ``scenes`` name it: thesis/ring is ring)
        tell = None if progress is None else (lambda it, params, left=tables[left]: progress(left, it, params))
        programs, _, _, _ = fit(inputs, [s for s in scenes if s != left], iterations, tell)
        fn, cfg = fns[left]
        sim = simulate(fn, programs, cfg.arch)
        ours, full = _ours(sim.cycles, sim.fps), _ours(sims[left].cycles, sims[left].fps)
        cells = {}
        for m in FIT_PMS.values():
            t = thesis_value(tables[left], "rcast", m)
            cells[m] = {"thesis": t, "ours": round(ours[m], 4), "rel_error": (ours[m] - t) / t,
                        "in_sample": (full[m] - t) / t}
            held.append(cells[m]["rel_error"])
            inside.append(cells[m]["in_sample"])
        params = {**{f"{p}.scale": programs.scale[p] for p in FIT_PMS},
                  **{f"{p}.record_cycles": programs.record_cycles[p] for p in FIT_RECORDS}}
        out["scenes"][tables[left]] = {"parameters": params, "cells": cells}
    out.update(held_out=summary(held), in_sample=summary(inside),
               not_comparable={s: w for s, w in inputs["differ"].items() if w})
    return out
