"""Whether a ``tlm scaling`` fit still shows its sweeps as they are (moved out of
:mod:`tlm.experiments.scaling`, which re-exports these names): the points a sweep lists and has
finished (:func:`sweep_points`, read by :data:`SWEEP_READ`), and the lines on a fit whose sweeps now
hold other points (:func:`out_of_date`, :func:`entry_out_of_date`); and the notes on fits that test nothing
(:func:`untested_notes`) and why a fit tests nothing (:func:`flat_why`)."""

from __future__ import annotations

import os
from collections.abc import Callable
from contextvars import ContextVar
from pathlib import Path
from typing import Any

import yaml

from tlm.config_words import safe_load  # (yaml.safe_load, its aliases bounded)
from tlm.errors import InputError, values_text
from tlm.experiments.sweep_rows import one_row_each
from tlm.storage import read_jsonl

# how sweep_points reads a sweep's sweep.yaml (its data) and sweep.jsonl (its rows); while a report is written, by
# that report's reads, each file once a report (tlm.report.once.reading sets it for the report alone)
SWEEP_READ: ContextVar[Callable[[Path], Any]] = ContextVar("SWEEP_READ", default=lambda path: (
    read_jsonl(path) if path.suffix == ".jsonl" else safe_load(path.read_text(encoding="utf-8"))))


def sweep_points(sweep_dir: Path) -> tuple[list[str], list[str]]:
    """The hashes of the points the sweep in ``sweep_dir`` lists (its ``sweep.yaml``; none
    where it lists none) and of those of them finished (a row ok and a ``results.json``),
    each sorted. A ``sweep.jsonl`` that is not JSON is an InputError. Its files read by :data:`SWEEP_READ`."""
    sweep_dir, read = Path(sweep_dir), SWEEP_READ.get()
    try:
        spec = read(sweep_dir / "sweep.yaml") or {}
    except (OSError, ValueError, yaml.YAMLError):
        spec = {}
    points = (spec.get("points") if isinstance(spec, dict) else None) or []
    planned = sorted({str(p.get("hash")) for p in points if isinstance(p, dict)})
    rows = read(sweep_dir / "sweep.jsonl") if (sweep_dir / "sweep.jsonl").is_file() else []
    rows = one_row_each(rows, lambda t: t[1])  # (a point's later row in place of its earlier: its last run's)
    done = {str(r.get("hash")) for _, r in rows if isinstance(r, dict) and r.get("status") == "ok"
            and (not planned or str(r.get("hash")) in planned)}
    return planned, sorted(h for h in done if (sweep_dir / "points" / h / "results.json").is_file())


def out_of_date(folder: Path, meta: dict) -> list[str]:
    """What a ``tlm scaling`` folder's fit no longer shows: a line per sweep it was fitted
    from (``eq52.json``'s ``fitted_from``) that now lists other points (run again into its
    folder with another base, other factors, other inputs or another tlm) or has finished
    other points than those fitted. A sweep that is gone is left to the caller; a folder of an
    older tlm, which did not record its points, gets a line saying that this cannot be told."""
    fitted = meta.get("fitted_from")
    if fitted is None:
        return (["its eq52.json does not record which points it was fitted from (written by an older tlm): "
                 "whether its sweeps hold other points now cannot be told; run 'tlm scaling' again to know"]
                if meta.get("sweeps") else [])
    return [line for entry in fitted if (line := entry_out_of_date(folder, entry))]


def entry_out_of_date(folder: Path, entry: dict) -> str | None:
    """:func:`out_of_date`'s line on one sweep of a ``tlm scaling`` folder's ``fitted_from`` (``entry``), None
    where the sweep holds the points fitted, and none finished since (its fit shows the sweep as it is), or
    where the sweep is gone (left to the caller)."""
    sweep = Path(os.path.normpath(Path(folder) / entry["sweep"]))  # (relative to the folder; absolute stays)
    if not (sweep / "sweep.jsonl").is_file():
        return None
    try:
        planned, done = sweep_points(sweep)
    except InputError as e:
        return f"whether its sweep {sweep} holds other points now cannot be told ({e})"
    then_planned, then_done = set(entry.get("planned") or []), set(entry.get("points") or [])
    rerun = "run 'tlm scaling' again to fit the sweep as it is"
    if planned and then_planned and set(planned) != then_planned:
        new = len(set(planned) - then_planned)
        return (f"out of date: its sweep {sweep} now holds other points than it was fitted from ({new} of "
                f"its {len(planned)} points are new: the sweep was run again with another base, other "
                f"factors, other inputs or another tlm); this fit is of the earlier points, not of those "
                f"the sweep holds now; {rerun}")
    if set(done) != then_done:
        more, less = len(set(done) - then_done), len(then_done - set(done))
        what = "; ".join(w for w in (f"{more} finished since" if more else "",
                                     f"{less} of the fitted ones no longer finished" if less else "") if w)
        return f"out of date: its sweep {sweep} has other finished points than it was fitted from ({what}); {rerun}"
    return None


