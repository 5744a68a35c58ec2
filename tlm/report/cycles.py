"""Section: where the cycles go (eq. 5.1 per PM, and the timeline of every unit).

Two figures per run shown:

* **eq. 5.1 breakdown**: one stacked bar per Processing Module, in cycles per frame
  (the run's totals over ``timing.frames`` frames, divided by the frame count):
  instructions T_norm, page misses T_ms, pipeline flushes T_ps, the data stalls T_ds by
  cause, and idle, so that every bar reaches the elapsed time per frame. With up to
  :data:`FEW_PIPELINES` pipelines every PM of every pipeline has its bar; with more, a
  PM kind's bar is the mean over the pipelines (the caption says so).
* **timeline**: a Gantt chart from ``trace.json``: per unit (PMs, memory modules,
  the compose unit, the crossbar) when it is busy, stalled (by cause) or idle, and when
  a PM holds a preempted job of the other image (a striped band under its row).
  Adjacent slices of one state are merged; a trace with more rectangles than the picture
  has pixels (:data:`MAX_RECTS`) is drawn at pixel resolution: each pixel column of a row
  shows the state that fills most of it (the caption says so).

The number of runs is bounded (:data:`MAX_RUNS`): every ``tlm run`` folder, for a
thesis study the slowest mode of each scene, for a sweep the fewest and the most
pipelines of each combination of its other factors, or its first and last point if it
does not vary ``arch.pipelines``; a note counts what was left out and names a few
(:data:`~tlm.report.common.NAMED`).
"""

from __future__ import annotations

import json
import re
import textwrap
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib.patches import Patch, PathPatch
from matplotlib.path import Path as MplPath

from tlm.arch.fifo import fifo_held
from tlm.arch.units import STALL_CAUSES
from tlm.report.collect import Inputs, Run
from tlm.report.common import FigureName, Section, count, new_figure, save, some
from tlm.report.compare import groups
from tlm.report.names import value_text
from tlm.report.numbers import sig, whole
from tlm.report.written import kept

PMS = ("vertex", "traversal", "intersection", "fragment")
FEW_PIPELINES = 2  # up to this many pipelines, every PM has a bar of its own
MAX_RUNS = 8  # runs shown (breakdown + timeline each)
MAX_GANTT_ROWS = 30  # more units: the first and the last pipeline (and the shared units) only
MAX_RECTS = 20000  # more merged slices than this: draw at pixel resolution
BINS = 1600  # pixel columns of the timeline at pixel resolution
MIN_WIDTH_PX = 800  # the time axis is about this many pixels wide: no span is drawn narrower than one

SEGMENTS = ("T_norm", "T_ms", "T_ps", *(f"stall: {c}" for c in STALL_CAUSES), "idle")
SEGMENT_LABELS = {"T_norm": "T_norm: instructions", "T_ms": "T_ms: page misses", "T_ps": "T_ps: pipeline flushes",
                  **{f"stall: {c}": f"T_ds: {c} stall" for c in STALL_CAUSES}, "idle": "idle"}
# the timeline's states, in legend order ("busy" is a PM's work: T_norm + T_ms + T_ps)
STATES = ("busy", "page misses", "block copy", *(f"stall: {c}" for c in STALL_CAUSES), "idle")
STATE_LABELS = {"busy": "busy (a PM's work: T_norm + T_ms + T_ps)", "page misses": "page misses (memory module)",
                "block copy": "block copy (memory module, crossbar)",
                **{f"stall: {c}": f"{c} stall" for c in STALL_CAUSES}, "idle": "idle",
                "preempted": "holds a preempted job (band under the row)"}
