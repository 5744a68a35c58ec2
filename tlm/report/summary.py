"""The report's first screen: what the model found, in words and one figure per question.

Four questions, each answered from whatever the inputs hold (and saying so when they
hold nothing for it):

1. How fast? Frames per second per scene and mode, ours beside the thesis's (Tables I–III):
   the thesis study's frames when there is one (the other runs' frame rates in words). Runs of one
   scene-mode given more than once: a bar each, in the order given, and B/A against the first in words
   (:mod:`tlm.report.compare`); the bottleneck figure then has a row per run.
2. What limits it? The bottleneck PM of each scene-mode and its utilisation (busy share
   of the elapsed cycles; with N pipelines a PM's busiest pipeline's, as its ``cycles.<pm>``
   is its slowest pipeline's), and whether the thesis names the same PM.
3. Does it scale? Speed-up with N pipelines against the ideal N (eq. 5.2's sweeps).
4. What does quality cost? Image error against run time of the photon-map filters.
5. What do the sweeps find? For each sweep, the factor that moves the frame rate most (its
   values compared like with like: within the combinations of the other factors that
   finished with each of them) and its best point (or that none moves it; points within 1% of its
   frame rate tie with it, said so: :data:`~tlm.report.summary_effects.NEAR_TIE`); where the points
   measured their image error, a factor that keeps the frame rate but changes the error says so (it does not
   "change nothing"), the best of points tied in frame rate is the one of least error, and "What
   quality costs" names the factor that moves the error most.
6. What do the granularity and extreme studies find? The largest packet up to which every
   size keeps within 1% of the reference's cycles (not a lucky size past one that does not),
   and the default size's error; the cases not as expected.

The sentences on the sweeps' points (their frame rates, bottleneck PM and image error) are
:mod:`tlm.report.summary_points`'s; those on what a sweep's factors do (question 5, and the factor that
moves the image error most) :mod:`tlm.report.summary_effects`'s; those on the studies that need no figure (the
error-vs-cost studies' seeds, the errors shown elsewhere, question 6) :mod:`tlm.report.summary_studies`'s.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

from tlm.config import ArchConfig
from tlm.experiments.thesis import THESIS_SCENES, median_words, slowest_words
from tlm.report.collect import Inputs, Run, with_set
from tlm.report.common import Figure, Section, bar_style, legend_below, line_style, log_ticks, new_figure, save, some
from tlm.report.compare import compare_lines
from tlm.report.compare import groups as compare_groups
from tlm.report.compare import short as compared_name
from tlm.report.html import esc
from tlm.report.summary_effects import error_factor, sweep_findings
from tlm.report.summary_points import (
    BUSIEST,
    PM_METRIC,
    PMS,
    bottleneck_of_points,
    busy_shares,
    fps_of_points,
    points_error,
    sweep_bottlenecks,
)
from tlm.report.summary_points import and_ as _and
from tlm.report.summary_points import count as _count
from tlm.report.summary_points import number as _number
from tlm.report.summary_studies import base_seed as _base_seed  # noqa: F401  (kept importable from here)
from tlm.report.summary_studies import other_errors as _other_errors
from tlm.report.summary_studies import seeds_words as _seeds_words
from tlm.report.summary_studies import study_findings as study_findings
from tlm.report.summary_studies import study_labels as _study_labels
from tlm.report.tables import study_summaries, thesis_table

MODES = ("rcast", "reflect", "refract", "pmap")
MODE_NAMES = {"rcast": "RCast", "reflect": "Reflect", "refract": "Refract", "pmap": "PMap"}
SIZE = (5.4, 3.1)
SCALING_LINES = 8  # curves of the scaling figure: of more, merged where the same, then the extremes


def _configured(config: dict) -> int:
    """A config's ``arch.pipelines`` (where it has none: the default, one)."""
    arch = config.get("arch") if isinstance(config, dict) else None
    n = arch.get("pipelines") if isinstance(arch, dict) else None
    return n if isinstance(n, int) and not isinstance(n, bool) and n > 0 else ArchConfig().pipelines


def _pipelines(run: Run) -> int:
    """How many pipelines ``run`` simulated: its results' per-pipeline cycles, else its
    config's ``arch.pipelines``."""
    per_pipe = run.results.get("pipelines")
    return len(per_pipe) if isinstance(per_pipe, list) and per_pipe else _configured(run.config)


