"""Section 3: scaling in the style of the thesis's Figs. 18-20.

Simulated frame latency and throughput against the number of pipelines N, beside
eq. 5.2 (and its slowest-pipeline variant), for the static and the dynamic scheduler,
and the speed-up TThru(1) / TThru(N). The fits come from ``tlm scaling`` folders
(``eq52.json`` and ``eq52.csv``) and from every sweep given to the report that varies
``arch.pipelines`` (fitted here with :mod:`tlm.experiments.scaling`: a scene is its file,
and a point without a steady state is named in the notes), save one that a scaling study among
the inputs was fitted from as the sweep is now (:func:`fitted_sweeps`): that is shown through the
study's fit alone (one run again or finished since is fitted here too, the study's fit out of date).
A ``tlm scaling`` folder whose sweep holds other points now than those it was fitted from
(run again with another base, or finished since: :func:`tlm.experiments.scaling.out_of_date`)
is said to be out of date, in the notes and on its figures.

Beside them, per scene of every such sweep (and of the sweeps a scaling study was
fitted from, ``Inputs.scaling_sweeps``), the idle fraction of each PM kind against N,
static scheduler against dynamic (:func:`idle_points`, :func:`plot_idle`), with a table
of N, scheduler, TThru, speed-up and idle fractions. A sweep row's ``idle.<pm>`` is the
PM's idle cycles (neither working nor in a stall: no job to run) over the stream's
elapsed cycles, averaged over the pipelines' PMs of that kind; there is one Vertex PM,
pipeline 0's.
"""

from __future__ import annotations

import math
import textwrap
from collections import defaultdict
from pathlib import Path

from matplotlib.ticker import NullLocator

from tlm.config_words import listing
from tlm.errors import InputError
from tlm.experiments import scaling as eq52
from tlm.report.collect import Inputs, Sweep
from tlm.report.common import (
    Figure,
    Section,
    colour,
    count,
    figure_name,
    legend_below,
    marker,
    new_figure,
    short_keys,
    some,
    wrap_title,
    write_png,
)
from tlm.report.html import esc
from tlm.report.names import path_labels
from tlm.report.sweep_lines import column_decimals
from tlm.report.sweeps import PMS, factors_of, named_rows

# one colour per PM kind (the yellow of the palette is too faint for a thin line); the
# scheduler is the line style: static solid, dynamic dashed, any other dotted
PM_COLOURS = {"vertex": 0, "traversal": 2, "intersection": 4, "fragment": 6}
SCHEDULER_LINES = {"static": "-", "dynamic": "--"}

TITLES = {"latency": "frame latency (eq. 5.2's T_tot)", "throughput": "throughput TThru"}

# a sweep crossing N with many other factors: combinations whose curves are the same are drawn once, and of
# the distinct ones at most these (those of the highest and the lowest speed-up at the largest N; the notes
# name the rest, whose numbers are the sweep's sweep.csv or the study's eq52.csv)
MAX_IDLE = 6  # idle figures (and tables) per sweep, scene and mode
MAX_CURVES = 6  # curves (scheduler x combination) on each panel of a scaling figure
LONG_COMBINATION = 40  # a combination's text past this many characters names each factor by its last dotted part
LEGEND_ROWS = 14  # a scaling panel's legend of more rows than this makes the figure taller
LEGEND_ROW_IN = 0.17  # inches per legend row past LEGEND_ROWS
LEGEND_CHARS = 80  # a scaling panel's legend label is wrapped at this many characters


def short_combination(text: str) -> str:
    """A combination of factor values as a label shows it: as written, or past :data:`LONG_COMBINATION`
    characters with each factor's last dotted part (``fifo_depth = 16, pairs = 1``)."""
    return short_keys(text) if len(text) > LONG_COMBINATION else text