# greyscale-safe: fills differ in luminance and each has its own hatch
STYLE = {
    "T_norm": ("#0072B2", ""), "busy": ("#0072B2", ""),
    "T_ms": ("#E69F00", "///"), "page misses": ("#E69F00", "///"),
    "T_ps": ("#56B4E9", "..."),
    "block copy": ("#009E73", "++"),
    "stall: handshake": ("#D55E00", "xxx"),
    "stall: swap": ("#F0E442", "\\\\\\"),
    "stall: copy": ("#CC79A7", "oo"),
    "stall: preemption": ("#777777", "**"),
    "stall: fifo_full": ("#000000", ""),
    "stall: fifo_empty": ("#BBBBBB", "---"),
    "idle": ("#F4F4F4", ""),
    "preempted": ("#FFFFFF", "||||"),
}
_EXTRA = [("#444444", "oo"), ("#999999", "xx"), ("#DDDDDD", "//")]  # states this module does not know

_UNIT = re.compile(r"^pipe(\d+)\.(\w+)$")


def style(state: str) -> tuple[str, str]:
    if state in STYLE:
        return STYLE[state]
    return _EXTRA[sum(map(ord, state)) % len(_EXTRA)]


# -- which runs ------------------------------------------------------------------------------

def _throughput(run: Run) -> float:
    return float((run.results.get("cycles") or {}).get("throughput") or 0)


def _pipelines(run: Run) -> int:
    return int(run.factors.get("arch.pipelines") or (run.config.get("arch") or {}).get("pipelines") or 1)


def select_runs(inputs: Inputs, limit: int = MAX_RUNS) -> tuple[list[Run], list[str]]:
    """The runs this section draws, and notes on which were chosen and why.

    Every ``tlm run`` folder; of a thesis study, the slowest mode (largest TThru) of each
    scene; of a sweep, the fewest and the most pipelines of each combination of its other
    factors (its first and last point if it does not vary ``arch.pipelines``). At most
    ``limit`` in all, in that order. A note that names runs names a few of many
    (:func:`~tlm.report.common.some`) and counts them all.
    """
    timed = [r for r in inputs.runs if (r.results.get("timing") or {}).get("units")]
    notes = []
    untimed = [r.label for r in inputs.runs if r not in timed]
    if untimed:
        notes.append(f"No timing results (not simulated), {len(untimed)} left out: {some(untimed)}.")
    chosen = [r for r in timed if r.kind == "run"]
    thesis = [r for r in timed if r.kind == "thesis"]
    if thesis:
        by_scene: dict[str, list[Run]] = defaultdict(list)
        for r in thesis:
            by_scene[r.scene_label].append(r)
        picks = [max(rs, key=_throughput) for rs in by_scene.values()]
        chosen += picks
        if len(picks) < len(thesis):
            shown = ", ".join(r.label for r in picks)
            rest = len(thesis) - len(picks)
            notes.append(f"Thesis cells: the slowest mode of each scene is shown ({shown}); "
                         f"the other {count(rest, 'cell')} {'is' if rest == 1 else 'are'} in Tables I-III.")
    in_sweep = {id(r) for r in timed if r.kind == "sweep-point"}
    for sw in inputs.sweeps:
        points = [r for r in sw.runs if id(r) in in_sweep]
        if not points:
            continue
        varies = any("arch.pipelines" in r.factors for r in points)
        groups: dict[tuple, list[Run]] = defaultdict(list)
        for r in points:  # (a sweep that does not vary the pipelines: one group, the whole sweep)
            key = tuple(sorted((k, repr(v)) for k, v in r.factors.items() if k != "arch.pipelines")) if varies else ()
            groups[key].append(r)
        picks = []
        for rs in groups.values():
            ends = [min(rs, key=_pipelines), max(rs, key=_pipelines)] if varies else [rs[0], rs[-1]]
            picks += [r for i, r in enumerate(ends) if r not in ends[:i]]
        chosen += picks
        if len(picks) < len(points):
            why = ("the fewest and the most pipelines of each combination of the other factors" if varies
                   else "its first and last point")
            notes.append(f"Sweep {sw.label}: {len(picks)} of {len(points)} points are shown, {why} "
                         f"({some([f'{r.label} [{_factors(r)}]' for r in picks])}).")
    if len(chosen) > limit:
        left = chosen[limit:]
        notes.append(f"At most {limit} runs are drawn; {len(left)} left out: {some([r.label for r in left])}.")
        chosen = chosen[:limit]
    return chosen, notes