def _fps(inputs: Inputs, out: Path) -> tuple[str, Figure | None]:
    thesis = inputs.of_kind("thesis")
    others: list = []  # the runs with a frame rate that the figure does not draw
    pipes: dict[tuple, int] = {}  # (scene, mode) drawn -> its pipelines
    twice: set[tuple] = set()  # (the scene-modes of runs compared: tlm.report.compare)
    drawn: dict[tuple, Run] = {}  # (a run's bar's key -> the run, where runs are drawn)
    compared: set[tuple] = set()  # (their bars' keys)
    fast = [r for r in inputs.runs if r.kind == "run" and isinstance(r.results.get("fps"), int | float)
            and not isinstance(r.results.get("fps"), bool) and r.results["fps"] > 0]
    if thesis:
        rows = [r for r in thesis[0].rows if r["metric"] == "FPS"]
        cells = {(r.path.parent.name, r.path.name): _pipelines(r) for r in inputs.runs
                 if r.kind == "thesis" and r.path.parent.parent == thesis[0].path}
        study = _configured(thesis[0].meta.get("config") or {})  # (a cell whose folder is not there)
        pipes = {(r["scene"], r["mode"]): cells.get((str(r["scene"]), str(r["mode"])), study) for r in rows}
        named = {s: inputs.study_scene(thesis[0], s) for s, _ in pipes}  # (the scene by its file, as in §1)
        ours = {(named[r["scene"]], r["mode"]): r["ours"] for r in rows}
        theirs = {(named[r["scene"]], r["mode"]): r["thesis"] for r in rows}
        pipes = {(named[s], m): n for (s, m), n in pipes.items()}
        others = sorted(fast, key=lambda r: r.results["fps"])
    else:
        ours = {}
        twice = {(r.scene_label, r.mode) for g in compare_groups(inputs) for r in g}
        for r in fast:  # (a scene-mode run more than once: a bar per run, named by its folder, in the order given)
            k = (compared_name(r) if (r.scene_label, r.mode) in twice else r.scene_label, r.mode)
            k = k if k not in drawn else (r.label, r.mode)
            drawn[k] = r
            if (r.scene_label, r.mode) in twice:
                compared.add(k)
        ours = {k: r.results["fps"] for k, r in drawn.items()}
        pipes = {k: _pipelines(r) for k, r in drawn.items()}
        others.sort(key=lambda r: r.results["fps"])
        theirs = {}
    ours = {k: v for k, v in ours.items() if isinstance(v, int | float) and v > 0}
    if not ours:
        return fps_of_points(inputs), None
    scenes = sorted({s for s, _ in ours}, key=_scene_order) if thesis or not twice else \
        list(dict.fromkeys(s for s, _ in ours))  # (runs compared: in the order given, the baseline first)
    fig = new_figure(*SIZE)
    ax = fig.add_subplot()
    drawn_modes = [m for m in MODES if any((s, m) in ours for s in scenes)]  # (the legend names the bars drawn)
    drawn_modes += sorted({m for _, m in ours} - set(MODES))
    width = 0.8 / len(drawn_modes)
    ticks = 0  # the thesis's values drawn
    for j, mode in enumerate(drawn_modes):
        xs = [i + (j - (len(drawn_modes) - 1) / 2) * width for i in range(len(scenes))]
        ax.bar(xs, [ours.get((s, mode), 0) for s in scenes], width, label=MODE_NAMES.get(mode, mode),
               **bar_style(MODES.index(mode) if mode in MODES else j))
        th = [theirs.get((s, mode)) if (s, mode) in ours else None for s in scenes]
        at = [(x, t) for x, t in zip(xs, th, strict=True) if t]
        if at:  # a black tick on a white one: seen on a black bar, a white one and the background alike
            ax.plot([x for x, _ in at], [t for _, t in at], "_", color="white", markersize=13, markeredgewidth=5)
            ax.plot([x for x, _ in at], [t for _, t in at], "k_", markersize=11, markeredgewidth=2,
                    label=None if ticks else "thesis")
            ticks += len(at)
    base = {(g[0].scene_label, g[0].mode): g[0] for g in compare_groups(inputs)} if compared else {}
    for k in compared:  # (a run compared: its frame rate on its bar, and B/A against its scene-mode's first)
        r, x = drawn[k], scenes.index(k[0]) + (drawn_modes.index(k[1]) - (len(drawn_modes) - 1) / 2) * width
        first = base.get((r.scene_label, r.mode))
        a = first.results.get("fps") if first is not None else None
        ratio = "\nA" if first is r else f"\n{ours[k] / a:.3g}x" if _number(a) and a > 0 else ""
        ax.annotate(f"{ours[k]:.3g}{ratio}", (x, ours[k]), ha="center", va="bottom", fontsize=7,
                    xytext=(0, 2), textcoords="offset points")
    ax.set_xticks(range(len(scenes)), scenes)
    ax.set_yscale("log")
    if compared:  # (each bar tall enough to see against the others, its label room above the highest)
        ax.set_ylim(min(ours.values()) / 3, max(ours.values()) * 2)
    ax.set_ylabel("frames per second")
    ax.legend(fontsize=7, ncol=5, loc="upper center", bbox_to_anchor=(0.5, 1.18), frameon=False)
    which = (f"the thesis study {thesis[0].path.name}" + (f" (the first of {len(thesis)})" if len(thesis) > 1 else "")
             if thesis else "")
    f = save(fig, out, "summary_fps.png", "Frames per second",
             (f"bars: ours, the frames of {which}, at the simulated clock" if thesis
              else "bars: ours at the simulated clock")
             + ("; black ticks edged in white: the thesis's Tables I–III" if ticks else "")
             + ("; a scene-mode run more than once: a bar per run, in the order given, each labelled with its frame "
                "rate and B/A against the first (A)" if compared else "")
             + (f"; {_count(len(others), 'other run')} among the inputs not drawn ("
                + ("its frame rate is" if len(others) == 1 else "their frame rates are") + " in the text)"
                if others else ""))
    best = max(ours, key=ours.get)
    worst = min(ours, key=ours.get)
    every = {*(pipes.get(k) for k in ours), *(_pipelines(r) for r in others)}
    one = len(every) == 1  # (every frame rate said at the same count: said once, at the end)

    def cell(k: tuple) -> str:  # (a run compared: what differs is its comparison's line, not its pipelines alone)
        return (f"{esc(str(k[0]))} {MODE_NAMES.get(k[1], k[1])}"
                f"{'' if one or k in compared else ', ' + _count(pipes[k], 'pipeline')}")

    n_one = next(iter(every)) if one else None
    alike = f"{ours[worst]:.3g}" == f"{ours[best]:.3g}"  # (every cell at one rate as said: each named, not one twice)
    each = sorted(ours, key=lambda k: (scenes.index(k[0]), MODES.index(k[1]) if k[1] in MODES else 9))
    text = (f"<b>How fast:</b> {'in the frames of ' + esc(which) + ', ' if thesis else ''}"
            + (f"from {ours[worst]:.3g} FPS ({cell(worst)}) to {ours[best]:.3g} FPS ({cell(best)})" if not alike
               else f"{ours[best]:.3g} FPS ({some([cell(k) for k in each])})")
            + (f" at {'one pipeline' if n_one == 1 else f'{n_one} pipelines'}." if one else "."))
    if others:  # (not drawn beside the thesis's cells, but not left unsaid)
        said_runs = [f"{esc(r.label)} {r.results['fps']:.3g} FPS"
                     + ("" if one else f" ({_count(_pipelines(r), 'pipeline')})") for r in others]
        if len(said_runs) > 4:
            said_runs = [said_runs[0], f"… {len(said_runs) - 2} more …", said_runs[-1]]
        text += (f" The {'other run' if len(others) == 1 else _count(len(others), 'other run')} among the inputs, "
                 "not in the figure: "
                 f"{'; '.join(said_runs)}.")
    said = []  # every thesis study's median, judged as the tables judge it (none where not comparable)
    summaries = study_summaries(inputs)
    for study, s in summaries:
        words = median_words(s)
        said.append(f"{'thesis study ' + study.path.name + ': ' if len(summaries) > 1 else ''}{words}")
    if said:
        text += f" Against Tables I–III: {esc('; '.join(said))}."
        # (the scenes of its cells, as the tables name them: thesis/ring; the framed ones, comparable, in a median)
        framed = [s for _, s in summaries if s.get("median_abs_rel_error_held_out") is not None
                  and any(Path(c).name in ("ring", "room") and c not in (s.get("not_comparable") or {})
                          for c in {k.rsplit("/", 1)[0] for k in s.get("slowest_pm") or {}})]
        if framed:  # (a median over the thesis's ring or room, whose framing was chosen against the same cells)
            text += (" The thesis's ring and room were framed against these same tables (the ring's missed eye rays, "
                     "the room's one light: docs/fidelity.md, “The scenes”), so the agreement is not independent "
                     "of them.")
    return text, f