def extremes(items: list, score, limit: int) -> list:
    """``items`` where they are at most ``limit``; else the ``limit - limit // 2`` of the highest
    ``score`` and the ``limit // 2`` of the lowest (None counts as the lowest), in their order."""
    if len(items) <= limit:
        return list(items)
    ranked = sorted(range(len(items)), key=lambda i: (score(items[i]) is None, -(score(items[i]) or 0.0)))
    keep = set(ranked[:limit - limit // 2]) | set(ranked[len(ranked) - limit // 2:])
    return [x for i, x in enumerate(items) if i in keep]


def _value_texts(key: str, values: list[dict]) -> list[str]:
    return list(dict.fromkeys(eq52.combination_text({key: v.get(key)}).split(" = ", 1)[1] for v in values))


def merged_label(values: list[dict]) -> str:
    """The label of the combinations ``values`` (each a factor's value by its key) that draw one figure or
    curve: one, as :func:`tlm.experiments.scaling.combination_text` writes it; several that are every
    combination of some values of each factor, each factor once (``fifo_depth = 16 or 64; pairs = 1``);
    else the first and how many more; ``(identical)`` after several. Long, by the factors' last parts."""
    if len(values) == 1:
        return short_combination(eq52.combination_text(values[0]))
    keys = list(values[0])
    texts = {k: _value_texts(k, values) for k in keys}
    if keys and math.prod(len(t) for t in texts.values()) == len(values):
        parts = [f"{k} = {listing(t, last='or')}" for k, t in texts.items()]
        text = "; ".join(parts)
    else:
        text = f"{eq52.combination_text(values[0])} and {count(len(values) - 1, 'more combination')}"
    return short_combination(text) + " (identical)"


def untested(fit: dict) -> bool:
    """Whether an eq. 5.2 fit has two values of N alone (N = 1 and one other): its two parameters A and B are
    solved from its two points, so its error is 0 by construction (or, where its N's have the same
    sum_i max / N, what B = 1 leaves) and tests nothing; a third N is what tests the equation."""
    return len({r["pipelines"] for r in fit["rows"]}) <= 2


def flat(fit: dict) -> bool:
    """Whether a fit of three or more N tests nothing all the same (``tested`` false: every point Vertex-bound, T
    the same at every N, or sum_i max / N the same; its ``why`` says which: h488)."""
    return fit.get("tested") is False and not untested(fit)


def judged(fit: dict) -> dict:
    """A fit of an ``eq52.json`` written before h488 (no ``tested``), judged from its rows as
    :func:`tlm.experiments.scaling.flat_why` judges a fit's points: untested where the simulated cycles are
    the same at every N (Vertex-bound where they are T_vert0, times the latency's multiple); else as it is."""
    rows = fit["rows"]
    if "tested" in fit or untested(fit) or len({r["simulated"] for r in rows}) > 1:
        return fit
    k = 1 if fit["target"] == "throughput" else fit.get("latency_multiple")
    by_n = {r["pipelines"]: {"throughput": r["simulated"] / k if k else math.inf, fit["target"]: r["simulated"],
                             "T_vert0": r["T_vert0"] if isinstance(r.get("T_vert0"), (int, float)) else -math.inf}
            for r in rows}  # (a table without T_vert0: not said to be Vertex-bound)
    why = eq52.flat_why(by_n, fit["target"], [0] * (len(rows) - 1), [1])
    slowest = {"slowest": {**fit["slowest"], "tested": False, "why": why}} if "slowest" in fit else {}
    return {**fit, "tested": False, "why": why, **slowest}


def error_text(fit: dict, short: bool = False) -> str:
    """A fit's largest |error| as a caption or a legend shows it, with why it tests nothing where it is
    :func:`untested`: exact by construction where the error is 0, else (the two points leave B or A undetermined,
    as a slowest pipeline holding all the work at both N does, and B = 1 or A = 0 is taken) no measure either;
    ``untested`` in place of the error where it is :func:`flat` (and its ``why``, unless ``short``)."""
    if flat(fit):
        return "untested" if short else f"untested ({fit.get('why')})"
    ns = " and ".join(map(str, sorted({r["pipelines"] for r in fit["rows"]})))
    why = untested_why(fit["max_abs_rel_error"])
    return f"{fit['max_abs_rel_error']:.1%}" + (f" (N = {ns} alone: {why})" if untested(fit) else "")


def untested_why(error: float) -> str:
    """What a fit of two values of N alone (:func:`untested`) is, judged by its own largest |error| ``error`` (an
    eq. 5.2 fit and its slowest-pipeline variant each alone): exact by construction where 0, else its two points
    leave A or B undetermined (B = 1 or A = 0 taken). The one rule of the report's captions and of ``tlm scaling``'s
    lines (``tlm.cli_tables._two_n``, which reaches the report only through tlm.api, applies it to each fit:
    tests/test_lastread_h309.py holds the two to it)."""
    return "exact by construction" if error == 0 else "A and B not both determined"


def plot_scaling(scene: str, fits: dict[tuple, dict], path: Path, source: str = "") -> None:
    """Three panels: latency and throughput against N (simulated, eq. 5.2, slowest-pipeline
    variant), and the speed-up; one colour and marker per scheduler, and per combination of
    the sweep's other factors where it was fitted per combination (a key's group,
    :func:`tlm.experiments.scaling.fit_key`), each curve labelled by it. Each panel's legend
    sits under it, where it covers no curve."""
    fig = new_figure(15, 5.8)  # (taller: the legends sit under the panels)
    axes = fig.subplots(1, 3)
    curves = sorted({(k[2], eq52.key_group(k)) for k in fits}, key=lambda c: (c[0] != "static", c))
    for key, f in sorted(fits.items()):
        _, mode, sched, target = key[:4]
        group = eq52.key_group(key)
        i = curves.index((sched, group))
        c, m = colour(2 * i), marker(i)
        name = f"{sched}, {group}" if group else sched
        ns = [r["pipelines"] for r in f["rows"]]
        ax = axes[0 if target == "latency" else 1]
        ax.plot(ns, [r["simulated"] for r in f["rows"]], color=c, marker=m, linestyle="-",
                label=f"{name} ({mode}): simulated")
        ax.plot(ns, [r["analytical"] for r in f["rows"]], color=c, linestyle="--",
                label=f"{name}: eq. 5.2, A={f['A']:.3g}, B={f['B']:.3g}, max err {error_text(f, True)}")
        if "analytical_slowest" in f["rows"][0]:
            s = f["slowest"]
            ax.plot(ns, [r["analytical_slowest"] for r in f["rows"]], color=c, linestyle=":",
                    label=f"{name}: slowest pipeline, A={s['A']:.3g}, B={s['B']:.3g}, "
                          f"max err {error_text({**s, 'rows': f['rows']}, True)}")
        if target == "throughput":
            axes[2].plot(ns, [r["speedup"] for r in f["rows"]], color=c, marker=m, linestyle="-",
                         label=f"{name} ({mode})")
    where = f" [{source}]" if source else ""
    for ax, target in zip(axes[:2], ("latency", "throughput"), strict=True):
        ax.set(xscale="log", yscale="log", xlabel="pipelines N", ylabel="cycles per frame",
               title=wrap_title(f"{scene}: {TITLES[target]}{where}", 6.5))
        ax.grid(True, which="both", alpha=0.3)
    ns = sorted({r["pipelines"] for f in fits.values() for r in f["rows"]})
    axes[2].plot(ns, ns, color="grey", linestyle=(0, (1, 2)), label="linear (ideal)")
    axes[2].set(xscale="log", yscale="log", xlabel="pipelines N", ylabel="speed-up TThru(1) / TThru(N)",
                title=wrap_title(f"{scene}: speed-up{where}", 6.5))
    # (the legends under the panels, long labels wrapped; one of many rows makes the figure taller, so that
    # the panels keep their size: constrained layout gives up where the legends leave them no room)
    rows = 0
    for ax in axes:
        handles, labels = ax.get_legend_handles_labels()
        wrapped = [textwrap.fill(t, LEGEND_CHARS, expand_tabs=False) if len(t) > LEGEND_CHARS else t for t in labels]
        rows = max(rows, sum(t.count("\n") + 1 for t in wrapped))
        ax.legend(handles, wrapped, fontsize=7, ncol=1, loc="upper center", bbox_to_anchor=(0.5, -0.14),
                  borderaxespad=0.0)
    if rows > LEGEND_ROWS:
        fig.set_size_inches(15, 5.8 + (rows - LEGEND_ROWS) * LEGEND_ROW_IN)
    axes[2].grid(True, which="both", alpha=0.3)
    for ax in axes:  # N at its own values, not at powers of ten
        ax.set_xticks(ns, [str(n) for n in ns])
        ax.xaxis.set_minor_locator(NullLocator())
    axes[2].set_yticks(ns, [str(n) for n in ns])
    axes[2].yaxis.set_minor_locator(NullLocator())
    write_png(fig, path)


def _fits_of_study(study) -> dict[tuple, dict]:
    rows = defaultdict(list)
    for r in study.rows:  # (a fit per combination of a sweep's other factors: its rows' and its group)
        rows[eq52.fit_key(r["scene"], r["mode"], r["scheduler"], r["target"], r.get("group") or "")].append(
            {**r, "pipelines": int(r["pipelines"])})
    fits = {}
    for f in study.meta.get("fits", []):
        key = eq52.fit_key(f["scene"], f["mode"], f["scheduler"], f["target"], f.get("group") or "")
        if key in rows:
            fits[key] = judged({**f, "rows": sorted(rows[key], key=lambda r: r["pipelines"])})
    return fits


def _fits_of_sweep(sweep, notes: list[str], names: dict[str, str] | None = None) -> dict[tuple, dict]:
    """Eq. 5.2 fitted over the sweep's points; ``names`` is given each group's scene (eq. 5.2's
    label) as the report names it (the scene of the group's points)."""
    records = []
    for run in sweep.runs:  # (read once by collect.read)
        rec = eq52.record(run.results, run.config)
        rec["report_name"] = run.scene_label
        rec["factors"] = run.factors  # (a fit per combination of the other factors: eq52.parts)
        records.append(rec)
        if rec["steady"] is False:
            notes.append(f"{run.label}{f' ({run.factors_text})' if run.factors else ''}: {eq52.unsteady(rec)}")
    fits = {}
    for key, pts in eq52.groups(records).items():
        if names is not None:
            names[key[0]] = pts[0]["report_name"]
        for group, part in eq52.parts(pts, f"{sweep.label}: {'/'.join(key)}", notes):
            for target in eq52.TARGETS:
                try:
                    fits[eq52.fit_key(*key, target, group)] = eq52.fit_both(part, target)
                except InputError as e:
                    notes.append(f"{sweep.label}: {'/'.join(key)}{f' ({group})' if group else ''} {target} "
                                 f"not fitted: {e}")
    notes.extend(f"{sweep.label}: {line}" for line in eq52.untested_notes(fits))  # (h488: a study's are its own)
    return fits


def _varies_pipelines(sw: Sweep) -> bool:
    return "arch.pipelines" in factors_of(sw)


def _scheduler_order(s: str) -> tuple:
    return (s != "static", s != "dynamic", s)


def idle_points(sw: Sweep, notes: list[str]) -> dict[tuple, dict]:
    """The data behind the idle figures and tables of a sweep over ``arch.pipelines``.

    Per (scene, mode), and per combination of the sweep's other factors where it crosses N with
    others ((scene, mode, ``bsp.levels = 15``), in the order of their first points):
    ``{"pms": [...], "points": [...], "values": {...}}`` (``values``: the other factors' values, by key;
    empty where N is crossed with none), the points sorted by scheduler
    (static first) then N, each ``{"point", "scheduler", "pipelines", "throughput",
    "speedup", "base", "idle": {pm: fraction}}``: ``throughput`` is the row's
    ``cycles.throughput`` (TThru), ``speedup`` TThru(N0) / TThru(N) of the same scheduler, ``base`` that N0, the
    smallest N it ran (N = 1 where swept; h531: the column was empty without it), both None without the TThru,
    ``idle`` the row's ``idle.<pm>`` as written. What
    cannot be drawn is said in ``notes``.
    """
    name = sw.label  # (as the report names the sweep: a/sw and b/sw for two folders named sw)
    ok = [r for r in named_rows(sw) if r.get("status") == "ok"]
    if not ok:
        notes.append(f"{name}: no idle fractions to draw: no finished point")
        return {}
    pms = [p for p in PMS if any(r.get(f"idle.{p}") is not None for r in ok)]
    if not pms:
        notes.append(f"{name}: no idle fractions to draw: its rows have no idle.<pm> column "
                     f"({', '.join(f'idle.{p}' for p in PMS)}); a sweep run by a newer tlm writes them")
        return {}
    # a sweep crossing N with other factors: a figure per combination of their values (as eq. 5.2's fits)
    # where one has two values of N (a zip of N with another factor: one figure over N, as before)
    # (a factor that leaves the cycles as they are, arch.trace, splits nothing: eq52.one_per_n)
    others = [k for k in factors_of(sw) if k not in eq52.GROUP_KEYS and not eq52.no_effect(k)
              and len({repr(r.get(k)) for r in ok}) > 1]
    ns = defaultdict(set)
    for r in ok:
        ns[tuple(repr(r.get(k)) for k in others)].add(r.get("arch.pipelines"))
    if not any(len(n) > 1 for n in ns.values()):
        others = []
    groups: dict[tuple, list[dict]] = defaultdict(list)
    factors: dict[int, dict] = {}  # (each point's factors, by id of its dict: what tells apart two of one N)
    unknown = []
    for r in sorted(ok, key=lambda r: r.get("point", 0)):
        run = sw.run_of(r)
        arch = (run.config.get("arch") or {}) if run is not None else {}
        n = r.get("arch.pipelines", arch.get("pipelines"))
        sched = r.get("arch.scheduler", arch.get("scheduler"))
        if n is None or sched is None:
            unknown.append(str(r.get("point")))
            continue
        combination = eq52.combination_text({k: r.get(k) for k in others})
        point = {"point": r.get("point"), "scheduler": str(sched), "pipelines": int(n),
                 "throughput": r.get("cycles.throughput"), "idle": {p: r.get(f"idle.{p}") for p in pms}}
        factors[id(point)] = {k: r.get(k) for k in factors_of(sw)}
        groups[(str(r.get("scene")), str(r.get("mode")), *((combination,) if combination else ()))].append(point)
    if unknown:
        notes.append(f"{name}: {'points' if len(unknown) > 1 else 'point'} {some(unknown)} left out of the idle "
                     "figures: neither the row nor a results folder gives their scheduler and N")
    out = {}
    for key, pts in sorted(groups.items(), key=lambda kv: kv[0][:2]):  # (a scene's combinations as they came)
        scene, mode = key[:2]
        if len(key) > 2:
            mode = f"{mode} ({key[2]})"  # (in the notes)
        pts = _one_per_n(pts, factors, f"{name}: {scene}/{mode}", notes)
        seen = defaultdict(list)
        for p in pts:
            seen[(p["scheduler"], p["pipelines"])].append(str(p["point"]))
        twice = [f"{s} N={n} (points {', '.join(ps)})" for (s, n), ps in seen.items() if len(ps) > 1]
        if twice:
            notes.append(f"{name}: {scene}/{mode}: no idle figure: several points share a scheduler and N, "
                         f"they differ in another factor ({'; '.join(twice)})")
            continue
        if len({p["pipelines"] for p in pts}) < 2:
            notes.append(f"{name}: {scene}/{mode}: no idle figure: one value of N only")
            continue
        pts.sort(key=lambda p: (_scheduler_order(p["scheduler"]), p["pipelines"]))
        first = {}  # (each scheduler's smallest N, the one its speed-up is measured against: pts are by N)
        for p in pts:
            first.setdefault(p["scheduler"], p)
        for p in pts:
            t1, t = first[p["scheduler"]]["throughput"], p["throughput"]
            p["speedup"], p["base"] = (t1 / t, first[p["scheduler"]]["pipelines"]) if t1 and t else (None, None)
        out[key] = {"pms": pms, "points": pts, "values": {k: factors[id(pts[0])].get(k) for k in others}}
    return out


def _one_per_n(pts: list[dict], factors: dict[int, dict], where: str, notes: list[str]) -> list[dict]:
    """The points of one idle figure with one per (scheduler, N) where several differ only in factors
    that leave the cycles as they are (:func:`tlm.experiments.scaling.no_effect`, ``arch.trace``): the
    first is kept, as eq. 5.2 keeps it, and ``notes`` gets a line where their TThru or idle fractions
    disagree. Points that differ in another factor are all kept (the caller says why no figure)."""
    same: dict[tuple, list[dict]] = defaultdict(list)
    for p in pts:
        same[(p["scheduler"], p["pipelines"])].append(p)
    out = []
    for p in pts:
        these = same[(p["scheduler"], p["pipelines"])]
        fs = [factors[id(q)] for q in these]
        keys = sorted({k for f in fs for k in f if len({repr(g.get(k)) for g in fs}) > 1})
        if len(these) == 1 or not all(eq52.no_effect(k) for k in keys):
            out.append(p)
        elif p is these[0]:
            out.append(p)
            if len({(repr(q["throughput"]), repr(sorted(q["idle"].items()))) for q in these}) > 1:
                shown = "; ".join(f"point {q['point']}: TThru {q['throughput']}" for q in these)
                notes.append(f"{where}: {p['scheduler']} N={p['pipelines']}: points "
                             f"{', '.join(str(q['point']) for q in these)} differ only in factors that leave the "
                             f"cycles as they are ({', '.join(keys) or 'none'}), yet their TThru or idle fractions "
                             f"disagree ({shown}): point {p['point']} drawn")
    return out


def plot_idle(scene: str, pms: list[str], points: list[dict], path: Path, source: str = "") -> None:
    """Idle fraction of each PM kind against N (log2): one colour and marker per PM, one line
    style per scheduler (static solid with filled markers, dynamic dashed with open ones)."""
    fig = new_figure(8, 4.8)
    ax = fig.subplots()
    scheds = sorted({p["scheduler"] for p in points}, key=_scheduler_order)
    for j, sched in enumerate(scheds):
        mine = [p for p in points if p["scheduler"] == sched]
        ns = [p["pipelines"] for p in mine]
        for i, pm in enumerate(pms):
            c = colour(PM_COLOURS.get(pm, i))
            ys = [math.nan if p["idle"][pm] is None else p["idle"][pm] for p in mine]
            ax.plot(ns, ys, color=c, marker=marker(i), markersize=5, linestyle=SCHEDULER_LINES.get(sched, ":"),
                    markerfacecolor=c if j == 0 else "white", markeredgecolor=c, label=f"{pm}, {sched}")
    ns = sorted({p["pipelines"] for p in points})
    ax.set_xscale("log", base=2)
    ax.set_xticks(ns, [str(n) for n in ns])
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_ylim(-0.02, 1.02)
    where = f" [{source}]" if source else ""
    ax.set(xlabel="pipelines N", ylabel="idle fraction of the elapsed cycles",
           title=wrap_title(f"{scene}: idle fraction per PM, {' against '.join(scheds)}{where}", 8.0))
    ax.grid(True, which="both", alpha=0.3)
    legend_below(ax, ncol=len(scheds))
    write_png(fig, path)


def _left(yes: bool) -> str:
    return ' class="l"' if yes else ""


def idle_table(title: str, pms: list[str], points: list[dict]) -> str:
    """N, scheduler, TThru, speed-up and the idle fraction of each PM, by N then scheduler; the speed-up's
    head names the N it is measured against where that is not 1 (:func:`speedup_base`)."""
    base = speedup_base(points)
    over = "" if base in ("1", "") else f" over N = {base}" if base.isdigit() else " over the smallest N"
    head = ["N", "scheduler", "TThru (M cycles)", f"speed-up{over}", *(f"idle {p}" for p in pms)]
    rows = sorted(points, key=lambda p: (p["pipelines"], _scheduler_order(p["scheduler"])))
    out = [f"<details><summary>{esc(title)}</summary>",
           "<table><tr>" + "".join(f"<th{_left(h == 'scheduler')}>{esc(h)}</th>" for h in head) + "</tr>"]
    # (TThru's numbers in one notation, to one count of decimals: column_decimals)
    thru = column_decimals([None if p["throughput"] is None else p["throughput"] / 1e6 for p in rows], lambda _v: "")
    for p, t in zip(rows, thru, strict=True):
        cells = [str(p["pipelines"]), p["scheduler"], t,
                 "" if p["speedup"] is None else f"{p['speedup']:.3f}",
                 *("" if p["idle"][pm] is None else f"{p['idle'][pm]:.3f}" for pm in pms)]
        out.append("<tr>" + "".join(f"<td{_left(k == 1)}>{esc(c)}</td>" for k, c in enumerate(cells)) + "</tr>")
    out.append("</table></details>")
    return "\n".join(out)


def speedup_base(points: list[dict]) -> str:
    """The N the points' speed-ups are measured against (:func:`idle_points`' ``base``): one N (``4``), else
    "each scheduler's smallest N"; "" where no point has a speed-up."""
    bases = {p.get("base") for p in points if p.get("speedup") is not None}
    return "" if not bases else str(next(iter(bases))) if len(bases) == 1 else "each scheduler's smallest N"


def fitted_sweeps(inputs: Inputs, current: bool = True) -> dict[Path, str]:
    """The sweep folders (resolved) that a scaling study among the inputs lists in its ``eq52.json``
    ``sweeps`` (relative to the study's folder), each with the study's folder name: such a sweep among
    the inputs is shown through that study's fit alone (as ``tlm plots`` shows it), not fitted again.
    ``current`` (the default): only those whose points now are those the study was fitted from
    (:func:`tlm.experiments.scaling.entry_out_of_date`; a study of an older tlm, which did not record them:
    by the path alone). A sweep run again, finished since, or another sweep where the path leads now (a study
    copied without its sweeps) is one the study's fit does not show: the report fits it too."""
    out: dict[Path, str] = {}
    for st in inputs.of_kind("scaling"):
        recorded = st.meta.get("fitted_from")
        entries = {e.get("sweep"): e for e in recorded or [] if isinstance(e, dict)}
        for rel in st.meta.get("sweeps") or []:
            if not isinstance(rel, str) or (st.path / rel).resolve() in out:
                continue
            if current and recorded is not None and (rel not in entries
                                                      or eq52.entry_out_of_date(st.path, entries[rel])):
                continue
            out[(st.path / rel).resolve()] = st.path.name
    return out


def fit_sources(inputs: Inputs, notes: list[str],
                studies: bool = True) -> list[tuple[str, str, dict, dict[str, str], Path, str]]:
    """The eq. 5.2 fits among the inputs, as §3 draws them and the summary's "Does it scale" reads
    them: each ``tlm scaling`` folder's, and each sweep's over ``arch.pipelines`` (fitted here, per
    combination of its other factors, :func:`tlm.experiments.scaling.parts`). Per source: (the
    folder's name, for the file names; its name in titles and notes; its fits by
    :func:`~tlm.experiments.scaling.fit_key`; each fit's scene as the report names it; the folder;
    why its fit no longer shows its sweeps, "" where it does). What was not fitted, and why, goes
    to ``notes``. ``studies`` false: the sweeps' alone. A sweep that a scaling study among the inputs
    was fitted from, as it is now (:func:`fitted_sweeps`), is no source of its own, whether ``studies`` or not: its
    fit is the study's (drawn twice otherwise, once per folder)."""
    fitted = fitted_sweeps(inputs)
    studies = inputs.of_kind("scaling") if studies else []
    # a scaling folder as titles and notes name it: its name, or where another folder of the section shares it,
    # the tail of its path that tells it apart (a sweep's label is the report's: :func:`~tlm.report.collect.read`)
    own = [sw.path for sw in inputs.sweeps if _varies_pipelines(sw) and sw.path.resolve() not in fitted]
    shown = path_labels([*(st.path for st in studies), *own])
    shown = shown[:len(studies)]
    # (the folder's name, for the file names; its name in titles and notes, a sweep's label (a/sw and b/sw
    # for two folders named sw); fits; each fit's scene, eq. 5.2's label, as the report names scenes: by the
    # scene's file; the folder; why its fit no longer shows its sweeps, "" where it does: a scaling folder's
    # own, not looked up by a name that a sweep or another scaling folder may share)
    sources: list[tuple[str, str, dict, dict[str, str], Path, str]] = []
    for st, label in zip(studies, shown, strict=True):
        fits = _fits_of_study(st)
        # what the fit left out or noticed (failed points, an unfinished sweep)
        notes.extend(f"{label}: {n}" for n in st.meta.get("notes") or [] if isinstance(n, str))
        old = eq52.out_of_date(st.path, st.meta)
        notes.extend(f"{label}: {n}" for n in old)
        stale = ("Out of date: its sweep holds other points now (see the notes). "
                 if any(n.startswith("out of date") for n in old) else "")
        sources.append((st.path.name, label, fits, {k[0]: inputs.study_scene(st, k[0]) for k in fits}, st.path,
                        stale))
    for sw in inputs.sweeps:
        if not _varies_pipelines(sw):
            continue
        if sw.path.resolve() in fitted:  # (its idle fractions are still drawn, from the sweep: scaling_section)
            notes.append(f"{sw.label}: fitted by the scaling study {fitted[sw.path.resolve()]} among the inputs: "
                         "shown through that fit, not fitted again")
            continue
        if not sw.runs:
            notes.append(f"{sw.label}: no finished point with a results folder: eq. 5.2 not fitted")
            continue
        names: dict[str, str] = {}
        sources.append((sw.path.name, sw.label, _fits_of_sweep(sw, notes, names), names, sw.path, ""))
    return sources


def _top_speedup(points: list[dict]):
    """The speed-up at the largest N of the first scheduler's points (idle_points' order)."""
    mine = [p for p in points if p["scheduler"] == points[0]["scheduler"]]
    return max(mine, key=lambda p: p["pipelines"])["speedup"]


def bounded_fits(fits: dict[tuple, dict], numbers: str) -> tuple[dict[tuple, dict], str]:
    """The fits of one scene that its scaling figure draws, and what the caption says of the rest.

    Fits per combination of a sweep's other factors whose curves are the same (every scheduler's and
    target's simulated cycles) are drawn once, their label naming them all (:func:`merged_label`); of
    more distinct ones than :data:`MAX_CURVES` curves (schedulers x combinations) per panel, those of the
    highest and the lowest speed-up at the largest N (the first scheduler's) are drawn, and the sentence
    returned says how many are not and that ``numbers`` (sweep.csv, eq52.csv) holds them. Fits of
    short combinations, none merged or left out, are returned as they are (and "")."""
    groups = list(dict.fromkeys(eq52.key_group(k) for k in fits))
    if groups == [""] or not groups:
        return fits, ""
    signature: dict[str, list] = defaultdict(list)
    for k, f in sorted(fits.items()):
        # (every number the figure draws or its caption reads: the rows' N, simulated, eq. 5.2 and slowest-pipeline
        # values and speed-ups, the fit's A, B, largest error and slowest-pipeline fit)
        signature[eq52.key_group(k)].append((k[1], k[2], k[3], [
            (r.get("pipelines"), r.get("simulated"), r.get("analytical"), r.get("analytical_slowest"), r.get("speedup"))
            for r in f["rows"]], [f.get(name) for name in ("A", "B", "max_abs_rel_error", "slowest")]))
    merged: dict[str, list[str]] = {}
    for g in groups:
        merged.setdefault(repr(signature[g]), []).append(g)
    lists = list(merged.values())
    scheds = sorted({k[2] for k in fits}, key=_scheduler_order)
    first = scheds[0]

    def score(gs: list[str]):
        f = next((v for k, v in fits.items() if eq52.key_group(k) == gs[0] and k[2] == first
                  and k[3] == "throughput"), None)
        return f["rows"][-1].get("speedup") if f and f.get("rows") else None

    drawn = extremes(lists, score, max(2, MAX_CURVES // len(scheds)))
    if len(lists) == len(groups) and len(drawn) == len(lists) and all(len(g) <= LONG_COMBINATION for g in groups):
        return fits, ""
    label = {}
    for gs in drawn:
        label[gs[0]] = (short_combination(gs[0]) if len(gs) == 1 else
                        short_combination(f"{gs[0]} and {count(len(gs) - 1, 'more combination')}") + " (identical)")
    out = {}
    for k, f in fits.items():
        if eq52.key_group(k) in label:
            out[eq52.fit_key(*k[:4], label[eq52.key_group(k)])] = f
    said = ""
    if len(lists) < len(groups):
        said += (f" The {len(groups)} combinations of the other factors draw {len(lists)} distinct curves: "
                 "identical ones are drawn once.")
    if len(drawn) < len(lists):
        left = [f"[{short_combination(gs[0])}]" for gs in lists if gs not in drawn]
        said += (f" {len(drawn)} of the {len(lists)} distinct curves are drawn, those of the highest and the lowest "
                 f"speed-up at the largest N; not drawn: {some(left)} ({numbers} holds every point).")
    return out, said.strip()


def below_floor(fits: dict[tuple, dict]) -> list[str]:
    """Where eq. 5.2's fit goes below T_vert0, the one (shared) Vertex PM's cycles per frame: a
    floor of both TThru and the latency at every N (each frame takes its Vertex PM that long),
    so the fit's value there is one no count of pipelines reaches. One line per fit so."""
    lines = []
    for k, f in sorted(fits.items()):
        ns = [r["pipelines"] for r in f.get("rows", []) if r.get("T_vert0") and r["analytical"] < r["T_vert0"]]
        if ns:
            group = f" ({eq52.key_group(k)})" if eq52.key_group(k) else ""
            floor = round(f["rows"][0]["T_vert0"])
            lines.append(f"{k[2]}{group} {k[3]}: eq. 5.2's fit falls below T_vert0 = {floor:,} "
                         f"cycles (the shared Vertex PM's cycles per frame, below which no frame goes) at N = "
                         f"{', '.join(map(str, ns))}: there it predicts what no count of pipelines reaches")
    return lines


def _merge_idle(groups: dict[tuple, dict]) -> dict[tuple, list[tuple[list[tuple], dict]]]:
    """idle_points' groups by (scene, mode), those of one (scene, mode) whose points are the same (scheduler,
    N, TThru and idle fractions) merged: ``[(keys, group), ...]``, the group the first key's."""
    out: dict[tuple, dict[str, tuple[list[tuple], dict]]] = defaultdict(dict)
    for key, g in groups.items():
        sig = repr([(p["scheduler"], p["pipelines"], p["throughput"], sorted(p["idle"].items()))
                    for p in g["points"]])
        out[key[:2]].setdefault(sig if len(key) > 2 else repr(key), ([], g))[0].append(key)
    return {at: list(by.values()) for at, by in out.items()}


def scaling_section(inputs: Inputs, out: Path) -> Section:
    sec = Section("scaling", "Scaling with N pipelines: simulated against eq. 5.2, static against dynamic")
    sources = fit_sources(inputs, sec.notes)
    idle_sweeps = [sw for sw in inputs.sweeps if _varies_pipelines(sw)]
    sec.notes.extend(inputs.scaling_missing)
    for sw in inputs.scaling_sweeps:  # fitted by a scaling study among the inputs: idle fractions only
        if _varies_pipelines(sw):
            idle_sweeps.append(sw)
        else:
            sec.notes.append(f"{sw.label}: does not vary arch.pipelines, no idle figure")
    for name, label, fits, named, where, stale in sources:
        for scene in sorted({k[0] for k in fits}):
            mine = {k: v for k, v in fits.items() if k[0] == scene}
            # (eq. 5.2's name of the scene: the file keeps its name)
            file = figure_name(out, "scaling", name, scene, key=f"scaling\n{where.absolute()}\n{scene}")
            scene_shown = named.get(scene, scene)
            numbers = "eq52.csv" if (where / "eq52.csv").is_file() else "sweep.csv"
            drawn, said = bounded_fits(mine, numbers)
            if said:
                sec.notes.append(f"{label}: {scene_shown}: {said}")
            sec.notes.extend(f"{label}: {scene_shown}: {line}" for line in below_floor(drawn))
            plot_scaling(scene_shown, drawn, out / file, label)
            worst = ", ".join(f"{k[2]}{f' ({eq52.key_group(k)})' if eq52.key_group(k) else ''} {k[3]} "
                              f"{error_text(v, True)}" for k, v in sorted(drawn.items()))
            whys = dict.fromkeys(v.get("why") for v in drawn.values() if flat(v))
            if whys:  # (h488: every point Vertex-bound, a 0.0% of no test)
                worst += f". Untested: {'; '.join(map(str, whys))}"
            if any(untested(v) for v in drawn.values()):  # (two points fit two parameters: a 0.0% that is no test)
                worst += (". A fit of two values of N tests nothing: eq. 5.2's two parameters, A and B, are "
                          "solved from its two points, which it then meets exactly whatever the model does (where "
                          "the two points do not determine both, B = 1 or A = 0 is taken, and the error measures "
                          "that choice, not the model); a third N in the sweep is what tests the equation")
            sec.figures.append(Figure(file, f"{scene_shown}: scaling from {label}{' (out of date)' if stale else ''}",
                                      stale + "Solid: simulated; dashed: eq. 5.2 fitted exactly at N = 1 and by "
                                      "least squares elsewhere; dotted: the slowest-pipeline variant. "
                                      f"Largest |error| of eq. 5.2: {worst}." + (f" {said}" if said else "")))
    tables = []
    for sw in idle_sweeps:
        groups = idle_points(sw, sec.notes)
        many_modes = len({key[1] for key in groups}) > 1
        for (scene, mode), merged in _merge_idle(groups).items():
            where = f"{scene}/{mode}" if many_modes else scene
            drawn = extremes(merged, lambda m: _top_speedup(m[1]["points"]), MAX_IDLE)
            bounded = ""
            if len(drawn) < len(merged) or len(merged) < sum(len(keys) for keys, _ in merged):
                combos = sum(len(keys) for keys, _ in merged)
                shown = {id(m) for m in drawn}
                left = [f"[{merged_label([groups[k]['values'] for k in m[0]])}]" for m in merged if id(m) not in shown]
                bounded = (f" The {combos} combinations of the other factors draw {len(merged)} distinct idle "
                           "figures (identical ones drawn once)"
                           + (f"; {len(drawn)} are drawn, those of the highest and the lowest speed-up at the "
                              f"largest N; sweep.csv holds the idle.<pm> of every point" if left else "") + ".")
                if left:
                    sec.notes.append(f"{sw.label}: {where}: {len(left)} of {len(merged)} distinct idle figures not "
                                     f"drawn (only those of the highest and the lowest speed-up at the largest N are): "
                                     f"{some(left)}; sweep.csv holds their idle.<pm> and cycles.throughput")
            for keys, g in drawn:
                key = keys[0]
                combination = merged_label([groups[k]["values"] for k in keys]) if len(key) > 2 else ""
                label = where + (f" [{combination}]" if combination else "")
                file = figure_name(out, "idle", sw.path.name, scene, *((mode,) if many_modes else ()),
                                   *((key[2],) if len(key) > 2 else ()),
                                   key="\n".join(("idle", str(sw.path.absolute()), *key)))
                plot_idle(label, g["pms"], g["points"], out / file, sw.label)
                sec.figures.append(Figure(file, f"{label}: idle fraction per PM against N, from {sw.label}",
                                          "Idle: no job to run (neither working nor stalled), as a fraction of the "
                                          "stream's elapsed cycles, averaged over the pipelines' PMs of each kind "
                                          "(one Vertex PM, pipeline 0's); the row's idle.<pm>. Solid, filled "
                                          "markers: static tiling; dashed, open markers: the dynamic scheduler."
                                          + bounded))
                base = speedup_base(g["points"])  # (the smallest N swept: N = 1 where it was, h531)
                ratio = f"TThru({base}) / TThru(N)" if base.isdigit() else "TThru(N0) / TThru(N) (N0 its smallest N)"
                tables.append(idle_table(f"{label} ({sw.label}): N, scheduler, TThru, speed-up {ratio} "
                                         "of the same scheduler, idle fraction per PM", g["pms"], g["points"]))
    sec.html = "\n".join(tables)
    if not sec.figures:
        folders = [label for _, label, _, _, _, _ in sources] + [sw.label for sw in idle_sweeps if not sw.runs]
        sec.absent = (f"no eq. 5.2 fit or idle figure from {', '.join(dict.fromkeys(folders))}: the notes say why"
                      if folders else
                      "no 'tlm scaling' folder and no sweep over arch.pipelines among the inputs "
                      "(e.g. 'tlm sweep scaling_ring', the built-in experiment)")
    return sec