def _factors(run: Run) -> str:
    return ", ".join(f"{k.split('.')[-1]}={value_text(k, v)}" for k, v in run.factors.items())


# -- (a) the eq. 5.1 breakdown ---------------------------------------------------------------

@dataclass
class Breakdown:
    """Stacked bars: ``segments[s][i]`` is bar i's cycles per frame in segment s."""

    labels: list[str]
    segments: dict[str, np.ndarray]
    elapsed: np.ndarray  # per bar: the unit's elapsed cycles per frame
    frames: int
    throughput: float  # TThru, cycles per frame
    aggregate: str | None = None  # how bars were aggregated over pipelines (None: one per PM)


def breakdown(run: Run, few: int = FEW_PIPELINES) -> Breakdown:
    """The eq. 5.1 terms per PM of ``run``, in cycles per frame (see the module docstring)."""
    timing = run.results["timing"]
    units = timing["units"]
    frames = max(int(timing.get("frames") or 1), 1)
    pms: list[tuple[int, str, dict]] = []
    for name, u in units.items():
        m = _UNIT.match(name)
        if m:
            pms.append((int(m.group(1)), m.group(2), u))
    order = {p: i for i, p in enumerate(PMS)}
    pms.sort(key=lambda t: (t[0], order.get(t[1], len(order)), t[1]))
    n_pipes = len({p for p, _, _ in pms})

    def values(u: dict) -> dict[str, float]:
        out = {"T_norm": u["T_norm"], "T_ms": u["T_ms"], "T_ps": u["T_ps"], "idle": u["idle"]}
        for c in STALL_CAUSES:
            out[f"stall: {c}"] = (u.get("stall") or {}).get(c, 0)
        return out

    rows: list[tuple[str, dict[str, float], float]] = []
    aggregate = None
    if n_pipes <= few:
        for p, name, u in pms:
            label = name if n_pipes == 1 else f"pipe{p}\n{name}"
            rows.append((label, values(u), u["elapsed"]))
    else:
        aggregate = f"mean over the {n_pipes} pipelines of each PM kind"
        kinds = sorted({name for _, name, _ in pms}, key=lambda n: order.get(n, len(order)))
        for kind in kinds:
            us = [u for _, name, u in pms if name == kind]
            vals = [values(u) for u in us]
            mean = {s: sum(v[s] for v in vals) / len(vals) for s in SEGMENTS}
            label = f"{kind}\n(mean of {len(us)})" if len(us) > 1 else f"{kind}\n(pipe0 only)"
            rows.append((label, mean, sum(u["elapsed"] for u in us) / len(us)))
    segments = {s: np.array([v[s] / frames for _, v, _ in rows], dtype=float) for s in SEGMENTS}
    return Breakdown([r[0] for r in rows], segments, np.array([r[2] / frames for r in rows], dtype=float), frames,
                     _throughput(run), aggregate)