def _scene_order(label: str) -> tuple:
    """The thesis's scenes first, in the order of its tables (ring, room, Cornell), then the others."""
    order = list(THESIS_SCENES.values())
    return (order.index(label) if label in order else len(order), label)


def _bottleneck(inputs: Inputs, out: Path) -> tuple[str, Figure | None]:
    cells: dict[tuple[str, str], dict[str, float]] = {}
    cell_of: dict[tuple[str, str], str] = {}  # a cell of the thesis's scenes: its key in the study's summary
    twice = {(r.scene_label, r.mode) for g in compare_groups(inputs) for r in g}  # (a row per run compared)
    for r in inputs.runs:
        key = (r.scene_label, r.mode)
        if r.kind == "run" and key in twice:
            key = (f"{r.scene_label} ({compared_name(r)})", r.mode)
        if r.kind != "thesis" and not (r.kind == "run" and key not in cells):
            continue
        busy = busy_shares(r.results)  # (each PM's busiest pipeline's, as its cycles.<pm> and slowest_pm)
        if busy is not None:
            cells[key] = busy
            if thesis_table(r) == r.scene:  # (the thesis's scene by its file, as the tables say)
                cell_of[key] = f"{r.scene}/{r.mode}"  # (the study's name of the cell)
    if not cells:
        return bottleneck_of_points(inputs), None
    thesis = inputs.of_kind("thesis")
    slowest = (thesis[0].meta.get("slowest_pm") or {}) if thesis else {}
    keys = sorted(cells, key=lambda k: (_scene_order(k[0]), MODES.index(k[1]) if k[1] in MODES else 9))
    if twice and not thesis:  # (runs compared: in the order given, the baseline first)
        keys = list(cells)
    # (h541: beside a thesis study its scene-modes are rows too, not runs)
    rows = "rows (the thesis study's scene-modes and the runs compared)" if twice and thesis else \
        "runs" if twice else "scene-modes"
    grid = np.array([[cells[k][pm] for pm in PMS] for k in keys])
    fig = new_figure(SIZE[0], max(SIZE[1], 0.22 * len(keys) + 0.9))
    ax = fig.add_subplot()
    ax.imshow(grid, cmap="Greys", vmin=0, vmax=1, aspect="auto")
    marked = 0  # the thesis's slowest PMs drawn
    for i, k in enumerate(keys):
        for j, pm in enumerate(PMS):
            v = grid[i, j]
            mark = ""
            if k in cell_of and (slowest.get(cell_of[k]) or {}).get("thesis") == PM_METRIC[pm]:
                mark = " ▲"
                marked += 1
            ax.text(j, i, f"{100 * v:.0f}%{mark}", ha="center", va="center", fontsize=7,
                    color="white" if v > 0.55 else "black", fontweight="bold" if j == grid[i].argmax() else None)
    ax.set_xticks(range(len(PMS)), [PM_METRIC[p] for p in PMS])
    ax.set_yticks(range(len(keys)), [f"{s} {MODE_NAMES.get(m, m)}" for s, m in keys], fontsize=7)
    f = save(fig, out, "summary_bottleneck.png", "Busy share per PM",
             "each cell: busy cycles / elapsed cycles of the PM (with N pipelines: its busiest pipeline's); "
             "bold: our bottleneck"
             + ("; ▲: the thesis's slowest PM" if marked else ""))
    tops = defaultdict(int)
    for k in keys:
        tops[PMS[int(np.argmax(grid[keys.index(k)]))]] += 1
    most = max(tops.values())
    top = [pm for pm in PMS if tops[pm] == most]  # (PM order: a tie is said as one, not one of it at random)
    share = [cells[k][pm] for pm in top for k in keys if PMS[int(np.argmax([cells[k][p] for p in PMS]))] == pm]
    low, high = f"{100 * min(share):.0f}", f"{100 * max(share):.0f}"  # (one value, or all alike: said once)
    busy = f"busy {low if low == high else f'{low}–{high}'}%"
    if len(keys) == 1:
        text = f"<b>What limits it:</b> the {PM_METRIC[top[0]]} PM is the bottleneck in the only scene-mode, busy " \
               f"{high}% of the time."
    elif len(top) == 1:
        text = (f"<b>What limits it:</b> the {PM_METRIC[top[0]]} PM is the bottleneck in {most} of {len(keys)} "
                f"{rows}, {busy} of the time.")
    else:
        names = _and([PM_METRIC[pm] for pm in top])
        text = (f"<b>What limits it:</b> no one PM: each of {names} is the bottleneck in {most} of {len(keys)} "
                f"{rows}, {busy} of the time there.")
    if slowest:
        m = sum(v["match"] for v in slowest.values())
        words = slowest_words({"scene_modes": len(slowest), "slowest_pm_matches": m, **thesis[0].meta})
        text += (f" {words[0].upper()}{words[1:]}." if len(slowest) > 1 else  # (qualified: slowest_words)
                 f" The slowest PM is {'' if m else 'not '}the thesis's.")
    points = sweep_bottlenecks(inputs)  # (not in the figure: the sweeps' points, where the bottleneck moves)
    if points:
        text += f" Across the sweeps' points (not drawn): {'; '.join(points)}. {BUSIEST[0].upper()}{BUSIEST[1:]}."
    return text, f


