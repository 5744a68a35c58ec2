"""Section: what each sweep varied and what it did to the frame rate.

Per sweep, a table of its points (factors, status, simulated FPS, TThru, the slowest
PM, host seconds; a failed point with its error) and one figure per varied factor:
the simulated FPS against that factor's values, one line per combination of the other
factors (up to :data:`MAX_SERIES`; more are drawn as their median with the min-max
band, and a note says so).
"""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path
from typing import Any

from tlm.report.collect import Inputs, Sweep
from tlm.report.common import Section, line_style, new_figure, save
from tlm.report.html import esc

MAX_SERIES = 8
MAX_ROWS = 200
PMS = ("vertex", "traversal", "intersection", "fragment")


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def factors_of(sw: Sweep) -> list[str]:
    return [*(sw.spec.get("grid") or {}), *(sw.spec.get("zip") or {})]


def table(sw: Sweep) -> str:
    factors = factors_of(sw)
    head = ["point", *factors, "status", "FPS", "TThru (M cycles)", "slowest PM", "host s"]
    rows = sorted(sw.rows, key=lambda r: r.get("point", 0))
    out = ['<table><tr>' + "".join(f"<th>{esc(h)}</th>" for h in head) + "</tr>"]
    for r in rows[:MAX_ROWS]:
        if r.get("status") == "ok":
            slow = max(PMS, key=lambda p: r.get(f"cycles.{p}") or 0)
            cells = [_fmt(r.get("fps")), f"{(r.get('cycles.throughput') or 0) / 1e6:.4g}", slow,
                     _fmt(round((r.get("seconds.functional") or 0) + (r.get("seconds.simulate") or 0), 3))]
        else:
            cells = [f"failed: {r.get('error')}", "", "", ""]
        vals = [str(r.get("point")), *(_fmt(r.get(f)) for f in factors), str(r.get("status")), *cells]
        out.append("<tr>" + "".join(f"<td>{esc(v)}</td>" for v in vals) + "</tr>")
    out.append("</table>")
    if len(rows) > MAX_ROWS:
        out.append(f'<p class="note">The first {MAX_ROWS} of {len(rows)} points are listed; '
                   f"all are in {esc(sw.path / 'sweep.csv')}.</p>")
    return "\n".join(out)


def _numeric(values: list) -> bool:
    return all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)


def factor_figure(sw: Sweep, factor: str, out: Path, notes: list[str]):
    """FPS against ``factor``; one line per combination of the other factors."""
    ok = [r for r in sw.rows if r.get("status") == "ok" and r.get("fps") is not None]
    others = [f for f in factors_of(sw) if f != factor]
    values = sorted({_key(r.get(factor)) for r in ok}, key=_order)
    if len(values) < 2:
        return None
    numeric = _numeric([r.get(factor) for r in ok])
    series: dict[tuple, dict] = defaultdict(dict)
    for r in ok:
        series[tuple(_key(r.get(f)) for f in others)][_key(r.get(factor))] = r["fps"]
    fig = new_figure(7, 4.5)
    ax = fig.subplots()
    xs_of = (lambda vs: vs) if numeric else (lambda vs: [values.index(v) for v in vs])
    if len(series) <= MAX_SERIES:
        for i, (combo, pts) in enumerate(sorted(series.items(), key=lambda kv: [_order(k) for k in kv[0]])):
            vs = [v for v in values if v in pts]
            label = ", ".join(f"{f.split('.')[-1]}={_fmt(c)}" for f, c in zip(others, combo, strict=True)) or "FPS"
            ax.plot(xs_of(vs), [pts[v] for v in vs], label=label, **line_style(i))
    else:
        med, lo, hi = [], [], []
        for v in values:
            ys = sorted(pts[v] for pts in series.values() if v in pts)
            med.append(ys[len(ys) // 2])
            lo.append(ys[0])
            hi.append(ys[-1])
        ax.fill_between(xs_of(values), lo, hi, color="0.8", hatch="///", edgecolor="0.5",
                        label=f"min-max over {len(series)} combinations of {', '.join(others)}")
        ax.plot(xs_of(values), med, label="median", **line_style(0))
        notes.append(f"{sw.path.name}: FPS against {factor} shows the median and range over {len(series)} "
                     f"combinations of the other factors (more than {MAX_SERIES} lines)")
    if numeric:
        lo_v, hi_v = min(values), max(values)
        if lo_v > 0 and hi_v / lo_v >= 100:
            ax.set_xscale("log")
    else:
        ax.set_xticks(range(len(values)), [_fmt(v) for v in values])
    fps = [r["fps"] for r in ok]
    if min(fps) > 0 and max(fps) / min(fps) >= 100:
        ax.set_yscale("log")
    ax.set(xlabel=factor, ylabel="simulated frames per second (FPS)",
           title=f"{sw.path.name}: simulated FPS against {factor}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    name = f"sweep_{sw.path.name}_{factor.replace('.', '_')}.png"
    return save(fig, out, name, f"{sw.path.name}: FPS against {factor}",
                f"{len(ok)} finished points of {len(sw.rows)}; {sw.spec.get('description') or ''}".strip())


def _key(v):
    return tuple(v) if isinstance(v, list) else v


def _order(v):
    if isinstance(v, bool) or v is None:
        return (0, str(v))
    if isinstance(v, int | float):
        return (1, v if math.isfinite(v) else float("inf"))
    return (2, str(v))


def sweeps_section(inputs: Inputs, out: Path) -> Section:
    sec = Section("sweeps", "Sweeps: the points and the frame rate against each factor")
    html = []
    for sw in inputs.sweeps:
        desc = sw.spec.get("description")
        failed = sum(r.get("status") != "ok" for r in sw.rows)
        html.append(f"<h3>{esc(sw.path.name)}</h3><p>{esc(desc or '')} {len(sw.rows)} points, "
                    f"{failed} failed; sweep file {esc(sw.spec.get('sweep'))}.</p>")
        html.append(table(sw))
        for factor in factors_of(sw):
            fig = factor_figure(sw, factor, out, sec.notes)
            if fig is not None:
                sec.figures.append(fig)
    sec.html = "\n".join(html)
    if not inputs.sweeps:
        sec.absent = "no sweep folder among the inputs"
    return sec