def breakdown_figure(run: Run, out: Path, name: str | FigureName, ceiling: float | None = None):
    """The eq. 5.1 breakdown of ``run``; ``ceiling``: the most cycles of the runs it is compared with (runs of
    one scene-mode, :mod:`tlm.report.compare`), drawn on that one scale, said so."""
    bd = breakdown(run)
    if not bd.labels:
        return None
    top = float(bd.elapsed.max()) if bd.elapsed.size else 0.0
    top = max(top, ceiling) if ceiling is not None else top
    scale, unit = cycles_unit(top)
    fig = new_figure(max(6.5, 1.0 * len(bd.labels) + 4.0), 4.8)
    ax = fig.subplots()
    x = np.arange(len(bd.labels))
    bottom = np.zeros(len(bd.labels))
    empty = []
    for s in SEGMENTS:
        v = bd.segments[s] / scale
        if not v.any():
            empty.append(s)
            continue
        c, h = style(s)
        ax.bar(x, v, 0.6, bottom=bottom, color=c, hatch=h, edgecolor="black", linewidth=0.6, label=SEGMENT_LABELS[s])
        bottom += v
    if bd.throughput:
        ax.axhline(bd.throughput / scale, color="black", linestyle="--", linewidth=1.0,
                   label=f"TThru (frame period): {sig(bd.throughput / scale)}")
    ax.set_xticks(x, bd.labels, fontsize=8)
    ax.set_ylim(0, 1.06 * max(top, bd.throughput) / scale or 1.0)
    ax.set(xlabel="Processing Module", ylabel=f"{unit} per frame")
    _title(ax, f"{run.label}: eq. 5.1 breakdown per PM", run)
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    caption = (f"Cycles per frame (totals over {bd.frames} simulated frames / {bd.frames}); each bar reaches the "
               f"PM's elapsed time, T_ds split by stall cause. ")
    caption += (f"Bars: {bd.aggregate}." if bd.aggregate else "Bars: every PM of every pipeline.")
    if empty:
        caption += f" No cycles (not drawn): {', '.join(SEGMENT_LABELS[s] for s in empty)}."
    caption += fifo_caption(run.results["timing"].get("fifo"))
    if ceiling is not None:
        caption += " On one y scale with the other runs of its scene-mode (compared in the summary)."
    return save(fig, out, name, f"{run.title}: where the cycles go (eq. 5.1)", _point(run) + caption)


def fifo_caption(fifo: dict | None) -> str:
    """The FIFOs' peak occupancy (results.json ``timing.fifo``) as a sentence of the breakdown's
    caption; "" for a run without it (one written before it was recorded)."""
    if not fifo:
        return ""
    waited = fifo["waited"]
    return (f" Traversal-to-Intersection FIFOs: none held more than {fifo_held(fifo)} at once; {waited} "
            f"put{'s' if waited != 1 else ''} waited for room (timing.fifo).")


def _title(ax, title: str, run: Run) -> None:
    """The axes' title: ``title``, and under it a sweep point's factor values (which point)."""
    if run.factors:
        ax.set_title(f"{title}\n{textwrap.fill(run.factors_text, 90, expand_tabs=False)}", fontsize=10)
    else:
        ax.set_title(title)


def _point(run: Run) -> str:
    """The caption's first words for a sweep point: which point of which sweep it is."""
    return f"Sweep point {run.label}: {run.factors_text}. " if run.factors else ""


# -- (b) the timeline ------------------------------------------------------------------------

@dataclass
class Gantt:
    """Merged spans per (unit, state) of a trace: ``spans[(unit, state)] = (starts, ends)`` in cycles."""

    rows: list[str]  # units, display order
    spans: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]
    end: int
    clock_hz: float | None
    slices: int  # slices in the trace (before merging)
    unknown: list[str] = field(default_factory=list)  # slice names this module does not know

    def total(self, unit: str, state: str) -> int:
        got = self.spans.get((unit, state))
        return 0 if got is None else int((got[1] - got[0]).sum())

    def rects(self) -> int:
        return sum(s.shape[0] for s, _ in self.spans.values())


def state_of(name: str) -> str | None:
    """A trace slice's state (None: not a state of its own)."""
    if name in ("busy", "page misses", "idle", "preempted") or name.startswith("stall: "):
        return name
    if name.startswith("copy"):
        return "block copy"
    return None


def _row_order(unit: str) -> tuple:
    m = _UNIT.match(unit)
    if m:
        name = m.group(2)
        return (0, int(m.group(1)), PMS.index(name) if name in PMS else len(PMS), name)
    m = re.match(r"^mem(\d+)$", unit)
    if m:
        return (1, int(m.group(1)), 0, "")
    return (2 if unit == "compose" else 3 if unit == "xbar" else 4, 0, 0, unit)