def _scaling(inputs: Inputs, out: Path) -> tuple[str, Figure | None]:
    """The speed-up of TThru against N of every eq. 5.2 fit that §3 draws (:func:`fit_sources`: the
    ``tlm scaling`` folders' and those of the sweeps over ``arch.pipelines``, a fit per combination of
    a sweep's other factors), the static scheduler's where a curve has it."""
    from tlm.experiments.scaling import key_group, out_of_date
    from tlm.report.scaling import extremes, fit_sources, fitted_sweeps, idle_points, short_combination
    from tlm.report.sweep_lines import legend_under
    from tlm.report.sweeps import factors_of

    # (source, scene, mode, group) -> scheduler -> rows: a scaling study's rows (eq52.csv), a sweep's fits
    found: dict[tuple, dict[str, list[dict]]] = defaultdict(lambda: defaultdict(list))
    studies = inputs.of_kind("scaling")
    stale = set()  # (the studies whose sweep holds other points now: §3 marks their fits out of date, and so here)
    for st in studies:
        if any(n.startswith("out of date") for n in out_of_date(st.path, st.meta)):
            stale.add(st.path.name)
        for r in st.rows:
            if r.get("target") == "throughput":  # (the scene by its file, as in §3)
                at = (st.path.name, inputs.study_scene(st, r["scene"]), r.get("mode", ""), r.get("group") or "")
                found[at][str(r.get("scheduler"))].append(r)
    sweeps = fit_sources(inputs, [], studies=False)  # (§3 says what was not fitted and why)
    for _, label, fits, named, _, _ in sweeps:
        for key, f in fits.items():
            scene, mode, sched, target = key[:4]
            if target == "throughput" and f.get("rows"):
                found[(label, named.get(scene, scene), mode, key_group(key))][sched] = f["rows"]
    # (a sweep over arch.pipelines that §3 does not fit but draws the idle tables of, TThru and speed-up per N:
    # one passed for §3's idle fractions alone that no scaling study among the inputs was fitted from, or one
    # of rows alone, no results folder to fit: its curve is said here, from those rows)
    # (a sweep among the inputs that a study's fit shows as it is now: fit_sources skips it; one read for the idle
    # fractions alone, that a study lists: §3 shows it through that study's fit, even one out of date)
    covered, listed = fitted_sweeps(inputs), fitted_sweeps(inputs, current=False)
    for sw, shown in [*((sw, listed) for sw in inputs.scaling_sweeps),
                      *((sw, covered) for sw in inputs.sweeps if not sw.runs)]:
        if sw.path.resolve() in shown or "arch.pipelines" not in factors_of(sw):
            continue
        for key, g in idle_points(sw, []).items():
            for p in g["points"]:
                if _number(p["throughput"]) and p["throughput"] > 0:
                    found[(sw.label, key[0], key[1], key[2] if len(key) > 2 else "")][p["scheduler"]].append(
                        {"pipelines": p["pipelines"], "simulated": p["throughput"]})
    curves = {at: ("static", by["static"]) if by.get("static") else next(iter(by.items()))
              for at, by in found.items() if any(by.values())}
    if not curves:
        if sweeps:
            return (f"No eq. 5.2 fit of {', '.join(dict.fromkeys(label for _, label, *_ in sweeps))}: no scaling to "
                    "show (§3's notes say why).", None)
        return "No eq. 5.2 study or sweep over arch.pipelines among the inputs: no scaling to show.", None
    scenes = defaultdict(set)  # (a scene fitted from two folders: each curve names its folder)
    for label, scene, _, _ in curves:
        scenes[scene].add(label)
    modes = len({mode for _, _, mode, _ in curves}) > 1
    order = sorted(curves, key=lambda c: (_scene_order(c[1]), c[0], c[2]))
    lines = []  # (name, N, speed-ups): each curve's, those whose points are the same one line
    same: dict[str, int] = {}
    for at in order:
        label, scene, mode, group = at
        sched, rs = curves[at]
        rs = sorted(rs, key=lambda r: r["pipelines"])
        ref = rs[0]["simulated"]
        n = [r["pipelines"] for r in rs]
        sp = [ref / r["simulated"] for r in rs]
        many = len(curves) > SCALING_LINES
        shown = short_combination(group) if many else group
        name = " ".join(w for w in (scene, MODE_NAMES.get(mode, mode) if modes else "",
                                    f"({label})" if len(scenes[scene]) > 1 else "",
                                    f"[{shown}]" if shown else "", "" if sched == "static" else f"({sched})",
                                    "(out of date)" if label in stale else "") if w)
        sig = repr((label, scene, mode, sched, n, sp))
        if many and sig in same:  # (a sweep's combinations of one curve: drawn once, counted)
            lines[same[sig]][3] += 1
            continue
        same[sig] = len(lines)
        lines.append([name, n, sp, 1])
    drawn = extremes(lines, lambda x: x[2][-1], SCALING_LINES)
    fig = new_figure(*SIZE)
    ax = fig.add_subplot()
    top_n = 1
    for i, (name, n, sp, k) in enumerate(drawn):
        ax.plot(n, sp, label=name if k == 1 else f"{name} and {k - 1} more (identical)", **line_style(i))
        top_n = max(top_n, n[-1])
    ax.plot([1, top_n], [1, top_n], color="0.6", linewidth=1, label="ideal")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log", base=2)
    ax.set_xlabel("pipelines N")
    ax.set_ylabel("speed-up of TThru")
    caption = ("speed-up of the throughput TThru against N = 1, static tiles unless a line names its scheduler; "
               "grey: the ideal N")
    if len(curves) > SCALING_LINES:  # (the legend under the plot, its labels wrapped: legend_under)
        legend_under(fig, ax, *SIZE)
        caption += (f"; of {len(curves)} curves ({len(lines)} distinct), those of the "
                    f"{SCALING_LINES - SCALING_LINES // 2} highest and {SCALING_LINES // 2} lowest speed-ups at the "
                    "largest N are drawn (§3's notes name the rest; sweep.csv holds every point)"
                    if len(drawn) < len(lines) else f"; {len(curves)} curves, {len(lines)} distinct")
    else:
        legend_below(ax)
    f = save(fig, out, "summary_scaling.png", "Scaling with N pipelines", caption)
    gains = [(name if k == 1 else f"{name} and {k - 1} more (identical)", n[-1], sp[-1]) for name, n, sp, k in lines]
    if len(lines) <= SCALING_LINES:
        parts = ", ".join(f"{esc(s)} {g:.1f}x at N = {n:g}" for s, n, g in gains)
    else:  # (a sweep of many combinations: the range, the best and the worst, not a sentence per curve)
        best, worst = max(gains, key=lambda x: x[2]), min(gains, key=lambda x: x[2])
        parts = (f"from {worst[2]:.2f}x to {best[2]:.2f}x over {len(curves)} curves; best {esc(best[0])} "
                 f"{best[2]:.2f}x at N = {best[1]:g}, worst {esc(worst[0])} {worst[2]:.2f}x at N = {worst[1]:g}")
    text = f"<b>Does it scale:</b> {parts} (static tiles; the dynamic scheduler and eq. 5.2 are in §3)."
    # (eq. 5.2's latency fits where the latency is images in flight x TThru at every point: the throughput's scaled)
    lat = [f for st in studies for f in st.meta.get("fits") or []
           if isinstance(f, dict) and f.get("target") == "latency"]
    scaled = [f for f in lat if isinstance(f.get("latency_multiple"), int)]
    if scaled:
        k = ", ".join(str(x) for x in sorted({f["latency_multiple"] for f in scaled}))
        which = ("The eq. 5.2 latency fit in §3 is its throughput fit" if len(lat) == 1 else
                 f"The {len(lat)} eq. 5.2 latency fits in §3 are their throughput fits" if len(scaled) == len(lat) else
                 f"{len(scaled)} of the {len(lat)} eq. 5.2 latency fits in §3 are their throughput fits")
        text += (f" {which} x {k}: in this closed loop the latency is images in flight x TThru (Little's law), "
                 "no second test of eq. 5.2.")
    if stale & {label for label, *_ in curves}:
        text += (f" Out of date: {esc(_and(sorted(stale & {label for label, *_ in curves})))}'s sweep holds other "
                 "points now than its fit was made from (§3's notes say which).")
    return text, f


