"""Report section: our simulated frame rates beside the figures the thesis quotes (§V.B).

The thesis compares its architecture with SaarCOR (Schmittler et al. [5]: 7.52-28.88
fps with one ray tracing core), GPU stream ray casting (Purcell et al., cited there by no number:
1.8-10.5 fps) and photon mapping on a GPU (Purcell et al. [16]: 8.1 s per frame for the ring
scene, 64.3 s for the Cornell Box), and gives its own FPS row in Tables I-III. The
peers rendered other scenes, at other resolutions, on other (real or simulated)
hardware: the comparison is of orders of magnitude only, and the figure says so.
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from tlm.config import MODES
from tlm.experiments.thesis import THESIS
from tlm.report.collect import Inputs, Run
from tlm.report.common import Section, bar_style, colour, marker, new_figure, save
from tlm.report.tables import SCENE_TITLE, TABLE_NUMBER

MODE_TITLE = {"rcast": "RCast", "reflect": "Reflect", "refract": "Refract", "pmap": "PMap"}
MAX_OURS_ROWS = 12
MODE_STYLE = (0, 1, 2, 4)  # common's colour/marker index per mode (skips the pale yellow: hollow markers)


def _mode_colour(i: int) -> str:
    return colour(MODE_STYLE[i])


def _mode_marker(i: int) -> str:
    return marker(MODE_STYLE[i])


def _offset(i: int) -> float:
    """Vertical offset of mode ``i``'s markers in a row, so that equal values stay visible."""
    return (i - 1.5) * 0.1


@dataclass(frozen=True)
class Peer:
    name: str
    source: str
    rendered: str
    quoted: str
    low_fps: float
    high_fps: float


# As quoted in the thesis, §V.B "Results and System Performance" (references as numbered there; the stream
# ray casting figures are "Purcell et al's commodity GPU based stream ray tracing studies", with no number: the
# thesis's [14] (SIGGRAPH 2002) and [17] (Purcell's 2004 dissertation) are both such studies, so neither is named).
PEERS = (
    Peer("SaarCOR, one RTC", "Schmittler, Wald and Slusallek, Graphics Hardware 2002 [5]",
         "ray tracing on a fixed-function ray tracing core (simulated hardware)", "7.52 fps to 28.88 fps", 7.52, 28.88),
    Peer("GPU stream ray casting", "Purcell et al.'s GPU stream ray tracing studies (no reference given)",
         "simple ray-casting images without indirect illumination on a commodity GPU", "1.8 fps to 10.5 fps",
         1.8, 10.5),
    Peer("GPU photon mapping, ring", "Purcell et al., Graphics Hardware 2003 [16]",
         "photon mapping without accelerated ray tracing, ring scene", "8.1 s per frame", 1 / 8.1, 1 / 8.1),
    Peer("GPU photon mapping, Cornell Box", "Purcell et al., Graphics Hardware 2003 [16]",
         "photon mapping without accelerated ray tracing, Cornell Box similar to Fig. 17", "64.3 s per frame",
         1 / 64.3, 1 / 64.3),
)
THESIS_SOURCE = "Ling 2004, Tables I–III (simulated, 600 MHz, one pipeline)"
THESIS_SIZES = {"ring": "320×240, 20,000 photons", "room": "320×240, 80,000 photons",
                "cornell": "320×320, 120,000 photons"}


def _thesis_row(table: str) -> str:
    """The thesis's own frame rates of one of its tables, named by the table, not by a scene
    name of ours (its room is our ``thesis/room``, not the built-in ``room``)."""
    return f"thesis, Table {TABLE_NUMBER[table]}: {SCENE_TITLE[table]}"


@dataclass
class OursRow:
    label: str
    scene: str
    name: str = ""  # the row's label on the chart
    resolutions: list[str] = field(default_factory=list)
    fps: dict[str, list[float]] = field(default_factory=dict)  # mode -> simulated FPS values

    def add(self, run: Run) -> None:
        res = run.results["scene"].get("resolution")
        text = f"{res[0]}×{res[1]}" if res else "?"
        if text not in self.resolutions:
            self.resolutions.append(text)
        self.fps.setdefault(run.mode, []).append(float(run.results["fps"]))