def untested_notes(fits: dict[tuple, dict]) -> list[str]:
    """The notes on fits of three or more N that test nothing (a fit's ``tested`` false: its ``why``, one line per
    reason, naming the fits; h488) and on groups of which some N are Vertex-bound (TThru the Vertex PM's T_vert0:
    the fit keeps them, and there the pipelines' work shows in nothing), keyed as :func:`fit_key` keys them. A fit
    of two values of N is said where its error is shown (``tlm scaling``'s line, the report's caption)."""
    why: dict[str, list[str]] = {}
    vertex: dict[str, list[int]] = {}
    for key, f in fits.items():
        name = "/".join(key[:3]) + (f" ({key[4]})" if len(key) > 4 and key[4] else "")
        if len(f.get("rows") or f.get("pipelines") or []) < 3:
            continue
        for variant, g in (("eq. 5.2", f), ("its slowest-pipeline variant", f.get("slowest") or {})):
            if g.get("tested") is False and (variant == "eq. 5.2" or f.get("tested") is not False):
                why.setdefault(f"{variant} untested: {g.get('why')}", []).append(f"{name} {key[3]}")
            elif g.get("tested") and g.get("why"):  # (B not determined, its error a test all the same: h493)
                why.setdefault(f"{variant}: {g['why']}", []).append(f"{name} {key[3]}")
        if f.get("tested") is not False and f.get("vertex_bound") and key[3] == "throughput":
            vertex[name] = f["vertex_bound"]
    lines = [f"{', '.join(names)}: {text}" for text, names in why.items()]
    return lines + [f"{name}: N = {', '.join(map(str, ns))} Vertex-bound (TThru is the Vertex PM's T_vert0): fitted "
                    "all the same, though there the pipelines' work shows in nothing" for name, ns in vertex.items()]


def vertex_bound(p: dict) -> bool:
    """Whether a point's TThru is its Vertex PM's T_vert0 (the floor no count of pipelines goes under)."""
    return p.get("throughput") is not None and p["throughput"] <= p["T_vert0"]


def flat_why(by_n: dict[int, dict], target: str, ys: list, xs: list) -> str | None:
    """Why a fit of three or more N tests nothing (None where it tests eq. 5.2), from the fit's own quantities:
    ``ys`` are T(N) - T(1), ``xs`` M(N) - M(1) at each N past 1. Where no y differs from 0 (T does not vary with N;
    every point's TThru its Vertex PM's T_vert0, a small image: h488) B is 0 and meets every point whatever
    the pipelines do; where no x does, B is not determined (1 taken); two values of N alone test nothing either."""
    if len(by_n) < 3:
        return (f"N = {values_text(sorted(by_n))} alone: two points fit eq. 5.2's two parameters, a test of "
                "nothing (a third N tests it)")
    if not any(ys):
        ns, t = values_text(sorted(by_n)), round(by_n[1][target])
        if all(map(vertex_bound, by_n.values())):
            return (f"every point's throughput is the Vertex PM's T_vert0 ({round(by_n[1]['T_vert0']):,} cycles) at "
                    f"every N, N = {ns}: B is untested (the pipelines' work never shows); raise the resolution past "
                    "the crossover, the sides docs/api.md gives per N")
        return (f"the simulated {target} is {t:,} cycles at every N, N = {ns}: B = 0 meets every point whatever the "
                "pipelines do, B is untested")
    if not any(xs):  # (a test all the same, h493: the fit's ``tested`` stays true, its error shown)
        return ("sum_i max(T_t,i, T_r,i, T_f,i) / N is the same at every N: B is not determined (B = 1 taken), "
                "and whatever B is eq. 5.2 predicts the same cycles at every N, those at N = 1: the error measures "
                "that prediction")
    return None
