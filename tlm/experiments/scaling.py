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
over the other N. In this model the latency is no second measurement: the stream is a closed
loop (a frame arrives when the one ``arch.images_in_flight`` before it is done), so by Little's
law the latency is images in flight x TThru: to the cycle (or the one rounding leaves) in every case
checked with the static tiles at the default 5 frames (with frames done in order, the one steady
frame's latency spans the window TThru is measured over), with one image, and with the dynamic
scheduler's two images, whose stream runs on past ``arch.frames`` until its completions repeat
(:mod:`tlm.arch.steady`: TThru and the latency over whole periods); within 0.2% where such a stream
does not settle within its 64 frames (``throughput_estimate.settled`` false: means over the later
half of its steady completions); not where the stream is too short for a steady state
(``throughput_steady`` false). Where every point of a group has it (:func:`latency_multiple`), the
latency fit's A and B are the throughput fit's times that multiple, with the same errors:
its ``latency_multiple`` says so (None where it does not hold), and ``tlm scaling`` and the
report say the latency fit is the throughput fit scaled. Eq. 5.2 divides the sum over the
pipelines by N: it assumes tiles of equal work. Beside it, the *slowest-pipeline* variant puts N times the slowest
pipeline's max(T_t, T_r, T_f) in the sum (its own A and B), which is what a static
tiling of an uneven image waits for.

A group's scene is the scene *file* its points rendered, judged by the file's bytes (and
those of the files its ``extends:`` chain names, and of the mesh files its geometry reads),
as :func:`tlm.experiments.thesis.table_of` judges a thesis scene (:func:`scene_identity`):
two copies of one file (and of its meshes) are one scene, two
files that share a ``name`` (a modified copy of ``cornell.yaml``, the built-in ``ring``
beside ``thesis/ring``) are two groups. Every group's scene is named as the report names it,
whatever else is fitted beside it (:func:`scene_name`): a built-in one by its name under
``scenes/`` (``thesis/ring``, never ``ring``), any other by the path its config gave, an absolute one
short (:func:`short_scene_path`: ``myroom.yaml``) (:func:`groups`). The points of one group must differ in N alone: a
group whose points' resolved configs differ in any other key (a sweep that zips
``arch.pipelines`` with ``arch.page_miss_cycles``, or two sweeps of different bases) is
refused, naming the key, since the fit would read that key's effect as the pipelines'
(the keys that leave the cycles as they are, :data:`NO_EFFECT`, may differ). A sweep that
crosses N with other factors is fitted once per combination of their values that has two
values of N (:func:`parts`: a fit's ``group``, ``bsp.levels = 15, cache.pairs = 4``), but for
the factors of :data:`NO_EFFECT`, which split nothing: the points of one N that differ in them
alone are fitted as one (:func:`one_per_n`; a note where their cycles disagree). Failed
points are left out, each named in the notes; so is a point whose stream was too short
for a steady state (``throughput_steady`` false: its TThru includes the fill and drain),
which is fitted all the same. :func:`analyse` writes ``eq52.csv`` (per point:
simulated and analytical cycles of both, relative errors), ``eq52.json`` (A, B, the
largest error, per group; ``tested`` false and ``why`` where a fit tests nothing, :func:`flat_why`: every point
Vertex-bound at every N, h488; a ``why`` with ``tested`` true where B alone is not determined, h493;
``vertex_bound``, the N whose TThru is T_vert0; ``fitted_from``: per sweep
folder, the hashes of the points its ``sweep.yaml`` listed and of those fitted, which :func:`out_of_date` compares with
the folder as it is later), ``provenance.json`` and one figure per scene
(``scaling_<scene>.png``, :func:`figure_files`: two scenes whose names give one file name get
two files): simulated and analytical T_tot against N, and the speed-up
T(1) / T(N), for each scheduler.
"""

from __future__ import annotations

import json
import os
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

import yaml

from tlm.config_words import safe_load  # (yaml.safe_load, its aliases bounded)
from tlm.errors import InputError, values_text
from tlm.experiments.provenance import identities_remembered, scene_identity, scene_label
from tlm.experiments.scaling_dated import (  # noqa: F401  (moved; the old names)
    SWEEP_READ,
    entry_out_of_date,
    flat_why,
    out_of_date,
    sweep_points,
    untested_notes,
    vertex_bound,
)
from tlm.experiments.study import run_study
from tlm.experiments.sweep_rows import one_row_each
from tlm.storage import check_destination, distinct_folders, read_jsonl

TARGETS = ("latency", "throughput")
# the keys of a point's resolved config that eq. 5.2's groups may differ in: the groups' own
# keys and N, and the keys that by their definition ('tlm params') leave the cycles as they
# are (a cap on events, the trace, the clock that turns cycles into FPS, the kernels' threads
# and batches, the photon-map reference)
GROUP_KEYS = frozenset({"scene", "mode", "arch.scheduler", "arch.pipelines"})
NO_EFFECT = frozenset({"arch.max_events", "arch.trace", "arch.clock_hz", "render.threads", "render.batch",
                       "render.batch_rays", "render.exposure"})
NO_EFFECT_PREFIXES = ("reference.",)
COLUMNS = ("scene", "mode", "scheduler", "pipelines", "target", "simulated", "analytical", "rel_error",
           "analytical_slowest", "rel_error_slowest", "T_vert0", "sum_max_per_N", "speedup")


def collect(sweep_dir: Path, notes: list[str] | None = None, failed: list[str] | None = None) -> list[dict]:
    """One record per finished point of the sweep in ``sweep_dir`` (each names the folder).

    A last row cut off while written (a killed sweep) is left out; any other row that is
    not JSON, or a finished point whose folder is gone, is an InputError. Rows of points
    its ``sweep.yaml`` does not list (an earlier sweep's, left by a rerun cut short) are
    left out; a sweep with points that have no row yet (interrupted, or still running) is
    fitted from those it has, and ``notes`` gets a line saying so. A point that failed
    (``status`` not ok) is left out, and ``notes`` gets a line naming it; ``failed`` (a list)
    gets ``point P (its factors)`` of each. A point whose stream had no steady state
    (:func:`unsteady`) is kept, and ``notes`` gets a line naming it.
    """
    sweep_dir = Path(sweep_dir)
    rows_path = sweep_dir / "sweep.jsonl"
    if not sweep_dir.exists():
        raise InputError("no such folder: name a 'tlm sweep' output folder (runs/scaling_ring)", source=str(sweep_dir))
    if not rows_path.is_file():
        raise InputError("is not a sweep folder (no sweep.jsonl): run 'tlm sweep' first", source=str(sweep_dir))
    try:
        spec = safe_load((sweep_dir / "sweep.yaml").read_text(encoding="utf-8")) or {}
    except (OSError, ValueError, yaml.YAMLError):
        spec = {}
    points = [p for p in (spec.get("points") if isinstance(spec, dict) else None) or [] if isinstance(p, dict)]
    planned = {str(p.get("hash")) for p in points}
    factors = {str(p.get("hash")): p.get("factors") for p in points}
    rows = [(n, row) for n, row in read_jsonl(rows_path, " (the file is corrupt: rerun 'tlm sweep' into this folder)")
            if not planned or str(row.get("hash")) in planned]
    rows = one_row_each(rows, lambda t: t[1])  # (a point's later row in place of its earlier: two runs killed)
    if planned and notes is not None and len({str(r.get("hash")) for _, r in rows}) < len(planned):
        done = len({str(r.get("hash")) for _, r in rows})
        notes.append(f"{sweep_dir}: {done} of its {len(planned)} points have a row (the sweep was interrupted or "
                     "is still running; the same 'tlm sweep' command finishes it): fitted from those")
    records = []
    for n, row in rows:
        if row.get("status") != "ok":
            what = f"point {row.get('point')} ({_factors_text(factors.get(str(row.get('hash'))), row)})"
            if notes is not None:
                notes.append(f"{sweep_dir}: {what} failed ({_short(row.get('error'))}): left out of the fit")
            if failed is not None:
                failed.append(f"{sweep_dir}: {what}")
            continue
        folder = sweep_dir / "points" / str(row.get("hash"))
        try:
            res = json.loads((folder / "results.json").read_text(encoding="utf-8"))
            cfg = safe_load((folder / "config.resolved.yaml").read_text(encoding="utf-8"))
        except FileNotFoundError as e:
            raise InputError(f"point {row.get('point')}: {e.filename} is missing (rerun 'tlm sweep' into this "
                             "folder to compute the point again)", source=str(rows_path), key=f"line {n}") from None
        except (OSError, ValueError, yaml.YAMLError) as e:
            raise InputError(f"point {row.get('point')}: cannot read its folder ({e})", source=str(rows_path),
                             key=f"line {n}") from None
        fac = factors.get(str(row.get("hash")))
        rec = {**record(res, cfg), "sweep": str(sweep_dir), "hash": str(row.get("hash")),
               "factors": fac if isinstance(fac, dict) else {}}
        records.append(rec)
        if notes is not None and rec["steady"] is False:
            notes.append(f"{sweep_dir}: point {row.get('point')} "
                         f"({_factors_text(factors.get(str(row.get('hash'))), row)}): {unsteady(rec)}")
    if not records:
        raise InputError("has no finished point", source=str(rows_path))
    return records


def unsteady(rec: dict) -> str:
    """The note on a point (a :func:`record`) whose stream was too short for a steady state, or did
    not settle (its completions did not repeat within the frames it ran)."""
    if rec.get("settled") is False:
        return (f"its stream did not settle within {rec.get('frames')} frames (throughput_steady false): its TThru "
                f"is the mean gap over the later half of its steady completions and its latency the mean over "
                f"{_latency_frames(rec)}, not over whole periods (raise arch.settle_frames above {rec.get('frames')})")
    need = f"; a steady window needs at least {rec['min_frames']} frames" if rec.get("min_frames") else ""
    frames = f"of {rec['frames']} frames " if rec.get("frames") else ""
    return (f"its stream {frames}was too short for a steady state (throughput_steady false{need}): its TThru and "
            "latency are measured over the whole stream, fill and drain included, and the fit reads them as the "
            "steady state's (raise arch.frames)")


def _latency_frames(rec: dict) -> str:
    """The frames an unsettled stream's latency is the mean over (:func:`tlm.arch.steady.steady_throughput`):
    those that arrived in the window of its later half of steady completions and were done before the drain,
    or where none was (a short stream: 5 frames of two images), those that arrived after the warm-up."""
    f, k = rec.get("frames"), rec.get("in_flight")
    if not (isinstance(f, int) and isinstance(k, int) and k >= 1):
        return ("the frames that arrived in that window (after the warm-up where none of those was done before "
                "the drain)")
    gaps = f - 2 * k + 1  # (the steady gaps; the window starts at completion k - 1 + gaps // 2)
    if gaps - (k - 1 + gaps // 2) > 0:
        return "the frames that arrived in that window"
    return "the frames that arrived after the warm-up (none that arrived in that window was done before the drain)"


def _factors_text(factors, row: dict) -> str:
    """A failed point's factors (``arch.pipelines = 8, arch.max_events = 20``), from ``sweep.yaml``
    where it lists them, else its N from the row."""
    if isinstance(factors, dict) and factors:
        return ", ".join(f"{k} = {v}" for k, v in factors.items())
    return f"N = {row['arch.pipelines']}" if "arch.pipelines" in row else "factors unknown"


def _short(error, limit: int = 120) -> str:
    """A failed point's error on one short line."""
    text = " ".join(str(error).split()) if error else "no error recorded"
    return text if len(text) <= limit else text[:limit - 4].rsplit(" ", 1)[0] + " ..."


def settings(cfg: dict) -> dict[str, str]:
    """The keys of a resolved config that must be equal across one group's points (every key
    but :data:`GROUP_KEYS` and :data:`NO_EFFECT`), dotted, each with its value as JSON text."""
    flat: dict[str, str] = {}

    def walk(node, prefix: str) -> None:
        for k, v in node.items():
            key = f"{prefix}{k}"
            if isinstance(v, dict) and v:
                walk(v, f"{key}.")
            elif key not in GROUP_KEYS and not no_effect(key):
                flat[key] = json.dumps(v, sort_keys=True, default=str)

    walk(cfg if isinstance(cfg, dict) else {}, "")
    return flat


def no_effect(key: str) -> bool:
    """Whether a dotted config key leaves the cycles as they are (:data:`NO_EFFECT`, or a key
    under one of :data:`NO_EFFECT_PREFIXES`, or such a prefix's section itself)."""
    return key in NO_EFFECT or any(key.startswith(p) or key == p.rstrip(".") for p in NO_EFFECT_PREFIXES)


def record(res: dict, cfg: dict) -> dict:
    """What eq. 5.2 needs of one point: its ``results.json`` and resolved config."""
    per_pipe = res["timing"]["pipelines"]
    source = res["scene"].get("source")
    estimate = res["timing"].get("throughput_estimate") or {}
    return {
        "settings": settings(cfg),
        "scene": str(res["scene"]["name"]), "scene_file": source, "scene_id": scene_identity(source),
        "scene_ref": cfg.get("scene") if isinstance(cfg.get("scene"), str) else None,
        "steady": estimate.get("steady"), "frames": estimate.get("frames"), "min_frames": estimate.get("min_frames"),
        "settled": estimate.get("settled"),
        "mode": cfg["mode"], "scheduler": cfg["arch"]["scheduler"],
        "pipelines": int(cfg["arch"]["pipelines"]),
        "T_vert0": int(res["cycles"]["vertex"]),
        "sum_max": sum(max(p["traversal"], p["intersection"], p["fragment"]) for p in per_pipe),
        "max_max": max(max(p["traversal"], p["intersection"], p["fragment"]) for p in per_pipe),
        "latency": int(res["cycles"]["latency"]), "throughput": int(res["cycles"]["throughput"]),
        "in_flight": cfg["arch"].get("images_in_flight"),
    }


def fit_key(scene: str, mode: str, scheduler: str, target: str, group: str = "") -> tuple:
    """A fit's key: (scene, mode, scheduler, target), and the combination of the other factors
    (:func:`parts`) where a group is fitted per combination."""
    return (scene, mode, scheduler, target, group) if group else (scene, mode, scheduler, target)


def key_group(key: tuple) -> str:
    """The combination of the other factors of a :func:`fit_key` ("" for a group fitted whole)."""
    return str(key[4]) if len(key) > 4 else ""


def _shown(text: str) -> str:
    """A setting's value (JSON text, :func:`settings`) as a label shows it: ``null``, ``15``, ``a``."""
    try:
        v = json.loads(text)
    except ValueError:
        return text
    return v if isinstance(v, str) else json.dumps(v)


def combination_text(values: dict) -> str:
    """A combination of factor values as :func:`parts` labels it: ``bsp.levels = null, cache.pairs = 4``."""
    return ", ".join(f"{k} = {_shown(json.dumps(v, sort_keys=True, default=str))}" for k, v in values.items())


def parts(points: list[dict], where: str = "", notes: list[str] | None = None) -> list[tuple[str, list[dict]]]:
    """The points of one (scene, mode, scheduler) group, split by their sweeps' other factors.

    A sweep that crosses ``arch.pipelines`` with other factors (a grid of N and ``bsp.levels``,
    or N beside a zip of ``bsp.levels`` and ``cache.pairs``) is fitted once per combination of
    the other factors' values, each a curve labelled ``bsp.levels = 15, cache.pairs = 4``: the
    factors (a point's ``factors``, its sweep's) whose values differ among the points, each
    value as the point's resolved config holds it (so that two sweeps of one base, one of them
    over another factor too, agree where the values do). A combination with one value of N is
    left out, ``notes`` saying so, where another has two; where none has (a zip of N with
    another factor: one N per combination) or no other factor varies, the group is one part,
    ``("", points)``, fitted (or refused, :func:`fit_group`) whole, as before. A factor that leaves
    the cycles as they are (:func:`no_effect`: ``arch.trace``, ``render.threads``) splits nothing:
    the points it tells apart are one point each, :func:`one_per_n`."""
    keys: list[str] = []
    for p in points:  # (a factor that leaves the cycles as they are, arch.trace, splits nothing: one_per_n)
        keys.extend(k for k in p.get("factors") or {} if k not in GROUP_KEYS and not no_effect(k) and k not in keys)

    def value(p: dict, k: str) -> str:
        text = (p.get("settings") or {}).get(k)
        if text is None:
            f = p.get("factors") or {}
            text = json.dumps(f[k], sort_keys=True, default=str) if k in f else "(not set)"
        return text

    keys = [k for k in keys if len({value(p, k) for p in points}) > 1]
    if not keys:
        return [("", one_per_n(points, where, notes))]
    split: dict[tuple, list[dict]] = {}
    for p in points:
        split.setdefault(tuple(value(p, k) for k in keys), []).append(p)
    labelled = [(", ".join(f"{k} = {_shown(v)}" for k, v in zip(keys, vals, strict=True)), pts)
                for vals, pts in split.items()]
    ok = [(label, pts) for label, pts in labelled if len({p["pipelines"] for p in pts}) >= 2]
    if not ok:
        return [("", one_per_n(points, where, notes))]
    if notes is not None:
        for label, pts in labelled:
            if len({p["pipelines"] for p in pts}) < 2:
                notes.append(f"{where + ': ' if where else ''}{label}: not fitted: one value of N only "
                             f"(N = {values_text(sorted({p['pipelines'] for p in pts}))}); eq. 5.2 needs two")
    return [(label, one_per_n(pts, f"{where + ': ' if where else ''}{label}", notes)) for label, pts in ok]


CYCLES = ("latency", "throughput", "T_vert0", "sum_max", "max_max")  # (what fit_group reads of a point)


def one_per_n(points: list[dict], where: str = "", notes: list[str] | None = None) -> list[dict]:
    """``points`` with one point per N where several of an N differ in nothing but the keys that leave
    the cycles as they are (:func:`no_effect`: a sweep crossing N with ``arch.trace``): their resolved
    configs' :func:`settings` equal, they are one point of eq. 5.2 run twice, and the first (in the
    sweeps' order) is kept. Where their cycles disagree all the same, ``notes`` gets a line naming the
    values and the point kept. Points of an N that differ in another key, or that have no ``settings``
    (records made by hand), are all kept: :func:`fit_group` refuses them, naming the key."""
    by_n: dict[int, list[dict]] = defaultdict(list)
    for p in points:
        by_n[p["pipelines"]].append(p)
    if all(len(same) == 1 for same in by_n.values()):
        return points
    out = []
    for p in points:
        same = by_n[p["pipelines"]]
        if len(same) == 1 or any("settings" not in q for q in same) or differing(same):
            out.append(p)
        elif p is same[0]:
            out.append(p)
            if notes is not None and len({tuple(q.get(k) for k in CYCLES) for q in same}) > 1:
                notes.append(f"{where + ': ' if where else ''}N = {p['pipelines']}: {len(same)} points differ only "
                             f"in keys that leave the cycles as they are ({_no_effect_text(same)}), yet their "
                             f"cycles disagree ({_cycles_text(same)}): fitted from the first "
                             f"({_point_text(p)}); rerun them to tell which is right")
    return out


def _no_effect_text(points: list[dict]) -> str:
    """The factors of ``points`` whose values differ (``arch.trace = false, true``); else that their
    factors are equal (two sweeps of one base and N)."""
    keys = sorted({k for p in points for k in p.get("factors") or {}})
    shown = []
    for k in keys:
        vals = []
        for p in points:
            v = _shown(json.dumps((p.get("factors") or {}).get(k), sort_keys=True, default=str))
            if v not in vals:
                vals.append(v)
        if len(vals) > 1:
            shown.append(f"{k} = {', '.join(vals)}")
    return "; ".join(shown) or "the same factors, from " + ", ".join(sorted({str(p.get('sweep')) for p in points}))


def _cycles_text(points: list[dict]) -> str:
    """``latency = 100, 120; throughput = 50, 60``: the cycles in which ``points`` disagree."""
    return "; ".join(f"{k} = {', '.join(str(p.get(k)) for p in points)}" for k in CYCLES
                     if len({p.get(k) for p in points}) > 1)


def _point_text(p: dict) -> str:
    """A point as a note names it: its factors, and its sweep folder where it has one."""
    fac = combination_text(p.get("factors") or {}) or f"N = {p['pipelines']}"
    return f"{fac}, {p['sweep']}" if p.get("sweep") else fac


def fit_group(points: list[dict], target: str, slowest: bool = False, source: str | None = None) -> dict:
    """A and B of eq. 5.2 for one group, exact at N = 1 and least squares elsewhere.

    ``slowest``: the variant with the slowest pipeline's max(T_t, T_r, T_f) in place of
    the mean over the pipelines (eq. 5.2 assumes tiles of equal work). ``source``: where
    the points come from (the sweep folders), for the errors' messages.
    """
    points = [{**p, "sum_max": p["max_max"] * p["pipelines"]} for p in points] if slowest else points
    by_n = {p["pipelines"]: p for p in points}
    other = differing(points)
    if len(by_n) == 1 and len(points) > 1:  # (no second sweep can pair with these: N is what does not vary)
        n, differ = points[0]["pipelines"], f" (they differ in {', '.join(other)})" if other else ""
        # (a sweep over arch.pipelines, its factor: its points of the other values of N failed or have not run yet)
        why = (f"the sweep has one value of N ({n}), and eq. 5.2 needs a sweep over arch.pipelines"
               if not any("arch.pipelines" in (p.get("factors") or {}) for p in points) else
               "no point of another value of N has finished (the sweep has no other, or those points failed or "
               "have not run yet: the same 'tlm sweep' command finishes an interrupted sweep), and eq. 5.2 needs "
               "finished points")
        raise InputError(f"the {len(points)} points of one scene, mode and scheduler all have N = {n}{differ}: "
                         f"{why} (N = 1 and another value; its other factors are fitted per combination)",
                         source=source, key="arch.pipelines")
    if len(by_n) != len(points):
        ns = sorted(p["pipelines"] for p in points)
        why = f"in {describe_differing(other, points)}" if other else "in another key"
        raise InputError(f"two points of one scene, mode and scheduler have the same N (N = {values_text(ns)}): "
                         f"they differ {why}, "
                         "so fit them from separate sweeps", source=source, key="arch.pipelines")
    if other:
        raise InputError(f"the points of one scene, mode and scheduler differ in more than N "
                         f"({describe_differing(other, points)}): eq. 5.2 would read the effect of "
                         f"{'that key' if len(other) == 1 else 'those keys'} as the pipelines'; fit points that "
                         f"differ in arch.pipelines alone (a sweep per value of {', '.join(other)})",
                         source=source, key=", ".join(other))
    if len(by_n) < 2:
        raise InputError(f"eq. 5.2 needs at least two values of N, the group has N = {values_text(sorted(by_n))}",
                         source=source, key="arch.pipelines")
    if 1 not in by_n:
        raise InputError(f"eq. 5.2 is fitted through N = 1, and the group has N = {values_text(sorted(by_n))}",
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
    why = flat_why(by_n, target, [y for _, y in xs], [x for x, _ in xs])
    vertex = [n for n in sorted(by_n) if vertex_bound(by_n[n])]
    # (B undetermined alone, the cycles varying: eq. 5.2 predicts T(1) at every N whatever B, a test, h493)
    tested = why is None or (len(by_n) > 2 and any(y for _, y in xs))
    return {"A": a, "B": b, "max_abs_rel_error": worst, "rows": rows, "tested": tested,
            **({"why": why} if why else {}), **({"vertex_bound": vertex} if vertex else {})}


def differing(points: list[dict]) -> dict[str, list[tuple[int, str]]]:
    """The settings (:func:`settings`) the points do not all share: each key with every
    point's (N, value); empty where a point has no ``settings`` (a record made by hand)."""
    if not points or any("settings" not in p for p in points):
        return {}
    keys = sorted({k for p in points for k in p["settings"]})
    out = {}
    for k in keys:
        values = [(p["pipelines"], p["settings"].get(k, "(not set)")) for p in points]
        if len({v for _, v in values}) > 1:
            out[k] = sorted(values)
    return out


def describe_differing(other: dict[str, list[tuple[int, str]]], points: list[dict], most: int = 6) -> str:
    """``arch.page_miss_cycles = 0 at N = 1, 100 at N = 2``: the keys of :func:`differing`, with
    each value at its N (with the distinct values alone where N repeats)."""
    unique_n = len({p["pipelines"] for p in points}) == len(points)
    parts = []
    for key, values in other.items():
        shown = ([f"{v} at N = {n}" for n, v in values] if unique_n
                 else sorted({v for _, v in values}, key=lambda v: (len(v), v)))
        more = ", ..." if len(shown) > most else ""
        parts.append(f"{key} = {', '.join(shown[:most])}{more}")
    return "; ".join(parts)


def fit_both(points: list[dict], target: str, source: str | None = None) -> dict:
    """Eq. 5.2 as the thesis writes it, with the slowest-pipeline variant beside it."""
    f = fit_group(points, target, source=source)
    g = fit_group(points, target, slowest=True, source=source)
    for r, q in zip(f["rows"], g["rows"]):
        r["analytical_slowest"] = q["analytical"]
        r["rel_error_slowest"] = q["rel_error"]
    f["slowest"] = {"A": g["A"], "B": g["B"], "max_abs_rel_error": g["max_abs_rel_error"], "tested": g["tested"],
                    **({"why": g["why"]} if "why" in g else {})}
    return f


def scene_name(rec: dict, short: bool = True) -> str:
    """The scene of a :func:`record` as the report names it, whatever else is fitted beside it: a
    built-in scene by its name under ``scenes/`` (``thesis/ring``, ``ring``; a file of another
    checkout's ``scenes`` folder too, where it is not here or is the same scene as the built-in one
    here), another by the path its config gave (else its file's), :func:`short_scene_path` (``short``
    false: as given, absolute or not); a record without a file, made by hand, by its ``name``."""
    source = rec.get("scene_file")
    if not source:
        return str(rec["scene"])
    label = scene_label(source)
    if label != str(source):
        return label  # (a built-in file of this installation)
    from tlm.scenes.loader import list_scenes, scenes_dir

    parts = Path(str(source).replace("\\", "/")).parts
    for i in range(len(parts) - 2, -1, -1):
        if parts[i] in ("scenes", "_scenes"):
            tail = Path(*parts[i + 1:]).with_suffix("").as_posix()
            mine = scenes_dir() / f"{tail}.yaml"
            if tail in list_scenes() and (not Path(source).is_file() or rec.get("scene_id") is None
                                          or rec.get("scene_id") == scene_identity(mine)):
                return tail
            break
    ref = rec.get("scene_ref")
    given = ref.strip() if isinstance(ref, str) and ref.strip() else str(source)
    return short_scene_path(given) if short else given


def short_scene_path(path: str) -> str:
    """A scene file that is not built-in, by a short name: a relative path as given; an absolute one (a
    resolved config's, ``/p/work/myroom.yaml``) relative to the current folder where it lies under it, as
    the report names it (``myroom.yaml``), else by its file's name; :func:`groups` tells apart two files
    that one name would stand for."""
    if not os.path.isabs(path):
        return path
    p = Path(os.path.normpath(path))
    for here in dict.fromkeys((Path.cwd(), Path.cwd().resolve())):
        try:
            return p.relative_to(here).as_posix()
        except ValueError:
            continue
    return p.name


def groups(records: list[dict]) -> dict[tuple[str, str, str], list[dict]]:
    """The points of :func:`record` by (scene, mode, scheduler), the scene told by its file
    (:func:`scene_identity`; a record without one, made by hand, by its name) and named by
    :func:`scene_name`, one rule whatever else is fitted; two files that one short name would stand
    for are named by their paths as given (``/x/a/room.yaml``, ``/x/b/room.yaml``), or where those are one
    too, by the name with their digests beside it, so two scenes get two names."""
    def ident(r: dict) -> str:
        return str(r.get("scene_id") or r["scene"])

    labels: dict[tuple[str, str], str] = {}
    for r in records:
        labels.setdefault((r["scene"], ident(r)), scene_name(r))
    taken = defaultdict(list)
    for key, label in labels.items():
        taken[label].append(key)
    full = {}
    for r in records:
        full.setdefault((r["scene"], ident(r)), scene_name(r, short=False))
    for label, keys in taken.items():  # (two files a short name does not tell apart: their paths, else digests)
        if len(keys) > 1:
            long = [full[key] for key in keys]
            for key in keys:
                labels[key] = full[key] if len(set(long)) == len(long) else f"{label} [{key[1]}]"
    out: dict[tuple[str, str, str], list[dict]] = defaultdict(list)
    for r in records:
        out[(labels[r["scene"], ident(r)], r["mode"], r["scheduler"])].append(r)
    return dict(sorted(out.items()))


def latency_multiple(points: list[dict]) -> int | None:
    """The whole number k with latency = k x throughput at every point of ``points`` (to the
    cycle or so that rounding each to whole cycles leaves: ``k / 2 + 1``), k the images in flight
    where a point says it (``in_flight``); None where there is none. In the closed-loop stream
    (:func:`tlm.arch.model.steady_throughput`) it is Little's law: the latency fit is then the
    throughput fit times k, no second test of eq. 5.2."""
    if not points or any(not p.get("throughput") or not p.get("latency") for p in points):
        return None
    k = round(points[0]["latency"] / points[0]["throughput"])
    if k < 1 or any(p.get("in_flight") not in (None, k) for p in points):
        return None
    ok = all(abs(p["latency"] - k * p["throughput"]) <= k / 2 + 1 for p in points)
    return k if ok else None


def fit(records: list[dict], notes: list[str] | None = None) -> dict[tuple, dict]:
    """Eq. 5.2 per (scene, mode, scheduler) (:func:`groups`), per combination of the sweeps' other
    factors (:func:`parts`, each fit's ``group``; ``notes`` gets a line per combination left out)
    and per target, keyed by :func:`fit_key`; an error names the group's sweep folders."""
    fits = {}
    for key, pts in groups(records).items():
        sweeps = sorted({r["sweep"] for r in pts if r.get("sweep")})
        group = "/".join(key) if "/" not in key[0] else f"{key[0]}: {key[1]}/{key[2]}"
        where = f"{', '.join(sweeps)} ({group})" if sweeps else group
        for label, part in parts(pts, where, notes):
            source = (f"{', '.join(sweeps)} ({group}{'; ' + label if label else ''})" if sweeps
                      else label or None)
            for target in TARGETS:
                # (the latency: images in flight x TThru at every point, or None where not: latency_multiple)
                fits[fit_key(*key, target, label)] = {
                    **fit_both(part, target, source), **({"group": label} if label else {}),
                    **({"latency_multiple": latency_multiple(part)} if target == "latency" else {})}
    return fits


def analyse(sweep_dirs: list[Path], out: Path, plot: Callable[[str, dict, Path], None] | None = None) -> dict:
    """Fit eq. 5.2 over the points of ``sweep_dirs``; write the table, the fits and, given
    ``plot`` (:func:`tlm.report.scaling.plot_scaling`, passed down by the CLI), a figure per
    scene as ``scaling_<scene>.png`` (:func:`figure_files`). No folder at all is an InputError, nothing written."""
    if not sweep_dirs:  # (an empty study, with no fit, is no answer)
        raise InputError("no folder given: name the sweep folders to fit (tlm sweep's output folders)", key="sweeps")
    check_destination(out, "eq52.json")
    notes: list[str] = []
    sweep_dirs = distinct_folders(sweep_dirs, notes)
    failed: list[str] = []
    with identities_remembered():  # (every point of a scene names one scene file: digested once, not once a point)
        records = [r for d in sweep_dirs for r in collect(d, notes, failed)]
    try:
        fits = fit(records, notes)
    except InputError as e:
        if not failed:
            raise
        raise InputError(f"{e} (left out, as they failed: {'; '.join(failed)})") from None
    table, summary = [], []
    files = {scene: pts[0].get("scene_file") for (scene, _, _), pts in groups(records).items()}
    for key, f in fits.items():
        scene, mode, sched, target = key[:4]
        group = {"group": key_group(key)} if key_group(key) else {}  # (a combination of the other factors)
        summary.append({"scene": scene, "scene_file": files.get(scene), "mode": mode, "scheduler": sched,
                        "target": target, **group, "A": f["A"], "B": f["B"],
                        "max_abs_rel_error": f["max_abs_rel_error"], "slowest": f["slowest"],
                        **{k: f[k] for k in ("tested", "why", "vertex_bound") if k in f},
                        "pipelines": [r["pipelines"] for r in f["rows"]],
                        **({"latency_multiple": f["latency_multiple"]} if "latency_multiple" in f else {})})
        table.extend({"scene": scene, "mode": mode, "scheduler": sched, "target": target, **r, **group}
                     for r in f["rows"])

    notes.extend(untested_notes(fits))  # (a fit that tests nothing: every point Vertex-bound, h488)

    def figures(_point, tmp: Path) -> list[dict]:
        for scene, file in figure_files({k[0] for k in fits} if plot else ()).items():
            plot(scene, {k: v for k, v in fits.items() if k[0] == scene}, tmp / file)
        return table

    # the sweeps it was fitted from (relative to this folder), for the report's idle fractions per PM,
    # and which of their points (out_of_date: the report says when a sweep holds other points later)
    sweeps = [os.path.relpath(Path(d).resolve(), Path(out).resolve()) for d in sweep_dirs]
    fitted_from = [{"sweep": rel, "planned": sweep_points(d)[0],
                    "points": sorted({r["hash"] for r in records if r["sweep"] == str(d)})}
                   for rel, d in zip(sweeps, sweep_dirs, strict=True)]
    run_study(", ".join(str(d) for d in sweep_dirs), out, "eq52", [None], figures, columns=COLUMNS,
              marker="eq52.json", files=lambda _rows: {"eq52.json": {"fits": summary, "sweeps": sweeps,
                                                                    "fitted_from": fitted_from, "notes": notes}})
    return {"fits": summary, "rows": table, "notes": notes}


def figure_files(scenes) -> dict[str, str]:
    """The figure file of each of ``scenes`` (eq. 5.2's names of its groups' scenes), in their sorted
    order: ``scaling_<scene>.png``, the scene's name as :func:`file_slug` writes it. Where two scenes
    would get one file name (``a b`` and ``a_b``, or on a file system that ignores case ``Room`` and
    ``room``), the later gets ``_`` and 8 hex digits of its name's hash (the rule of the report's figure
    names, :func:`tlm.report.common.figure_name`), so that no figure overwrites another; the same
    scenes get the same names every time."""
    import hashlib

    files: dict[str, str] = {}
    taken: set[str] = set()
    for scene in sorted(scenes):
        stem = f"scaling_{file_slug(scene)}"
        tag = hashlib.sha1(scene.encode("utf-8", "surrogatepass")).hexdigest()[:8]  # (a path of bytes not UTF-8)
        name = next(n for n in (stem, f"{stem}_{tag}", *(f"{stem}_{tag}_{i}" for i in range(2, 1000)))
                    if f"{n}.png".lower() not in taken)
        taken.add(f"{name}.png".lower())
        files[scene] = f"{name}.png"
    return files


def file_slug(text: str) -> str:
    """``text`` (a scene's name, or its file's path) as a part of a file name, in ASCII only (letters,
    digits, ``-``, ``.`` and ``_``), so that it works unquoted in a shell, in a URL and in LaTeX: each
    other ASCII character is ``_`` (``my scene`` is ``my_scene``); a letter with an accent loses it and
    any other character is ``_``, and then the name ends in ``_`` and 8 hex digits of the text's hash, so
    that ``café`` (``cafe_`` and its hash) is not ``cafe``, nor ``cafè``. At most 60 characters."""
    import hashlib
    import unicodedata

    def ascii_of(ch: str) -> str:
        if ch.isascii():
            return ch if ch.isalnum() or ch in "-." else "_"
        folded = unicodedata.normalize("NFKD", ch).encode("ascii", "ignore").decode("ascii")
        return "".join(c for c in folded if c.isalnum()) or "_"

    slug = "".join(map(ascii_of, text)).strip("_.")
    if text.isascii():
        return slug[:60] or "scene"
    tag = hashlib.sha1(text.encode("utf-8", "surrogatepass")).hexdigest()[:8]
    return f"{slug[:60 - 9].rstrip('_.') or 'scene'}_{tag}"