def merge(starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sort spans and merge those that touch or overlap."""
    if starts.size == 0:
        return starts, ends
    o = np.argsort(starts, kind="stable")
    s, e = starts[o], ends[o]
    reach = np.maximum.accumulate(e)
    new = np.ones(s.shape[0], dtype=bool)
    new[1:] = s[1:] > reach[:-1]
    first = np.flatnonzero(new)
    last = np.r_[first[1:] - 1, s.shape[0] - 1]
    return s[first], reach[last]


def gantt(trace_path: Path) -> Gantt:
    """Read ``trace.json``: every unit's spans per state, adjacent slices merged.

    Rows ``<unit> (preempted)`` (when a PM holds a job it switched away from) become the
    state ``preempted`` of the unit; their idle filler is not a state of the unit and
    is dropped. Slices of a name this module does not know keep their name as state.
    """
    doc = json.loads(Path(trace_path).read_text(encoding="utf-8"))
    events = doc["traceEvents"] if isinstance(doc, dict) else doc
    names: dict[int, str] = {}
    for ev in events:
        if ev.get("ph") == "M" and ev.get("name") == "thread_name":
            names[ev["tid"]] = ev["args"]["name"]
    raw: dict[tuple[str, str], list[tuple[int, int]]] = defaultdict(list)
    unknown: set[str] = set()
    end, n = 0, 0
    for ev in events:
        if ev.get("ph") != "X":
            continue
        n += 1
        scope = names.get(ev["tid"], f"tid {ev['tid']}")
        a = ev.get("args") or {}
        if "start_cycle" in a and "cycles" in a:  # exact cycles (timestamps are microseconds)
            s, d = int(a["start_cycle"]), int(a["cycles"])
        else:  # a trace written before timestamps were microseconds: they are cycles
            s, d = int(ev["ts"]), int(ev["dur"])
        end = max(end, s + d)
        name = ev["name"]
        if scope.endswith(" (preempted)"):
            if name != "preempted":
                continue  # the row's idle filler
            scope = scope[: -len(" (preempted)")]
        state = state_of(name)
        if state is None:
            unknown.add(name)
            state = name
        raw[(scope, state)].append((s, s + d))
    spans = {}
    for key, pairs in raw.items():
        a = np.array(pairs, dtype=np.int64)
        spans[key] = merge(a[:, 0], a[:, 1])
    rows = sorted({u for u, _ in spans}, key=_row_order)
    clock = (doc.get("otherData") or {}).get("clock_hz") if isinstance(doc, dict) else None
    return Gantt(rows, spans, end, clock, n, sorted(unknown))


def _coverage(starts: np.ndarray, ends: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Cycles of the (sorted, disjoint) spans inside each bin between ``edges``."""
    dur = ends - starts
    before = np.r_[0, np.cumsum(dur)]
    i = np.searchsorted(starts, edges, side="right") - 1
    inside = np.where(i >= 0, np.clip(edges - starts[np.maximum(i, 0)], 0, dur[np.maximum(i, 0)]), 0)
    cum = before[np.maximum(i, 0)] * (i >= 0) + inside
    return np.diff(cum.astype(float))


def _runs_of(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and one-past-last index of each run of True in ``mask``."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def pixel_spans(g: Gantt, bins: int = BINS) -> dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]:
    """The spans at pixel resolution: each of ``bins`` columns of a row shows one state,
    the one other than idle that fills most of it (idle only when nothing else happens
    there), so that short activity stays visible.

    The preempted band is kept where a column is at least half preempted.
    """
    edges = np.linspace(0, g.end, bins + 1)
    out: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]] = {}
    for unit in g.rows:
        states = [s for (u, s) in g.spans if u == unit and s != "preempted"]
        if states:
            cov = np.stack([_coverage(*g.spans[(unit, s)], edges) for s in states])
            busy = np.where([s != "idle" for s in states], 1.0, 0.0)[:, None]
            top = np.argmax(cov * (1.0 + busy * 1e12), axis=0)  # any activity beats idle
            has = cov.sum(axis=0) > 0
            for k, s in enumerate(states):
                a, b = _runs_of((top == k) & has)
                if a.size:
                    out[(unit, s)] = (edges[a], edges[b])
        if (unit, "preempted") in g.spans:
            cov = _coverage(*g.spans[(unit, "preempted")], edges)
            a, b = _runs_of(cov >= 0.5 * np.diff(edges))
            if a.size:
                out[(unit, "preempted")] = (edges[a], edges[b])
    return out


