"""Section: what each sweep varied and what it did to the frame rate.

Per sweep, a table of its points (factors, status, simulated FPS, TThru, the slowest
PM, whether it reused a render where one did (its host s then time none), host seconds less their one-off
part, numba compiling and first imports, said in a note under it, and where they were measured: the host and
Dask worker that ran the points, said once where one ran them all, else a column,
:func:`~tlm.report.provenance.ran_note`; a failed point with its error) and one figure per varied factor:
the simulated FPS against that factor's values, one line per combination of the other
factors. Combinations that draw the same line are drawn once, one label naming them all,
and the lines are counted after that: up to :data:`MAX_SERIES` distinct lines are drawn
as lines (40 combinations that draw 2 lines are 2 lines); more are drawn as the median
over the combinations with the min-max band, and the caption and a note say what the
band is. A factor that is not a number (a scene, a mode) is a category: its values are
points side by side (the median and a min-max bar beyond :data:`MAX_SERIES` distinct
lines), never joined by a line. A factor of numbers with null among its values (``bsp.levels:
[null, 6, 8]``, null the thesis's depth) keeps its axis of numbers: the null points are drawn
apart, at the value they resolved to where their results folder records it, else at a tick
``null`` beside the numbers (:func:`~tlm.report.sweep_lines.draw_nulls`). A point's scene is named as the report
names scenes, by its file (:func:`named_rows`); a factor's value as its YAML writes it, ``null`` (not ``None``) with
what null asks of its key where the key's help says (``levels=null (floor(ln n))``,
:func:`~tlm.report.names.value_text`). The legend is under the plot, its labels wrapped to the
figure's width, and the figure grows by its height, so that no label squeezes the plot.
A sweep folder's ``points/`` may also hold point folders that are not its points (an
earlier run of other code or another config into the folder: a point's hash holds both);
the section counts them (:func:`other_point_folders`).

A sweep over ``bsp.levels`` also gets the thesis's balance claim ("floor(ln n) levels,
with n denoting the number of photons and/or triangles, yields good performance balance"
of the Traversal and Intersection PMs) tested: Ttrav / Tisct (the rows' cycles.traversal
over cycles.intersection) and the simulated FPS against the levels, one line per scene
and combination of the other factors (those that draw the same line drawn once, and
counted after that against :data:`MAX_SERIES`, :func:`levels_lines`), a vertical marker
at each scene's floor(ln n) (n from the points' results.json) and a table of the ratio
and FPS there, the level whose ratio is closest to 1 and the level of the best FPS
(:func:`levels_balance`). Points of one series at one level that measured the same (``bsp.levels:
null`` asks for floor(ln n), which the sweep may ask for by number too) are shown once, a note
counting the repeats (:func:`_one_per_level`); the points table gives each point's Ttrav / Tisct.
A note that names points or series names a few of many and counts them all
(:func:`~tlm.report.common.some`).
"""

from __future__ import annotations

import math
import os
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from tlm.config_words import listing
from tlm.kernels.bsp import default_levels
from tlm.report.collect import Inputs, Sweep, with_set
from tlm.report.common import NAMED, Figure, FigureName, Section, count, line_style, new_figure, save, some
from tlm.report.html import esc
from tlm.report.names import value_text
from tlm.report.provenance import ran_by, ran_label, ran_note
from tlm.report.sweep_lines import (
    LEVELS,
    all_numbers,
    column_decimals,
    column_texts,
    dodge,
    draw_nulls,
    factor_axis,
    hashable,
    legend_under,
    merge_groups,
    null_points,
    order_key,
    same_value,
)

MAX_SERIES = 8
MAX_ROWS = 200
LABEL_COMBOS = 3  # a legend label of more than MAX_SERIES identical combinations (no product) names this many
PMS = ("vertex", "traversal", "intersection", "fragment")
FACTOR_SIZE = (7.0, 4.5)  # inches, the FPS-against-a-factor figure without its legend
LEVELS_SIZE = (13.0, 4.8)  # inches, the BSP-levels figure without its legend
# a swept key's name and unit on a figure's axis, where tlm knows them (else the dotted key alone): axis_label
AXIS_NAMES = {
    "arch.fifo_depth": ("FIFO depth", "entries"), "arch.pipelines": ("pipelines N", ""),
    "arch.packet_size": ("packet size", "rays, pixels or photons"), "arch.clock_hz": ("clock", "Hz"),
    "arch.page_miss_cycles": ("page-miss time T_ms", "cycles"), "arch.flush_cycles": ("flush time T_ps", "cycles"),
    "arch.swap_cycles": ("swap time", "cycles"), "arch.context_switch_cycles": ("context switch", "cycles"),
    "arch.copy_words_per_cycle": ("block copy rate", "128-bit words per cycle"),
    "arch.tiles_per_pipeline": ("tiles per pipeline", ""), "cache.pairs": ("cache block pairs per PM", ""),
    "cache.block_words": ("cache block", "128-bit words"), "bsp.levels": ("BSP levels", ""),
    "photons.count": ("photons emitted", ""), "photons.max_bounces": ("photon bounces", "surface hits"),
    "estimate.radius": ("search radius", "scene units"), "estimate.k": ("k-voxel samples k", ""),
    "estimate.final_gather": ("final-gather rays", "per gather point"), "estimate.k_nearest": ("k nearest", ""),
}