def _tradeoff(inputs: Inputs, out: Path) -> tuple[str, Figure | None]:
    from tlm.report.tradeoff import (
        KNN_REFERENCE,
        KNN_WHY,
        as_drawn,
        black_words,
        floor_line,
        log_floor,
        reference_converged,
        reference_line,
        series_styles,
        truth_noise_words,
        unmodelled_cost,
    )
    from tlm.report.tradeoff import gather_rays as _gather_rays
    from tlm.report.tradeoff import series_of as _series

    studies = [st for st in inputs.of_kind("error-vs-cost") if st.rows]
    labels = _study_labels(studies)
    rows = [{**r, "_study": st} for st in studies for r in st.rows]
    err = "truth_rel_mse" if any(r.get("truth_rel_mse") is not None for r in rows) else "rel_mse"
    measured = [r for r in rows if r.get(err) is not None]
    rows = [r for r in measured if _number(r.get("frame_seconds")) and r["frame_seconds"] > 0]  # (a log axis's)
    black, said = black_words(studies, err)  # (a study whose reference, or truth, is black: no relative MSE, h419)
    if not rows and studies:  # (not "no error-against-cost study": a black image, or the frame not simulated)
        others = len(studies) - len(black)
        return ("<b>What quality costs:</b> " + said + ((" No row of the other" if black else "no row of the")
                + " error-against-cost " + ("study" if others == 1 else "studies") + " among the inputs has both a "
                "relative MSE and a "
                "simulated frame time above 0 (a study written before 'tlm error-vs-cost' simulated the frame: run it "
                "again): no error against frame time here; its figures draw the RMSE against host wall time."
                if others else " No error against frame time here.")
                + points_error(inputs) + error_factor(inputs)), None
    if not rows:
        return _other_errors(inputs), None

    def series_of(r: dict) -> str:  # (a row's series: its filter, final gathering, and study where several)
        where = labels[id(r["_study"])]
        return _series(r) + (f" ({where})" if where else "")

    fig = new_figure(*SIZE)
    ax = fig.add_subplot()
    order = {id(st): i for i, st in enumerate(studies)}
    series = [series_of(r) for r in sorted(rows, key=lambda r: (str(r["filter"]), _gather_rays(r),
                                                                 order[id(r["_study"])]))]
    series = list(dict.fromkeys(series))  # (a filter with final gathering is a series of its own, after it)
    # one study: each series the style the study's own figures give it (of all its rows, drawn or not); several: in turn
    styles = series_styles(studies[0].rows) if len(studies) == 1 else {name: i for i, name in enumerate(series)}
    values = np.array([float(r[err]) for r in rows])
    floor = log_floor(values)  # (an error of 0 drawn a decade below the least positive one)
    log_y = floor == floor  # (none above 0: a linear axis, each error drawn as it is; a log one could draw none)
    drawn = as_drawn(values, floor if log_y else None)  # (on a log axis: a 0 at the floor, below 0 left off)
    zero, below, odd = int((values == 0).sum()), int((values < 0).sum()), int((~np.isfinite(values)).sum())
    shown = np.isfinite(drawn)
    apart = False  # (the k-NN reference drawn: hollow, its own key, as its frame time leaves out its search)
    for name in [n for n in series if any(k and series_of(r) == n for r, k in zip(rows, shown, strict=True))]:
        xy = sorted(((r["frame_seconds"] * 1e3, y) for r, y, k in zip(rows, drawn, shown, strict=True)
                     if k and series_of(r) == name), key=lambda p: p[0])
        knn = any(unmodelled_cost(r) for r in rows if series_of(r) == name)
        apart |= knn
        ax.plot([x for x, _ in xy], [y for _, y in xy], label=name + (f" ({KNN_REFERENCE})" if knn else ""),
                **{**line_style(styles[name]), "linestyle": "none", **({"markerfacecolor": "none"} if knn else {})})
    floor_line(ax, "y", floor if log_y else None, values, "error")
    ax.set_xscale("log")
    log_ticks(ax, "x")  # (no minor tick labels running into each other)
    if log_y:
        ax.set_yscale("log")
        log_ticks(ax, "y")
    ax.set_xlabel("simulated frame time TThru / clock (ms)")
    ax.set_ylabel("relative MSE" + (" vs Mitsuba" if err == "truth_rel_mse" else " vs reference"))
    legend_below(ax)
    f = save(fig, out, "summary_tradeoff.png", "Error against frame time",
             "each point: one photon count, radius or k of a filter (with final gathering, when on, a series "
             "of its own" + ("; each study's points a series of their own, named by its folder and the --set "
                             "overrides the other studies do not share" if len(studies) > 1 else "")
             + "); lower left is better"
             + (f"; hollow: the k-NN reference (knn), not comparable: {KNN_WHY}" if apart else "")
             + (f"; {zero} of them with an error of 0, which a log axis cannot show: drawn at {floor:.2g} (the "
                "dotted line)" if zero and log_y else "")
             + (f"; {below} with an error below 0, which a log axis cannot show: not drawn" if below and log_y else "")
             + ("" if log_y else "; no error is above 0, which a log axis needs: the error axis is linear")
             + (f"; {odd} with an error that is not a finite number: not drawn" if odd else "")
             + (f"; {len(measured) - len(rows)} with no simulated frame time above 0: not drawn"
                if len(measured) > len(rows) else ""))
    quoted = [r for r, v in zip(rows, values, strict=True) if np.isfinite(v) and v >= 0]  # (below 0: no error)
    if not quoted:
        return (f"<b>What quality costs:</b> none of the {_count(len(rows), 'error-against-cost row')} has a relative "
                f"MSE of 0 or above ({esc(', '.join(f'{v:.3g}' for v in values[:3]))}"
                f"{', ...' if len(values) > 3 else ''}): no lowest error to quote (the figure's caption says which "
                "are drawn)." + points_error(inputs) + error_factor(inputs)), f
    left = len(rows) - len(quoted)
    rows = quoted
    best, knn = {}, {}  # (knn: the k-NN reference, whose frame time leaves out its search: ranked by it nowhere)
    for r in rows:
        into = knn if unmodelled_cost(r) else best
        if series_of(r) not in into or r[err] < into[series_of(r)][err]:
            into[series_of(r)] = r
    if not best:
        return ("<b>What quality costs:</b> only the k-NN reference (knn) was measured, relative MSE "
                f"{min(r[err] for r in knn.values()):.3g}: its simulated frame time leaves out its search (not "
                "modelled), so no filter is ranked by frame time." + points_error(inputs) + error_factor(inputs)), f
    lo = min(best.values(), key=lambda r: r[err])
    gather = _gather_rays(lo)
    st = lo["_study"]
    # (the input the numbers are from, where another study or a --set could have made them: its folder, --set)
    source = ", ".join(w for w in (st.path.name, with_set(st.overrides)) if w) \
        if len(studies) > 1 or st.overrides else ""
    # (several studies: a value against a reference that did not converge says so, as the lowest's does)
    unsure = {id(s) for s in studies if len(studies) > 1 and err == "rel_mse" and reference_converged(s) is False}
    rest = [f"{esc(k)} {best[k][err]:.3g} at {best[k]['frame_seconds']:.3g} s"
            + (" (against a reference NOT converged)" if id(best[k]["_study"]) in unsure else "") for k in series
            if k in best and best[k] is not lo]
    refs = [f"{esc(k)} {knn[k][err]:.3g}" + (" (against a reference NOT converged)" if id(knn[k]["_study"]) in unsure
                                             else "") for k in series if k in knn]
    if err == "truth_rel_mse":  # (the truth's samples, and where they are few, that its noise is in the error)
        spp = lo.get("truth_spp")
        against = " against Mitsuba's path tracer" + (f" ({int(spp):,} spp)" if _number(spp) and spp > 0 else "")
        noise = f" {esc(words)}" if (words := truth_noise_words(spp)) else ""
        named = ""
    else:
        against = " against our reference" + (" (NOT converged)" if reference_converged(st) is False else "")
        noise = ""
        # (the reference in one line: its key, photons a round, k_nearest, rounds and resolution, h507)
        named = f" That error is against {esc(reference_line(st))}." if reference_line(st) else ""
    # (one seed's winner is one sample: said as such; among the filters ranked, as the lowest error above is)
    seeds = _seeds_words([r for r in rows if not unmodelled_cost(r)], err, series_of)
    text = (f"<b>What quality costs:</b> the lowest error{' of a filter whose search is modelled' * bool(knn)} is "
            f"{esc(lo['filter'])}'s"
            + (f" with final gathering ({gather} rays)" if gather else "")
            + (f" (from {esc(source)})" if source else "") + ", relative MSE "
            f"{lo[err]:.3g} at {lo['frame_seconds']:.3g} s a frame"
            + against + (f"; {', '.join(rest)}" if rest else "")
            + (f"; the k-NN reference, not ranked as its frame time leaves out its search (not modelled): "
               f"{', '.join(refs)}" if refs else "")
            + (f" ({_count(left, 'row')} with a relative MSE below 0 or not a finite number left out)" if left
               else "") + "." + named + esc(seeds) + noise + (f" {said}" if said else "")
            + points_error(inputs) + error_factor(inputs))
    return text, f


def summary_section(inputs: Inputs, out: Path) -> Section:
    sec = Section("summary", "What the model found")
    texts, figs = [], []
    for q in (_fps, _bottleneck, _scaling, _tradeoff):
        text, fig = q(inputs, out)
        texts.append(text)
        if q is _fps:  # (runs of one scene-mode compared, B/A: after how fast they are)
            texts += compare_lines(inputs)
        if fig is not None:
            figs.append(fig)
    found = sweep_findings(inputs) + study_findings(inputs)
    sec.lead = "<br>".join([*found, *texts])  # a sweep's or a study's finding first: it is what its report is for
    sec.figures = figs
    sec.shown = len(figs)
    if not figs and not found:
        sec.absent = ("the inputs hold no frame rates, busy shares, scaling sweeps, sweep points, error, "
                      "granularity or extreme studies")
    return sec

