"""Eq. 5.2 against the simulation: the thesis's multi-pipeline model (Figs. 18-20).

The thesis estimates the time of N duplicated pipelines as

    T_tot(N) ~ A * T_vert0 + sum_i B * max(T_t,i, T_r,i, T_f,i) / N          (5.2)

with A and B constants "such that, if N = 1, T_tot = acquired simulation time".
:func:`fit` reads the simulated points of a scaling sweep (``tlm sweep`` over
``arch.pipelines``), takes T_vert0 (the one Vertex PM's cycles per frame) and each
pipeline's Traversal, Intersection and Fragment cycles per frame from every point,
and fits A and B per (scene, mode, scheduler) and per target: the frame latency (the
"total time" of one frame, arrival to image) and the throughput (TThru, cycles per
frame in the stream). The fit is exact at N = 1, as the thesis asks, and least squares
over the other N. Eq. 5.2 divides the sum over the pipelines by N: it assumes tiles of
equal work. Beside it, the *slowest-pipeline* variant puts N times the slowest
pipeline's max(T_t, T_r, T_f) in the sum (its own A and B), which is what a static
tiling of an uneven image waits for. :func:`analyse` writes ``eq52.csv`` (per point:
simulated and analytical cycles of both, relative errors), ``eq52.json`` (A, B, the
largest error, per group), ``provenance.json`` and one figure per scene
(``scaling_<scene>.png``): simulated and analytical T_tot against N, and the speed-up
T(1) / T(N), for each scheduler.
"""

from __future__ import annotations

import json
import os
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

import yaml

from tlm.errors import InputError
from tlm.experiments.study import run_study
from tlm.storage import check_destination, read_jsonl

TARGETS = ("latency", "throughput")
COLUMNS = ("scene", "mode", "scheduler", "pipelines", "target", "simulated", "analytical", "rel_error",
           "analytical_slowest", "rel_error_slowest", "T_vert0", "sum_max_per_N", "speedup")


def collect(sweep_dir: Path, notes: list[str] | None = None) -> list[dict]:
    """One record per finished point of the sweep in ``sweep_dir`` (each names the folder).

    A last row cut off while written (a killed sweep) is left out; any other row that is
    not JSON, or a finished point whose folder is gone, is an InputError. Rows of points
    its ``sweep.yaml`` does not list (an earlier sweep's, left by a rerun cut short) are
    left out; a sweep with points that have no row yet (interrupted, or still running) is
    fitted from those it has, and ``notes`` gets a line saying so.
    """
    sweep_dir = Path(sweep_dir)
    rows_path = sweep_dir / "sweep.jsonl"
    if not rows_path.is_file():
        raise InputError("is not a sweep folder (no sweep.jsonl): run 'tlm sweep' first", source=str(sweep_dir))
    try:
        spec = yaml.safe_load((sweep_dir / "sweep.yaml").read_text()) or {}
    except (OSError, ValueError, yaml.YAMLError):
        spec = {}
    planned = {str(p.get("hash")) for p in (spec.get("points") if isinstance(spec, dict) else None) or []
               if isinstance(p, dict)}
    rows = [(n, row) for n, row in read_jsonl(rows_path, " (the file is corrupt: rerun 'tlm sweep' into this folder)")
            if not planned or str(row.get("hash")) in planned]
    if planned and notes is not None and len({str(r.get("hash")) for _, r in rows}) < len(planned):
        done = len({str(r.get("hash")) for _, r in rows})
        notes.append(f"{sweep_dir}: {done} of its {len(planned)} points have a row (the sweep was interrupted or "
                     "is still running; the same 'tlm sweep' command finishes it): fitted from those")
    records = []
    for n, row in rows:
        if row.get("status") != "ok":
            continue
        folder = sweep_dir / "points" / str(row.get("hash"))
        try:
            res = json.loads((folder / "results.json").read_text())
            cfg = yaml.safe_load((folder / "config.resolved.yaml").read_text())
        except FileNotFoundError as e:
            raise InputError(f"point {row.get('point')}: {e.filename} is missing (rerun 'tlm sweep' into this "
                             "folder to compute the point again)", source=str(rows_path), key=f"line {n}") from None
        except (OSError, ValueError, yaml.YAMLError) as e:
            raise InputError(f"point {row.get('point')}: cannot read its folder ({e})", source=str(rows_path),
                             key=f"line {n}") from None
        records.append({**record(res, cfg), "sweep": str(sweep_dir)})
    if not records:
        raise InputError("has no finished point", source=str(rows_path))
    return records


def record(res: dict, cfg: dict) -> dict:
    """What eq. 5.2 needs of one point: its ``results.json`` and resolved config."""
    per_pipe = res["timing"]["pipelines"]
    return {
        "scene": str(res["scene"]["name"]), "mode": cfg["mode"], "scheduler": cfg["arch"]["scheduler"],
        "pipelines": int(cfg["arch"]["pipelines"]),
        "T_vert0": int(res["cycles"]["vertex"]),
        "sum_max": sum(max(p["traversal"], p["intersection"], p["fragment"]) for p in per_pipe),
        "max_max": max(max(p["traversal"], p["intersection"], p["fragment"]) for p in per_pipe),
        "latency": int(res["cycles"]["latency"]), "throughput": int(res["cycles"]["throughput"]),
    }