def axis_label(factor: str) -> str:
    """``factor`` on a figure's axis: its name and unit where tlm knows them (``FIFO depth (arch.fifo_depth,
    entries)``, :data:`AXIS_NAMES`), else the dotted key."""
    name, unit = AXIS_NAMES.get(factor, ("", ""))
    return f"{name} ({factor}{', ' + unit if unit else ''})" if name else factor


# a sweep row's image error against the point's reference (sweep.csv), and its column's head in the points table
ERROR_COLUMNS = {"error.rel_mse": "relative MSE", "error.rmse": "RMSE"}
REUSED = "reused"  # a point's "render" cell where it reused a render (sweep.csv functional_cached): none timed


def _finite(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def factors_of(sw: Sweep) -> list[str]:
    return [*(sw.spec.get("grid") or {}), *(sw.spec.get("zip") or {})]


def named_rows(sw: Sweep) -> list[dict]:
    """The sweep's rows with a point's ``scene`` as the report names scenes (the scene file's
    name under ``scenes/``, :attr:`~tlm.report.collect.Run.scene_label`), not as its config
    wrote it: the sweep's ``room`` and a thesis study's ``room`` may be two files. A row
    without a results folder keeps what its config wrote."""
    out = []
    for r in sw.rows:
        run = sw.run_of(r)
        out.append({**r, "scene": run.scene_label} if run is not None and "scene" in r else r)
    return out


def _listed(what: str, values: list[str]) -> str:
    """``scene a``, ``scenes a and b``, ``scenes a, b and c``."""
    return f"{what}{'s' * (len(values) > 1)} {listing(values)}"


def described(sw: Sweep) -> str:
    """What the sweep ran, as its captions say it: its sweep file's ``description``; where it ran with
    ``--set`` overrides (sweep.yaml ``overrides``), which may change what that description names (another
    scene, mode or resolution), the scenes and modes its points resolved to and the overrides, the
    description after them as its file wrote it."""
    desc = str(sw.spec.get("description") or "").strip()
    if not sw.overrides:
        return desc
    rows = named_rows(sw)
    scenes = list(dict.fromkeys(str(r["scene"]) for r in rows if r.get("scene") is not None))
    modes = list(dict.fromkeys(str(r["mode"]) for r in rows if r.get("mode") is not None))
    ran = ", ".join(_listed(w, v) for w, v in (("scene", scenes), ("mode", modes)) if v)
    text = f"{ran + ', ' if ran else ''}{with_set(sw.overrides)}"
    return f"{text} (its sweep file's description, before the --set: “{desc.rstrip('.')}”)." if desc \
        else f"{text}."


def _ratio_text(r: dict) -> str:
    """A row's Ttrav / Tisct (cycles.traversal / cycles.intersection), "" where it has none."""
    trav, isct = r.get("cycles.traversal"), r.get("cycles.intersection")
    return f"{trav / isct:.4f}" if isinstance(trav, int | float) and isinstance(isct, int | float) and isct else ""


def table(sw: Sweep) -> str:
    """The sweep's points, one row each (the first :data:`MAX_ROWS`); a sweep over ``bsp.levels``
    also gets each point's Ttrav / Tisct, so that every point of its BSP-levels balance is shown
    as a number (its table summarises each series in one row, and its figure may be left out)."""
    factors = factors_of(sw)
    ratio = LEVELS in factors
    rows = sorted(named_rows(sw), key=lambda r: r.get("point", 0))
    # (the points' image error against their reference, where they measured it: sweep.csv's error.rel_mse and
    # error.rmse, a column each)
    errs = [k for k in ERROR_COLUMNS if any(_finite(r.get(k)) for r in rows if r.get("status") == "ok")]
    # (who ran each point, the host and the Dask worker: a column only where more than one did, else said once)
    whos = [ran_by(r) for r in rows]
    ran = len({w for w in whos if w is not None}) > 1
    # (whether each point rendered its frame or reused one, a column where one reused it: its host s are then not a
    # faster host's, h531)
    reused = any(r.get("functional_cached") is True for r in rows if r.get("status") == "ok")
    head = ["point", *factors, "status", "FPS", "TThru (M cycles)", *(["Ttrav / Tisct"] if ratio else []),
            *(ERROR_COLUMNS[k] for k in errs), "slowest PM", *(["render"] if reused else []), "host s",
            *(["ran on"] if ran else [])]
    out = ['<table><tr>' + "".join(f"<th>{esc(h)}</th>" for h in head) + "</tr>"]
    # each column's numbers in one notation (column_texts): a factor's values, FPS, TThru, host seconds
    shown = rows[:MAX_ROWS]
    ok = [r for r in shown if r.get("status") == "ok"]
    columns = {f: column_texts([r.get(f) for r in shown], lambda v, f=f: value_text(f, v)) for f in factors}
    # (the measured columns to one count of decimals each: column_decimals)
    fps = column_decimals([r.get("fps") for r in ok])
    thru = column_decimals([(r.get("cycles.throughput") or 0) / 1e6 for r in ok])
    # (host seconds less the one-off part: numba compiling or loading kernels and first imports, paid by whichever
    # points a worker ran first, not by their settings; sweep.csv's seconds.one_off)
    host = column_decimals([round(_host_seconds(r), 3) for r in ok])
    err = {e: column_decimals([r.get(e) if _finite(r.get(e)) else None for r in ok], lambda _v: "") for e in errs}
    k = 0  # (the row's place among the finished ones)
    for i, r in enumerate(shown):
        if r.get("status") == "ok":
            slow = max(PMS, key=lambda p: r.get(f"cycles.{p}") or 0)
            render = [REUSED if r.get("functional_cached") is True else "done"] if reused else []
            cells = [fps[k], thru[k], *([_ratio_text(r)] if ratio else []), *(err[e][k] for e in errs), slow,
                     *render, host[k]]
            k += 1
        else:
            cells = [f"failed: {r.get('error')}", "", *([""] if ratio else []), *("" for _ in errs), "",
                     *([""] if reused else []), ""]
        vals = [str(r.get("point")), *(columns[f][i] for f in factors), str(r.get("status")), *cells,
                *([ran_label(whos[i])] if ran else [])]
        out.append("<tr>" + "".join(f"<td>{esc(v)}</td>" for v in vals) + "</tr>")
    out.append("</table>")
    once = [r for r in ok if _finite(r.get("seconds.one_off"))]
    if once:
        paid = [r for r in once if r["seconds.one_off"] >= 0.0005]
        where = (f"{sum(r['seconds.one_off'] for r in paid):.3g} s in all, paid by "
                 f"{_points([str(r.get('point')) for r in paid])}" if paid else "none here")
        out.append('<p class="note">host s: a point\'s host seconds (sweep.csv seconds.functional, '
                   "seconds.simulate and seconds.write) less their one-off part, seconds.one_off: numba compiling or "
                   "loading kernels "
                   "and modules imported for the first time, paid by whichever points each worker ran first, not "
                   f"by their settings ({esc(where)}).</p>")
    if reused:  # (not a faster host: no render to do)
        out.append(f'<p class="note">render {REUSED}: the point took its frame from the functional cache, rendered '
                   "before by another point or run (sweep.csv functional_cached), and its host s leave out that "
                   "render's seconds (§9 gives them).</p>")
    if (where := ran_note(whos)) is not None:  # (host s are that machine's: sweep.csv's worker and host)
        out.append(f'<p class="note">{esc(where)}.</p>')
    if len(rows) > MAX_ROWS:
        out.append(f'<p class="note">The first {MAX_ROWS} of {len(rows)} points are listed; '
                   f"all are in {esc(sw.path / 'sweep.csv')}.</p>")
    return "\n".join(out)


def _host_seconds(r: dict) -> float:
    """A row's host seconds less their one-off part (``seconds.one_off``; none in a sweep.csv of
    before it was measured)."""
    once = r.get("seconds.one_off")
    return max(0.0, (r.get("seconds.functional") or 0) + (r.get("seconds.simulate") or 0)
               + (r.get("seconds.write") or 0) - (once if _finite(once) else 0.0))


def _combo_label(others: list[str], combo: tuple) -> str:
    return ", ".join(f"{f.split('.')[-1]}={value_text(f, c)}" for f, c in zip(others, combo, strict=True)) or "FPS"


def _alternatives(factor: str, values: list) -> str:
    """``1, 16, 256 or 4096``."""
    return listing([value_text(factor, v) for v in values], last="or")


def _group_label(others: list[str], combos: list[tuple]) -> str:
    """The legend label of combinations of the other factors that draw one line.

    One combination: ``levels=7, fifo_depth=16``. Several that are every combination of
    some values of each factor: each factor once, ``levels=7; fifo_depth=1, 16, 256 or 4096
    (identical)``; any other set: the combinations joined by `` | ``, ``(identical)`` added,
    the first :data:`LABEL_COMBOS` and how many more where they are more than :data:`MAX_SERIES`."""
    if len(combos) == 1:
        return _combo_label(others, combos[0])
    values = [sorted({c[i] for c in combos}, key=order_key) for i in range(len(others))]
    if math.prod(len(v) for v in values) == len(set(combos)):
        return "; ".join(f"{f.split('.')[-1]}={_alternatives(f, v)}" for f, v in zip(others, values, strict=True)) \
            + " (identical)"
    if len(combos) > MAX_SERIES:  # (the table above lists every point)
        return (" | ".join(_combo_label(others, c) for c in combos[:LABEL_COMBOS])
                + f" and {len(combos) - LABEL_COMBOS} more combinations (identical)")
    return " | ".join(_combo_label(others, c) for c in combos) + " (identical)"


def factor_figure(sw: Sweep, factor: str, out: Path, notes: list[str]):
    """FPS against ``factor``; one line per combination of the other factors, combinations
    that draw the same line drawn once (:func:`merge_groups`), their label naming them all; more than
    :data:`MAX_SERIES` distinct lines are drawn as the median over the combinations and the
    min-max band (the caption says so). A factor of numbers is an axis of numbers and its
    points are joined by lines; any other factor (a scene, a mode: categories, with no
    order or distance between them) is drawn as points at its categories, the lines side
    by side, with no line between categories. The null points of a factor of numbers and
    null are drawn apart on its axis of numbers (:func:`draw_nulls`), not as a category."""
    ok = [r for r in named_rows(sw) if r.get("status") == "ok" and r.get("fps") is not None]
    others = [f for f in factors_of(sw) if f != factor]
    values = sorted({hashable(r.get(factor)) for r in ok}, key=order_key)
    if len(values) < 2:
        return None
    # a factor of numbers and null (bsp.levels: [null, 6, 8]): the numbers on an axis of numbers, the null
    # points apart (:func:`null_points`), not a category of their own
    nulls = ([r for r in ok if r.get(factor) is None] if None in values
             and all_numbers([r.get(factor) for r in ok if r.get(factor) is not None]) else [])
    if nulls:
        values = [v for v in values if v is not None]
    numeric = all_numbers([r.get(factor) for r in ok if not (nulls and r.get(factor) is None)])
    if not numeric:  # categories in the sweep's order (its points are numbered in its grid's order), not by name
        first: dict = {}
        for r in sorted(ok, key=lambda r: order_key(r.get("point"))):
            first.setdefault(hashable(r.get(factor)), len(first))
        values = sorted(values, key=lambda v: first.get(v, len(first)))
    series: dict[tuple, dict] = defaultdict(dict)
    for r in ok:
        if not (nulls and r.get(factor) is None):
            series[tuple(hashable(r.get(f)) for f in others)][hashable(r.get(factor))] = r["fps"]
    fig = new_figure(*FACTOR_SIZE)
    ax = fig.subplots()
    xs_of = (lambda vs: vs) if numeric else (lambda vs: [values.index(v) for v in vs])
    # (the series with the same points drawn once, a label naming them all: a line that hides another would
    # read as one combination; None beyond MAX_SERIES distinct lines)
    merged = merge_groups(series, MAX_SERIES)
    lines = None if merged is None else [(_group_label(others, combos), pts) for combos, pts in merged]
    combos = f"{len(series)} combinations of {', '.join(others)}" if len(series) > 1 else ""
    if lines is not None:
        for i, (labels, pts) in enumerate(lines):
            vs = [v for v in values if v in pts]
            if numeric:
                ax.plot(xs_of(vs), [pts[v] for v in vs], label=labels, **line_style(i))
            else:  # (categories: points side by side at each, no line across)
                dx = dodge(i, len(lines))
                ax.plot([x + dx for x in xs_of(vs)], [pts[v] for v in vs], label=labels,
                        **{**line_style(i), "linestyle": "none", "markersize": 7})
        drawn = (f" The {combos} draw {len(lines)} distinct line{'s' if len(lines) > 1 else ''}: identical ones "
                 "are drawn once, their label naming them all." if len(lines) < len(series) else "")
    else:
        med, lo, hi = [], [], []
        for v in values:
            ys = sorted(pts[v] for pts in series.values() if v in pts)
            med.append(float(np.median(ys)))  # (the mean of the two middle values when their count is even)
            lo.append(ys[0])
            hi.append(ys[-1])
        spread = f"min-max over {combos}"
        if numeric:
            ax.fill_between(xs_of(values), lo, hi, color="0.8", hatch="///", edgecolor="0.5", label=spread)
            ax.plot(xs_of(values), med, label="median", **line_style(0))
        else:  # (categories: the median as a point, the range as a bar through it, no line across)
            ax.errorbar(xs_of(values), med, yerr=[np.subtract(med, lo), np.subtract(hi, med)], fmt="none",
                        ecolor="0.35", elinewidth=6, alpha=0.45, label=spread)
            ax.plot(xs_of(values), med, label="median", **{**line_style(0), "linestyle": "none", "markersize": 7})
        notes.append(f"{sw.label}: FPS against {factor} shows the median and the min-max range over the "
                     f"{combos}: they draw more than {MAX_SERIES} distinct lines")
        band = "band" if numeric else "bar"
        drawn = (f" The {combos} draw more than {MAX_SERIES} distinct lines: the {band} at each value of {factor} "
                 f"spans the lowest to the highest FPS of those combinations there, the "
                 f"{'line' if numeric else 'point'} is their median (the mean of the two middle values when their "
                 "count is even, a value no point need have).")
    null_text = ""
    if numeric:
        nulled = null_points(sw, factor, nulls, others)
        xs = [*values, *(x for _, x, _ in nulled if x is not None)]
        lo_v, hi_v = min(xs), max(xs)
        log = factor_axis(ax, factor, xs)  # (log from 8x, base 2 over powers of two; ticked at the values where few)
        if nulled:
            index = {} if merged is None else {c: i for i, (cs, _) in enumerate(merged) for c in cs}
            null_text = draw_nulls(ax, factor, nulled, index, lines is None, (lo_v, hi_v), log)
    else:
        ax.set_xticks(range(len(values)), [value_text(factor, v) for v in values])
        ax.set_xlim(-0.5, len(values) - 0.5)
    fps = [r["fps"] for r in ok]
    if min(fps) > 0 and max(fps) / min(fps) >= 100:
        ax.set_yscale("log")
    ax.set(xlabel=axis_label(factor), ylabel="simulated frames per second (FPS)",
           title=f"{sw.label}: simulated FPS against {factor}")
    ax.grid(True, which="both", alpha=0.3)
    legend_under(fig, ax, *FACTOR_SIZE)
    name = FigureName(("sweep", sw.path.name, factor), f"{sw.path.absolute()}\n{factor}")  # sweep_<folder>_<factor>.png
    if not numeric:
        drawn += (f" The factor {factor} is a category, not a number: its values are drawn as points, "
                  + ("each line beside the others, " if lines is not None
                     else "the median and the min-max range over the other factors' combinations, ")
                  + "and no line joins two values.")
    caption = (f"{len(ok)} finished points of {sw.planned}{sw.unfinished}; "
               f"{described(sw)}").strip().rstrip(";")
    drawn += null_text
    return save(fig, out, name, f"{sw.label}: FPS against {factor}",
                f"{caption.rstrip('.')}.{drawn}" if drawn else caption)


def _closest_to_one(points: list[dict]) -> dict:
    """The point whose Ttrav / Tisct is closest to 1 in |ln ratio| (the fewer levels on a tie)."""
    return min(points, key=lambda p: (abs(math.log(p["ratio"])), p["level"]))


def levels_balance(sw: Sweep, notes: list[str]) -> tuple[dict[tuple, list[dict]], list[dict]]:
    """The data behind the BSP-levels figure and table of a sweep over ``bsp.levels``.

    Returns ``(series, summary)``. ``series``: per (scene, the other factors' values but
    ``scene``), the finished points sorted by level, each ``{"point", "level",
    "traversal", "intersection", "ratio", "fps", "throughput", "truncated"}`` (cycles from
    the row, ratio = traversal / intersection). ``summary``: one dict per series,
    ``{"key", "scene", "triangles", "floor_ln", "ratio_at_floor", "fps_at_floor",
    "closest_level", "closest_ratio", "best_level", "best_fps"}``: ``triangles`` is the
    scene's triangle count in its points' results.json (None without one), ``floor_ln``
    floor(ln n) as the BSP builder computes it, the ``*_at_floor`` values None when the
    sweep has no point at that level; closest means the smallest |ln ratio|, best the
    highest FPS, the fewer levels on a tie. What cannot be used is said in ``notes``.
    """
    name = sw.label
    others = [f for f in factors_of(sw) if f not in (LEVELS, "scene")]
    triangles: dict[str, set[int]] = defaultdict(set)
    series: dict[tuple, list[dict]] = defaultdict(list)
    unusable = []
    for r in sorted(named_rows(sw), key=lambda r: r.get("point", 0)):
        if r.get("status") != "ok":
            continue
        run = sw.run_of(r)
        scene = str(r.get("scene"))
        bsp = ((run.results.get("scene") or {}).get("bsp") or {}) if run is not None else {}
        if run is not None and run.results["scene"].get("triangles") is not None:
            triangles[scene].add(int(run.results["scene"]["triangles"]))
        level = r.get(LEVELS)
        if level is None:  # null: the builder's own floor(ln n)
            level = bsp.get("requested_levels")
        trav, isct = r.get("cycles.traversal"), r.get("cycles.intersection")
        if level is None or trav is None or not isct or not trav:
            unusable.append(str(r.get("point")))
            continue
        series[(scene, *(hashable(r.get(f)) for f in others))].append({
            "point": r.get("point"), "level": int(level), "traversal": trav, "intersection": isct,
            "ratio": trav / isct, "fps": r.get("fps"), "throughput": r.get("cycles.throughput"),
            "truncated": bool(bsp.get("truncated")), "asked": r.get(LEVELS)})
    if unusable:
        notes.append(f"{name}: {_points(unusable)} left out of the BSP-levels balance: no level, or no "
                     "traversal and intersection cycles")
    if not series:
        notes.append(f"{name}: no BSP-levels balance: no finished point with cycles.traversal and "
                     "cycles.intersection")
        return {}, []
    truncated = [str(p["point"]) for p in sorted((p for pts in series.values() for p in pts if p["truncated"]),
                                                 key=lambda p: order_key(p["point"]))]  # (in point order)
    if truncated:
        notes.append(f"{name}: {_points(truncated)} built a shallower BSP tree than their level asks "
                     "(results.json scene.bsp.truncated); they are drawn at the level asked")
    for scene, ns in sorted(triangles.items()):
        if len(ns) > 1:
            notes.append(f"{name}: {scene}: its points report different triangle counts {sorted(ns)}; "
                         "floor(ln n) of the largest is marked")
    missing = sorted({k[0] for k in series} - set(triangles))
    if missing:
        notes.append(f"{name}: no results.json for {', '.join(missing)}: its triangle count n, hence floor(ln n), "
                     "is unknown and not marked")
    out: dict[tuple, list[dict]] = {}
    summary = []
    shared, single = [], []  # the series with no balance curve, and why
    repeats: list[dict] = []  # points that measured what another of their series measured at their level
    for key, pts in sorted(series.items(), key=lambda kv: [order_key(k) for k in kv[0]]):
        pts, again = _one_per_level(pts)
        if pts is None:
            shared.append(_series_label(key, others))
            continue
        repeats += again
        if len(pts) < 2:
            single.append(_series_label(key, others))
            continue
        pts.sort(key=lambda p: p["level"])
        out[key] = pts
        n = max(triangles[key[0]]) if triangles.get(key[0]) else None
        floor_ln = default_levels(n) if n is not None else None
        at = next((p for p in pts if p["level"] == floor_ln), None)
        close = _closest_to_one(pts)
        with_fps = [p for p in pts if p["fps"] is not None]
        best = max(with_fps, key=lambda p: (p["fps"], -p["level"])) if with_fps else None
        summary.append({"key": key, "label": _series_label(key, others), "scene": key[0], "triangles": n,
                        "floor_ln": floor_ln,
                        "ratio_at_floor": at["ratio"] if at else None, "fps_at_floor": at["fps"] if at else None,
                        "closest_level": close["level"], "closest_ratio": close["ratio"],
                        "best_level": best["level"] if best else None, "best_fps": best["fps"] if best else None})
    if repeats:
        numbers = [str(p["point"]) for p in sorted(repeats, key=lambda p: order_key(p["point"]))]
        null = ", bsp.levels null being the builder's floor(ln n)" if any(p["asked"] is None for p in repeats) else ""
        notes.append(f"{name}: {_points(numbers)} left out of the BSP-levels balance as repeats: each measured the "
                     f"same Ttrav, Tisct, FPS and TThru as the point of its series at its level{null} "
                     "(that point is shown)")
    if shared:
        notes.append(f"{name}: {_curves(shared)}: no balance curve, several points share a level with different "
                     "cycles or FPS (they differ in a factor the report cannot tell apart)")
    if single:
        notes.append(f"{name}: {_curves(single)}: one level only, no balance curve")
    return out, summary


def _one_per_level(pts: list[dict]) -> tuple[list[dict] | None, list[dict]]:
    """A series' points one per level, and the points left out as repeats: points of one level
    that measured the same (traversal and intersection cycles, FPS, TThru, to 1e-9: ``bsp.levels:
    null`` builds the tree of its floor(ln n), which the sweep may also ask for by number) are
    one, the one asked for by number kept. ``(None, [])`` where points of one level differ."""
    by_level: dict[int, list[dict]] = defaultdict(list)
    for p in pts:
        by_level[p["level"]].append(p)
    kept, again = [], []
    for same_level in by_level.values():
        first = min(same_level, key=lambda p: (p["asked"] is None, order_key(p["point"])))
        if not all(same_value(p[k], first[k]) for p in same_level for k in ("traversal", "intersection", "fps",
                                                                         "throughput")):
            return None, []
        kept.append(first)
        again += [p for p in same_level if p is not first]
    return kept, again


def _points(numbers: list[str]) -> str:
    """``point 3``, ``points 3 and 5``, or of many ``200 points (0, 1, 2, 3 and 196 more)``."""
    if len(numbers) == 1:
        return f"point {numbers[0]}"
    if len(numbers) <= NAMED:
        return f"points {listing(numbers)}"
    return f"{len(numbers)} points ({some(numbers)})"


def _curves(labels: list[str]) -> str:
    """The series named by ``labels``: one by its label, of many their count and a few."""
    return labels[0] if len(labels) == 1 else f"{len(labels)} series ({some(labels)})"


def _series_label(key: tuple, others: list[str]) -> str:
    rest = ", ".join(f"{f.split('.')[-1]}={value_text(f, v)}" for f, v in zip(others, key[1:], strict=True))
    return f"{key[0]} ({rest})" if rest else str(key[0])


def levels_table(summary: list[dict]) -> str:
    head = ["scene", "triangles n", "floor(ln n)", "Ttrav / Tisct at floor(ln n)", "FPS at floor(ln n)",
            "level with Ttrav / Tisct closest to 1", "Ttrav / Tisct there", "level of the best FPS", "best FPS"]
    out = ["<table><tr>" + "".join(f"<th>{esc(h)}</th>" for h in head) + "</tr>"]

    def num(v, f: str) -> str:
        return "not swept" if v is None else format(v, f)

    for s in summary:
        known = s["floor_ln"] is not None
        cells = [s["label"], "" if s["triangles"] is None else str(s["triangles"]),
                 str(s["floor_ln"]) if known else "unknown",
                 num(s["ratio_at_floor"], ".4f") if known else "", num(s["fps_at_floor"], ".4g") if known else "",
                 str(s["closest_level"]), f"{s['closest_ratio']:.4f}",
                 "" if s["best_level"] is None else str(s["best_level"]),
                 "" if s["best_fps"] is None else f"{s['best_fps']:.4g}"]
        left = ' class="l"'
        out.append("<tr>" + "".join(f"<td{left if i == 0 else ''}>{esc(c)}</td>" for i, c in enumerate(cells))
                   + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def levels_lines(sw: Sweep, series: dict[tuple, list[dict]], summary: list[dict],
                 limit: int = MAX_SERIES) -> list[tuple[str, dict]] | None:
    """The lines of the BSP-levels figure: the series of ``summary`` (:func:`levels_balance`),
    those of one scene with the same points (each level's Ttrav / Tisct and FPS, to 1e-9)
    drawn once, their label naming every combination of the other factors that draws it
    (:func:`_group_label`), as in the FPS figures. Each line is ``(label, the summary of its
    first series)``; None when they are more than ``limit`` distinct lines (counted after
    the merge: 100 combinations that draw 5 curves are 5 lines)."""
    others = [f for f in factors_of(sw) if f not in (LEVELS, "scene")]
    by_scene: dict[Any, dict[tuple, dict]] = defaultdict(dict)
    of_key = {}
    for s in summary:
        pts = series[s["key"]]
        of_key[s["key"]] = s
        by_scene[s["scene"]][s["key"][1:]] = {**{(p["level"], "ratio"): p["ratio"] for p in pts},
                                              **{(p["level"], "fps"): p["fps"] for p in pts}}
    lines: list[tuple[str, dict]] = []
    for scene, combos_of in by_scene.items():
        merged = merge_groups(combos_of, limit - len(lines))
        if merged is None:
            return None
        for combos, _ in merged:
            first = of_key[(scene, *combos[0])]
            lines.append((first["label"] if len(combos) == 1 else f"{scene} ({_group_label(others, combos)})", first))
    return lines


def levels_figure(sw: Sweep, series: dict[tuple, list[dict]], summary: list[dict], out: Path,
                  lines: list[tuple[str, dict]] | None = None) -> Figure:
    """Ttrav / Tisct (log) and FPS against the BSP levels, one line per distinct series
    (``lines``, :func:`levels_lines`; by default one per series), a dotted vertical line at
    each scene's floor(ln n) and a horizontal line at ratio 1."""
    if lines is None:
        lines = [(s["label"], s) for s in summary]
    fig = new_figure(*LEVELS_SIZE)
    ratio_ax, fps_ax = fig.subplots(1, 2)
    scenes = sorted({k[0] for k in series})
    marked = set()
    for i, (label, s) in enumerate(lines):
        pts = series[s["key"]]
        style = line_style(i)
        levels = [p["level"] for p in pts]
        ratio_ax.plot(levels, [p["ratio"] for p in pts], label=label, **style)
        fps_ax.plot(levels, [math.nan if p["fps"] is None else p["fps"] for p in pts], label=label, **style)
        if s["floor_ln"] is not None and s["scene"] not in marked:
            marked.add(s["scene"])
            for ax in (ratio_ax, fps_ax):
                ax.axvline(s["floor_ln"], color=style["color"], linestyle=(0, (1, 2)), linewidth=1.4,
                           label=f"floor(ln n) = {s['floor_ln']}: {s['scene']}, n = {s['triangles']}")
    ratios = [p["ratio"] for pts in series.values() for p in pts]
    ratio_ax.axhline(1.0, color="grey", linestyle="--", linewidth=1, label="Ttrav = Tisct")
    ratio_ax.set_yscale("log")
    ratio_ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ratio_ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ratio_ax.yaxis.set_minor_formatter(NullFormatter())
    ratio_ax.set_ylim(min(*ratios, 1.0) / 1.25, max(*ratios, 1.0) * 1.25)
    ratio_ax.set(ylabel="Ttrav / Tisct (cycles.traversal / cycles.intersection)",
                 title=f"{sw.label}: traversal against intersection")
    fps_ax.set(ylabel="simulated frames per second (FPS)", title=f"{sw.label}: FPS")
    levels = sorted({p["level"] for pts in series.values() for p in pts})
    for ax in (ratio_ax, fps_ax):
        ax.set_xticks(levels, [str(v) for v in levels])
        ax.set_xlabel(axis_label(LEVELS))
        ax.grid(True, which="both", alpha=0.3)
    legend_under(fig, ratio_ax, *LEVELS_SIZE)  # (one legend for both panels, under them: a label naming many
    # combinations would cover the lines inside a panel)
    where = ", ".join(dict.fromkeys(f"{s['scene']} {s['floor_ln']}" for s in summary if s["floor_ln"] is not None))
    merged = (f" The {len(summary)} series (scenes times the other factors' values) draw {len(lines)} distinct "
              f"line{'s' if len(lines) > 1 else ''}: identical ones are drawn once, their label naming them all."
              if len(lines) < len(summary) else "")
    return save(fig, out, FigureName(("bsp_balance", sw.path.name), str(sw.path.absolute())),
                f"{sw.label}: Ttrav / Tisct and FPS against the BSP levels, {count(len(scenes), 'scene')}",
                "The thesis: floor(ln n) levels balance the Traversal and Intersection PMs. Left: the slowest "
                "pipeline's Traversal over Intersection cycles per frame (1 = balanced, dashed); right: the "
                f"simulated FPS. Dotted verticals: floor(ln n) of each scene ({where or 'n unknown'}).{merged}")


def other_point_folders(sw: Sweep) -> list[str]:
    """The folders in the sweep's ``points/`` that are not its points: those of an earlier run into
    the folder of other code or another config (a point's hash holds the code's fingerprint, the
    resolved config and its input files' content), which a rerun leaves there
    (:func:`~tlm.experiments.sweep_folder.other_names`: one listing, a writer's hidden temporary folders left out)."""
    from tlm.experiments.sweep_folder import other_names

    planned = {str(p.get("hash")) for p in sw.spec.get("points") or [] if isinstance(p, dict)}
    return other_names(sw.path / "points", planned or {str(r.get("hash")) for r in sw.rows})


def other_folders_text(names: list[str], points: Path, sw: Sweep | None = None) -> str:
    """What a sweep's ``points/`` holding the folders ``names`` of no point of it means (the report's note). The
    folder's ``sweep.yaml`` is the sweep's own (an earlier sweep's, which ``tlm sweep``'s line compares, is gone),
    so what the folders are is told by their code alone, as :func:`~tlm.experiments.sweep_folder.code_said` tells
    it: the ``code_fingerprint`` in their ``results.json`` against that of the sweep ``sw``'s points; where it
    cannot be told (a point of theirs failed, ``sw``'s points ran no code told, or more than one), what may have
    left them."""
    from tlm.experiments.sweep_folder import code_said

    n = len(names)
    said = None
    if sw is not None:
        codes = {c for r in sw.runs if isinstance(c := r.results.get("code_fingerprint"), str)}
        if len(codes) == 1:
            said = code_said([sw.path / "points" / name for name in names], codes.pop(), "this sweep's")
    said = said or ("other tlm code, another config or a different --set (an edit under tlm/ or to an input file "
                    "changes every point's hash)")
    return (f"{n} point folder{'s' if n != 1 else ''} in {points} {'are' if n != 1 else 'is'} not "
            f"this sweep's: left by an earlier run into the folder of {said}; nothing reads "
            f"{'them' if n != 1 else 'it'}, and removing {'them' if n != 1 else 'it'} changes no result "
            "(sweep.yaml lists this sweep's hashes)")


def _shown_folder(sw: Sweep) -> Path:
    """The sweep's folder as a note names it: by its label where that is a tail of its path (``a/sw``),
    else by its name (a folder read twice, labelled ``sw (2)``)."""
    label = Path(sw.label)
    return label if Path(os.path.abspath(sw.path)).parts[-len(label.parts):] == label.parts else Path(sw.path.name)


def sweeps_section(inputs: Inputs, out: Path) -> Section:
    sec = Section("sweeps", "Sweeps: the points and the frame rate against each factor")
    html = []
    for sw in inputs.sweeps:
        desc = described(sw)
        failed = sum(r.get("status") != "ok" for r in sw.rows)
        other = other_point_folders(sw)
        said = other_folders_text(other, _shown_folder(sw) / "points", sw) if other else ""  # (listed once)
        stale = f" {said}." if other else ""
        html.append(f"<h3>{esc(sw.label)}</h3><p>{esc(desc or '')} {count(len(sw.rows), 'point')}, "
                    f"{failed} failed{esc(sw.unfinished)}; sweep file {esc(sw.spec.get('sweep'))}.{esc(stale)}</p>")
        if other:
            sec.notes.append(f"{sw.label}: {said}")
        if sw.unfinished:
            sec.notes.append(f"{sw.label}: {len(sw.rows)} of its {sw.planned} points have a row: the figures "
                             "show those only")
        html.append(table(sw))
        for factor in factors_of(sw):
            fig = factor_figure(sw, factor, out, sec.notes)
            if fig is not None:
                sec.figures.append(fig)
        if LEVELS in factors_of(sw):
            series, summary = levels_balance(sw, sec.notes)
            if summary:
                html.append(f"<p>{esc(sw.label)}: the BSP depth against the thesis's floor(ln n) "
                            "(Ttrav / Tisct = cycles.traversal / cycles.intersection of the rows; closest to 1 "
                            "in |ln ratio|; FPS as simulated).</p>")
                html.append(levels_table(summary))
                lines = levels_lines(sw, series, summary)
                if lines is not None:
                    sec.figures.append(levels_figure(sw, series, summary, out, lines))
                else:
                    sec.notes.append(f"{sw.label}: no BSP-levels figure: {len(summary)} curves (scenes times "
                                     f"the other factors' values) draw more than {MAX_SERIES} distinct lines; the "
                                     "table lists them")
    sec.html = "\n".join(html)
    if not inputs.sweeps:
        sec.absent = "no sweep folder among the inputs"
    return sec