def ours_rows(inputs: Inputs, notes: list[str]) -> list[OursRow]:
    """One row per (source, scene): a thesis study, a sweep or a single run."""
    owner: dict[Path, str] = {}
    for study in inputs.of_kind("thesis"):
        root = study.path.resolve()
        for r in inputs.runs:
            if r.kind == "thesis" and r.path.resolve().parent.parent == root:
                owner[r.path.resolve()] = f"study {study.path.name}"
    for sweep in inputs.sweeps:
        for r in sweep.runs:
            owner[r.path.resolve()] = f"sweep {sweep.label}"
    rows: dict[tuple[str, str], OursRow] = {}
    for run in inputs.runs:
        if run.results.get("fps") is None:
            notes.append(f"{run.label}: no simulated FPS in results.json, left out")
            continue
        src = owner.get(run.path.resolve(), run.label)
        key = (src, run.scene_label)  # (the scene by its file: the built-in room is not thesis/room)
        if key not in rows:
            label = f"ours: {src}"
            rows[key] = OursRow(label, run.scene_label, label if src == run.label else f"{label}, {run.scene_label}")
        rows[key].add(run)
    return list(rows.values())


def _fps_text(values: list[float]) -> str:
    if len(values) == 1:
        return f"{values[0]:.3g}"
    low, high = f"{min(values):.3g}", f"{max(values):.3g}"  # (runs of one frame rate: it is said once)
    return f"{low if low == high else f'{low}–{high}'} ({len(values)} runs)"


def _reciprocal(x):
    with np.errstate(divide="ignore"):
        return 1.0 / np.asarray(x, dtype=float)


def _chart(rows: list[OursRow], out: Path):
    labels: list[str] = []
    fig = new_figure(9.0, 2.2 + 0.36 * (len(PEERS) + len(THESIS) + len(rows)))
    ax = fig.add_subplot()
    y = 0
    values: list[float] = []
    for k, p in enumerate(PEERS):
        if p.high_fps > p.low_fps:
            ax.barh(y, p.high_fps - p.low_fps, left=p.low_fps, height=0.55, **bar_style(k + 1))
            ax.annotate(f"{p.low_fps:g}", (p.low_fps, y), xytext=(-3, 0), textcoords="offset points",
                        ha="right", va="center", fontsize=7)
            ax.annotate(f"{p.high_fps:g} fps", (p.high_fps, y), xytext=(3, 0), textcoords="offset points",
                        ha="left", va="center", fontsize=7)
        else:
            ax.plot([p.low_fps], [y], marker="X", color="black", markersize=8, linestyle="none")
            ax.annotate(p.quoted, (p.low_fps, y), xytext=(6, 0), textcoords="offset points", ha="left",
                        va="center", fontsize=7)
        values += [p.low_fps, p.high_fps]
        labels.append(p.name)
        y += 1
    ax.axhline(y - 0.5, color="#999", linewidth=0.6)
    for scene, table in THESIS.items():
        fps = table["FPS"]
        ax.barh(y, max(fps) - min(fps), left=min(fps), height=0.35, color="#dddddd", edgecolor="#777",
                linewidth=0.5)
        for i in range(len(MODES)):
            ax.plot([fps[i]], [y + _offset(i)], marker=_mode_marker(i), markersize=7, linestyle="none",
                    markerfacecolor="white", markeredgecolor=_mode_colour(i), markeredgewidth=1.4)
        values += list(fps)
        labels.append(f"{_thesis_row(scene)} ({THESIS_SIZES[scene].split(',')[0]})")
        y += 1
    ax.axhline(y - 0.5, color="#999", linewidth=0.6)
    for row in rows:
        for i, mode in enumerate(MODES):
            v = row.fps.get(mode, [])
            if v:
                ax.plot(v, [y + _offset(i)] * len(v), marker=_mode_marker(i), markersize=6, linestyle="none",
                        color=_mode_colour(i), markeredgecolor="black", markeredgewidth=0.5, alpha=0.9)
                values += v
        labels.append(f"{row.name} ({', '.join(row.resolutions)})")
        y += 1
    ax.set_yticks(range(len(labels)), labels=labels, fontsize=7.5)
    ax.set_ylim(len(labels) - 0.5, -0.7)
    ax.set_xscale("log")
    lo, hi = min(values), max(values)
    ax.set_xlim(lo / 3.0, hi * 6.0)
    ax.set_xlabel("frames per second (log scale)")
    sec = ax.secondary_xaxis("top", functions=(_reciprocal, _reciprocal))
    sec.set_xlabel("seconds per frame", fontsize=8)
    sec.tick_params(labelsize=7)
    ax.grid(axis="x", which="major", linewidth=0.4, color="#bbb")
    handles = [Line2D([], [], marker=_mode_marker(i), linestyle="none", color=_mode_colour(i), markeredgecolor="black",
                      label=MODE_TITLE[m]) for i, m in enumerate(MODES)]
    handles += [Line2D([], [], marker="o", linestyle="none", markerfacecolor="white", markeredgecolor="black",
                       label="hollow: thesis (Tables I–III)"),
                Line2D([], [], marker="o", linestyle="none", color="#888", markeredgecolor="black",
                       label="filled: ours (simulated)"),
                Patch(facecolor="white", edgecolor="black", hatch="///", label="range quoted by the thesis"),
                Line2D([], [], marker="X", linestyle="none", color="black", label="single figure quoted")]
    fig.legend(handles=handles, loc="outside lower center", ncol=4, fontsize=7, frameon=False)
    fig.suptitle("Frame rate: ours beside the thesis and the peers it quotes", fontsize=11)
    caption = ("Peers rendered other scenes at other resolutions on other hardware (figures as quoted in the "
               "thesis, §V.B); ours are simulated at the resolution shown. An order-of-magnitude comparison only.")
    return save(fig, out, "peers.png", "Frame rate against the peers the thesis quotes", caption)