def _rects(xs: list[np.ndarray], ws: list[np.ndarray], ys: list[float], hs: list[float]) -> MplPath:
    """Rectangles (x, y, width, height) as one compound path; ``xs[i]``, ``ws[i]`` share ``ys[i]``, ``hs[i]``."""
    x = np.concatenate(xs)
    w = np.concatenate(ws)
    y = np.concatenate([np.full(len(a), v, dtype=float) for a, v in zip(xs, ys, strict=True)])
    h = np.concatenate([np.full(len(a), v, dtype=float) for a, v in zip(xs, hs, strict=True)])
    v = np.empty((x.shape[0], 5, 2))
    v[:, 0, 0], v[:, 0, 1] = x, y
    v[:, 1, 0], v[:, 1, 1] = x + w, y
    v[:, 2, 0], v[:, 2, 1] = x + w, y + h
    v[:, 3, 0], v[:, 3, 1] = x, y + h
    v[:, 4] = v[:, 0]
    codes = np.tile(np.array([MplPath.MOVETO, MplPath.LINETO, MplPath.LINETO, MplPath.LINETO, MplPath.CLOSEPOLY],
                             dtype=MplPath.code_type), x.shape[0])
    return MplPath(v.reshape(-1, 2), codes)


def _gantt_rows(run: Run, g: Gantt) -> tuple[list[str], str | None]:
    """The rows drawn, and a note when some were left out (too many pipelines)."""
    if len(g.rows) <= MAX_GANTT_ROWS:
        return g.rows, None
    pipes = sorted({int(m.group(1)) for u in g.rows if (m := _UNIT.match(u))})
    keep_p = {pipes[0], pipes[-1]}
    per = 2 * int((run.results["timing"].get("images_in_flight")) or 2)
    keep = []
    for u in g.rows:
        m = _UNIT.match(u)
        mm = re.match(r"^mem(\d+)$", u)
        if m:
            ok = int(m.group(1)) in keep_p
        elif mm:
            ok = int(mm.group(1)) // per in keep_p
        else:
            ok = True
        if ok:
            keep.append(u)
    return keep, (f"{run.label}: the timeline shows pipelines {pipes[0]} and {pipes[-1]} of {len(pipes)} "
                  f"(their PMs and memory modules) and the shared units; {len(g.rows) - len(keep)} other units "
                  f"are left out to keep the rows readable.")


# a timeline's time unit: the largest of these its stream lasts at least one of (at 600 MHz, ms or µs; at 1 Hz,
# days or years: no "ms" with an offset of x1e10 on the axis), and its clock's: the largest the clock is one of
TIME_UNITS = (("years", 365.25 * 86400), ("days", 86400.0), ("h", 3600.0), ("min", 60.0), ("s", 1.0), ("ms", 1e-3),
              ("µs", 1e-6), ("ns", 1e-9), ("ps", 1e-12))  # (ps: a cycle at arch.clock_hz's 1e12 is 1 ps, not 0.001 ns)
CLOCK_UNITS = (("THz", 1e12), ("GHz", 1e9), ("MHz", 1e6), ("kHz", 1e3), ("Hz", 1.0))