def fit_group(points: list[dict], target: str, slowest: bool = False, source: str | None = None) -> dict:
    """A and B of eq. 5.2 for one group, exact at N = 1 and least squares elsewhere.

    ``slowest``: the variant with the slowest pipeline's max(T_t, T_r, T_f) in place of
    the mean over the pipelines (eq. 5.2 assumes tiles of equal work). ``source``: where
    the points come from (the sweep folders), for the errors' messages.
    """
    points = [{**p, "sum_max": p["max_max"] * p["pipelines"]} for p in points] if slowest else points
    by_n = {p["pipelines"]: p for p in points}
    if len(by_n) != len(points):
        ns = sorted(p["pipelines"] for p in points)
        raise InputError(f"two points of one scene, mode and scheduler have the same N ({ns}): they differ in "
                         "another key, so fit them from separate sweeps", source=source, key="arch.pipelines")
    if len(by_n) < 2:
        raise InputError(f"eq. 5.2 needs at least two values of N, the group has {sorted(by_n)}",
                         source=source, key="arch.pipelines")
    if 1 not in by_n:
        raise InputError(f"eq. 5.2 is fitted through N = 1, and the group has N = {sorted(by_n)}",
                         source=source, key="arch.pipelines")
    one = by_n[1]
    t1, v, m1 = one[target], one["T_vert0"], one["sum_max"]
    # T(N) - T(1) = B * (M(N) - M(1)), M(N) = sum_i max(...) / N; then A from N = 1
    xs = [(p["sum_max"] / n - m1, p[target] - t1) for n, p in by_n.items() if n != 1]
    den = sum(x * x for x, _ in xs)
    b = sum(x * y for x, y in xs) / den if den > 0 else 1.0
    a = (t1 - b * m1) / v if v else 0.0
    rows = []
    for n in sorted(by_n):
        p = by_n[n]
        model = a * v + b * p["sum_max"] / n
        rows.append({"pipelines": n, "simulated": p[target], "analytical": round(model),
                     "rel_error": round((model - p[target]) / p[target], 6) if p[target] else 0.0,
                     "T_vert0": v, "sum_max_per_N": round(p["sum_max"] / n), "speedup": round(t1 / p[target], 4)})
    worst = max(abs(r["rel_error"]) for r in rows)
    return {"A": a, "B": b, "max_abs_rel_error": worst, "rows": rows}


def fit_both(points: list[dict], target: str, source: str | None = None) -> dict:
    """Eq. 5.2 as the thesis writes it, with the slowest-pipeline variant beside it."""
    f = fit_group(points, target, source=source)
    g = fit_group(points, target, slowest=True, source=source)
    for r, q in zip(f["rows"], g["rows"]):
        r["analytical_slowest"] = q["analytical"]
        r["rel_error_slowest"] = q["rel_error"]
    f["slowest"] = {"A": g["A"], "B": g["B"], "max_abs_rel_error": g["max_abs_rel_error"]}
    return f


def fit(records: list[dict]) -> dict[tuple, dict]:
    """Eq. 5.2 per (scene, mode, scheduler) and target; an error names the group's sweep folders."""
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in records:
        groups[(r["scene"], r["mode"], r["scheduler"])].append(r)
    fits = {}
    for key, pts in sorted(groups.items()):
        sweeps = sorted({r["sweep"] for r in pts if r.get("sweep")})
        source = f"{', '.join(sweeps)} ({'/'.join(key)})" if sweeps else None
        for target in TARGETS:
            fits[(*key, target)] = fit_both(pts, target, source)
    return fits


def analyse(sweep_dirs: list[Path], out: Path, plot: Callable[[str, dict, Path], None] | None = None) -> dict:
    """Fit eq. 5.2 over the points of ``sweep_dirs``; write the table, the fits and, given
    ``plot`` (:func:`tlm.report.scaling.plot_scaling`, passed down by the CLI), a figure per
    scene as ``scaling_<scene>.png``."""
    check_destination(out, "eq52.json")
    notes: list[str] = []
    records = [r for d in sweep_dirs for r in collect(d, notes)]
    fits = fit(records)
    table, summary = [], []
    for (scene, mode, sched, target), f in fits.items():
        summary.append({"scene": scene, "mode": mode, "scheduler": sched, "target": target, "A": f["A"],
                        "B": f["B"], "max_abs_rel_error": f["max_abs_rel_error"], "slowest": f["slowest"],
                        "pipelines": [r["pipelines"] for r in f["rows"]]})
        table.extend({"scene": scene, "mode": mode, "scheduler": sched, "target": target, **r} for r in f["rows"])

    def figures(_point, tmp: Path) -> list[dict]:
        for scene in sorted({k[0] for k in fits} if plot else ()):
            plot(scene, {k: v for k, v in fits.items() if k[0] == scene}, tmp / f"scaling_{scene}.png")
        return table

    # the sweeps it was fitted from (relative to this folder), for the report's idle fractions per PM
    sweeps = [os.path.relpath(Path(d).resolve(), Path(out).resolve()) for d in sweep_dirs]
    run_study(", ".join(str(d) for d in sweep_dirs), out, "eq52", [None], figures, columns=COLUMNS,
              marker="eq52.json", files=lambda _rows: {"eq52.json": {"fits": summary, "sweeps": sweeps,
                                                                    "notes": notes}})
    return {"fits": summary, "rows": table, "notes": notes}