def _html(rows: list[OursRow]) -> str:
    e = html.escape
    out = ['<table class="peers-table">',
           "<caption>Frame rates: the peers as quoted by the thesis (§V.B), the thesis's own FPS row, and ours. "
           "Peers rendered other scenes at other resolutions on other hardware: compare orders of magnitude only."
           "</caption>",
           "<thead><tr><th>system</th><th>source</th><th>what was rendered</th><th>figure quoted</th>"
           "<th>frames per second</th></tr></thead><tbody>"]
    for p in PEERS:
        fps = f"{p.low_fps:.3g}" if p.low_fps == p.high_fps else f"{p.low_fps:.4g}–{p.high_fps:.4g}"
        out.append(f'<tr class="peer"><td>{e(p.name)}</td><td>{e(p.source)}</td><td>{e(p.rendered)}</td>'
                   f"<td>{e(p.quoted)}</td><td>{e(fps)}</td></tr>")
    for scene, table in THESIS.items():
        fps = ", ".join(f"{MODE_TITLE[m]} {v:g}" for m, v in zip(MODES, table["FPS"]))
        what = f"the thesis's {SCENE_TITLE[scene]}, {THESIS_SIZES[scene]}"
        out.append(f'<tr class="thesis"><td>{e(_thesis_row(scene))}</td><td>{e(THESIS_SOURCE)}</td>'
                   f"<td>{e(what)}</td><td>FPS row</td><td>{e(fps)}</td></tr>")
    for row in rows:
        fps = ", ".join(f"{MODE_TITLE[m]} {_fps_text(row.fps[m])}" for m in MODES if m in row.fps)
        out.append(f'<tr class="ours"><td>{e(row.label)}</td><td>this simulation (results.json fps)</td>'
                   f"<td>{e(f'{row.scene} scene, ' + ', '.join(row.resolutions) + ' pixels')}</td><td>–</td>"
                   f"<td>{e(fps)}</td></tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


def peers_section(inputs: Inputs, out: Path) -> Section:
    """Our simulated FPS beside SaarCOR, GPU ray casting, GPU photon mapping and the thesis."""
    out = Path(out)
    section = Section("peers", "Peers: frame rates beside the figures the thesis quotes")
    rows = ours_rows(inputs, section.notes)
    if not rows:
        section.absent = "no run among the inputs has a simulated frame rate (results.json fps)"
        return section
    if len(rows) > MAX_OURS_ROWS:
        rest = rows[MAX_OURS_ROWS:]
        section.notes.append(f"{len(rest)} rows of ours left out of the figure and table (at most {MAX_OURS_ROWS}): "
                             + "; ".join(f"{r.label}, {r.scene}" for r in rest))
        rows = rows[:MAX_OURS_ROWS]
    section.figures.append(_chart(rows, out))
    section.html = _html(rows)
    return section
