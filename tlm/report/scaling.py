"""Section 3: scaling in the style of the thesis's Figs. 18-20.

Simulated frame latency and throughput against the number of pipelines N, beside
eq. 5.2 (and its slowest-pipeline variant), for the static and the dynamic scheduler,
and the speed-up TThru(1) / TThru(N). The fits come from ``tlm scaling`` folders
(``eq52.json`` and ``eq52.csv``) and from every sweep given to the report that varies
``arch.pipelines`` (fitted here with :mod:`tlm.experiments.scaling`).
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

from matplotlib.ticker import NullLocator

from tlm.errors import InputError
from tlm.experiments import scaling as eq52
from tlm.report.collect import Inputs
from tlm.report.common import Figure, Section, colour, marker, new_figure

TITLES = {"latency": "frame latency (eq. 5.2's T_tot)", "throughput": "throughput TThru"}


def plot_scaling(scene: str, fits: dict[tuple, dict], path: Path, source: str = "") -> None:
    """Three panels: latency and throughput against N (simulated, eq. 5.2, slowest-pipeline
    variant), and the speed-up; one colour and marker per scheduler."""
    fig = new_figure(15, 4.6)
    axes = fig.subplots(1, 3)
    scheds = sorted({k[2] for k in fits}, key=lambda s: (s != "static", s))
    for (_, mode, sched, target), f in sorted(fits.items()):
        i = scheds.index(sched)
        c, m = colour(2 * i), marker(i)
        ns = [r["pipelines"] for r in f["rows"]]
        ax = axes[0 if target == "latency" else 1]
        ax.plot(ns, [r["simulated"] for r in f["rows"]], color=c, marker=m, linestyle="-",
                label=f"{sched} ({mode}): simulated")
        ax.plot(ns, [r["analytical"] for r in f["rows"]], color=c, linestyle="--",
                label=f"{sched}: eq. 5.2, A={f['A']:.3g}, B={f['B']:.3g}, max err {f['max_abs_rel_error']:.1%}")
        if "analytical_slowest" in f["rows"][0]:
            s = f["slowest"]
            ax.plot(ns, [r["analytical_slowest"] for r in f["rows"]], color=c, linestyle=":",
                    label=f"{sched}: slowest pipeline, A={s['A']:.3g}, B={s['B']:.3g}, "
                          f"max err {s['max_abs_rel_error']:.1%}")
        if target == "throughput":
            axes[2].plot(ns, [r["speedup"] for r in f["rows"]], color=c, marker=m, linestyle="-",
                         label=f"{sched} ({mode})")
    where = f" [{source}]" if source else ""
    for ax, target in zip(axes[:2], ("latency", "throughput"), strict=True):
        ax.set(xscale="log", yscale="log", xlabel="pipelines N", ylabel="cycles per frame",
               title=f"{scene}: {TITLES[target]}{where}")
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
    ns = sorted({r["pipelines"] for f in fits.values() for r in f["rows"]})
    axes[2].plot(ns, ns, color="grey", linestyle=(0, (1, 2)), label="linear (ideal)")
    axes[2].set(xscale="log", yscale="log", xlabel="pipelines N", ylabel="speed-up TThru(1) / TThru(N)",
                title=f"{scene}: speed-up{where}")
    axes[2].legend(fontsize=7)
    axes[2].grid(True, which="both", alpha=0.3)
    for ax in axes:  # N at its own values, not at powers of ten
        ax.set_xticks(ns, [str(n) for n in ns])
        ax.xaxis.set_minor_locator(NullLocator())
    axes[2].set_yticks(ns, [str(n) for n in ns])
    axes[2].yaxis.set_minor_locator(NullLocator())
    fig.savefig(path, dpi=110)


def _fits_of_study(study) -> dict[tuple, dict]:
    rows = defaultdict(list)
    for r in study.rows:
        rows[(r["scene"], r["mode"], r["scheduler"], r["target"])].append(
            {**r, "pipelines": int(r["pipelines"])})
    fits = {}
    for f in study.meta.get("fits", []):
        key = (f["scene"], f["mode"], f["scheduler"], f["target"])
        if key in rows:
            fits[key] = {**f, "rows": sorted(rows[key], key=lambda r: r["pipelines"])}
    return fits


def _fits_of_sweep(sweep, notes: list[str]) -> dict[tuple, dict]:
    records = [eq52.record(r.results, r.config) for r in sweep.runs]  # read once by collect.read
    groups = defaultdict(list)
    for r in records:
        groups[(r["scene"], r["mode"], r["scheduler"])].append(r)
    fits = {}
    for key, pts in sorted(groups.items()):
        for target in eq52.TARGETS:
            try:
                fits[(*key, target)] = eq52.fit_both(pts, target)
            except InputError as e:
                notes.append(f"{sweep.path.name}: {'/'.join(key)} {target} not fitted: {e}")
    return fits


def scaling_section(inputs: Inputs, out: Path) -> Section:
    sec = Section("scaling", "Scaling with N pipelines: simulated against eq. 5.2, static against dynamic")
    sources: list[tuple[str, dict]] = [(s.path.name, _fits_of_study(s)) for s in inputs.of_kind("scaling")]
    for sw in inputs.sweeps:
        if "arch.pipelines" not in (sw.spec.get("grid") or {}) and "arch.pipelines" not in (sw.spec.get("zip") or {}):
            continue
        if not sw.runs:
            sec.notes.append(f"{sw.path.name}: no finished point")
            continue
        sources.append((sw.path.name, _fits_of_sweep(sw, sec.notes)))
    for name, fits in sources:
        for scene in sorted({k[0] for k in fits}):
            mine = {k: v for k, v in fits.items() if k[0] == scene}
            file = f"scaling_{name}_{scene}.png"
            plot_scaling(scene, mine, out / file, name)
            worst = ", ".join(f"{k[2]} {k[3]} {v['max_abs_rel_error']:.1%}" for k, v in sorted(mine.items()))
            sec.figures.append(Figure(file, f"{scene}: scaling from {name}",
                                             "Solid: simulated; dashed: eq. 5.2 fitted exactly at N = 1 and by "
                                             "least squares elsewhere; dotted: the slowest-pipeline variant. "
                                             f"Largest |error| of eq. 5.2: {worst}."))
    if not sec.figures:
        sec.absent = ("no 'tlm scaling' folder and no sweep over arch.pipelines among the inputs "
                      "(e.g. 'tlm sweep configs/scaling_ring.yaml')")
    return sec