def time_axis(end_cycles: float, clock_hz: float) -> tuple[float, str]:
    """The factor from cycles to a timeline's time unit and its axis label, both chosen by the clock
    ``clock_hz`` and the stream's ``end_cycles``: ``time (ms at 600 MHz)``, ``time (days at 1 Hz)``."""
    secs = end_cycles / clock_hz
    unit, size = next(((u, v) for u, v in TIME_UNITS if secs >= v), TIME_UNITS[-1])
    hz_unit, hz = next(((u, v) for u, v in CLOCK_UNITS if clock_hz >= v), CLOCK_UNITS[-1])
    return 1.0 / (clock_hz * size), f"time ({unit} at {clock_hz / hz:g} {hz_unit})"


def cycles_unit(top: float) -> tuple[float, str]:
    """The scale and name of a cycle count axis up to ``top``: millions past 1e6, thousands past 1e4."""
    return (1e6, "million cycles") if top >= 1e6 else (1e3, "thousand cycles") if top >= 1e4 else (1.0, "cycles")


def gantt_figure(run: Run, out: Path, name: str | FigureName, notes: list[str]):
    g = gantt(run.trace)
    if not g.rows or g.end <= 0:
        notes.append(f"{run.label}: trace.json has no slices; no timeline.")
        return None
    rows, note = _gantt_rows(run, g)
    if note:
        notes.append(note)
    if g.unknown:
        notes.append(f"{run.label}: slices of unknown kind drawn as states of their own: {', '.join(g.unknown)}.")
    coarse = g.rects() > MAX_RECTS
    spans = pixel_spans(g) if coarse else g.spans
    clock = g.clock_hz
    if clock:
        k, xlabel = time_axis(g.end, clock)
    else:
        k, xlabel = 1.0, "time (cycles)"
    fig = new_figure(11, 1.6 + 0.3 * len(rows))
    ax = fig.subplots()
    min_w = g.end * k / MIN_WIDTH_PX  # a short span is drawn one pixel wide
    index = {u: i for i, u in enumerate(rows)}
    by_state: dict[str, list[tuple]] = defaultdict(list)
    for (unit, state), (s, e) in spans.items():
        if unit in index and s.size:
            y = len(rows) - 1 - index[unit]
            w = (e - s) * k
            w = w if state == "idle" else np.maximum(w, min_w)
            by_state[state].append((s * k, w, *((y - 0.42, 0.2) if state == "preempted" else (y - 0.2, 0.6))))
    present = set(by_state)
    for state, parts in by_state.items():
        # one compound path per state: hatching and drawing cost per path, not per span
        c, h = style(state)
        pre = state == "preempted"
        ax.add_artist(PathPatch(_rects([p[0] for p in parts], [p[1] for p in parts], [p[2] for p in parts],
                                       [p[3] for p in parts]),
                                facecolor=c, hatch=h, edgecolor="#444444" if pre else "black",
                                linewidth=0.4 if pre else 0, zorder=3 if pre else 1 if state == "idle" else 2))
    frame_times = run.results["timing"].get("frame_times") or []
    for f in frame_times:
        ax.axvline(f["done"] * k, color="black", linestyle=":", linewidth=0.8, zorder=4)
    ax.set_yticks(range(len(rows)), list(reversed(rows)), fontsize=7)
    ax.set_ylim(-0.6, len(rows) - 0.4)
    ax.set_xlim(0, g.end * k)
    ax.set(xlabel=xlabel)
    _title(ax, f"{run.label}: busy, stalled and idle over time", run)
    if clock:
        per, unit = cycles_unit(g.end)
        top = ax.secondary_xaxis("top", functions=(lambda t: t / k / per, lambda c: c * per * k))
        top.set_xlabel(unit, fontsize=8)
    order = [s for s in (*STATES, "preempted") if s in present] + sorted(present - set(STATES) - {"preempted"})
    handles = []
    for s in order:
        c, h = style(s)
        handles.append(Patch(facecolor=c, hatch=h, edgecolor="black", linewidth=0.5, label=STATE_LABELS.get(s, s)))
    if frame_times:
        handles.append(ax.plot([], [], color="black", linestyle=":", linewidth=0.8, label="a frame is done")[0])
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    caption = (f"From trace.json ({whole(g.slices)} slices over {whole(g.end)} cycles, {len(frame_times) or 'the'} "
               f"simulated frames); adjacent slices of one state merged; a span shorter than a pixel is drawn one "
               f"pixel wide.")
    if coarse:
        caption += (f" {whole(g.rects())} spans are more than the picture can show: each of {BINS} columns of a row "
                    f"shows the state other than idle that fills most of it (idle only where nothing else "
                    f"happens).")
    return save(fig, out, name, f"{run.title}: timeline of every unit", _point(run) + caption)


# -- the section -----------------------------------------------------------------------------

def _ceilings(runs: list[Run], inputs: Inputs) -> dict[int, float]:
    """The runs drawn of each scene-mode run more than once (:func:`tlm.report.compare.groups`): each run's (by
    its ``id``) one ceiling, the most cycles of any of them, so that their breakdowns share one y scale."""
    out: dict[int, float] = {}
    drawn = {id(r) for r in runs}
    for g in groups(inputs):
        tops = []
        for r in (r for r in g if id(r) in drawn):
            try:
                bd = breakdown(r)
            except (KeyError, TypeError, ValueError):  # (its figure's note says why)
                continue
            if bd.labels:
                tops.append((id(r), max(float(bd.elapsed.max()), bd.throughput)))
        if len(tops) > 1:
            out.update({i: max(t for _, t in tops) for i, _ in tops})
    return out


def cycles_section(inputs: Inputs, out: Path) -> Section:
    sec = Section("cycles", "Where the cycles go")
    if not inputs.runs:
        cases = inputs.unread_cases()
        sec.absent = ("no run, thesis or sweep folder among the inputs" + (f"; {cases}" if cases else
                                                                           " (nothing was simulated)"))
        return sec
    runs, notes = select_runs(inputs)
    sec.notes.extend(notes)
    if not runs:
        sec.absent = "none of the runs has timing results"
        return sec
    ceilings = _ceilings(runs, inputs)
    for i, run in enumerate(runs):
        slug = ("cycles", f"{i:02d}", run.label)  # (cycles_00_<label>_breakdown.png)
        try:
            fig = breakdown_figure(run, out, FigureName((*slug, "breakdown"), "\n".join((*slug, "breakdown"))),
                                   ceilings.get(id(run)))
        except (KeyError, TypeError, ValueError) as e:
            sec.notes.append(f"{run.label}: its timing results lack the eq. 5.1 terms ({type(e).__name__}: {e}); "
                             f"no breakdown.")
            fig = None
        else:
            if fig is None:
                sec.notes.append(f"{run.label}: no Processing Module in its timing results; no breakdown.")
        if fig is not None:
            sec.figures.append(fig)
        if run.trace is None:
            traced = ((run.config or {}).get("arch") or {}).get("trace")
            why = ("arch.trace was false; a sweep's points trace only where it sets arch.trace: true"
                   if traced is False else
                   "the run wrote one, and it is gone from the folder" if traced else "none was written")
            other = kept(run, "trace.json")  # (one there that a rerun kept from an earlier output: not read)
            sec.notes.append(f"{run.label}: no trace.json {f'of its own{other}' if other else f'({why})'}, so no "
                             "timeline.")
            continue
        try:
            fig = gantt_figure(run, out, FigureName((*slug, "timeline"), "\n".join((*slug, "timeline"))), sec.notes)
        except (OSError, KeyError, TypeError, ValueError) as e:
            sec.notes.append(f"{run.label}: trace.json cannot be read ({type(e).__name__}: {e}); no timeline.")
            fig = None
        if fig is not None:
            sec.figures.append(fig)
    return sec
