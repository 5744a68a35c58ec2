"""Whether a ``tlm scaling`` fit still shows its sweeps as they are (moved out of
:mod:`tlm.experiments.scaling`, which re-exports these names): the points a sweep lists and has
finished (:func:`sweep_points`, read by :data:`SWEEP_READ`), and the lines on a fit whose sweeps now
hold other points (:func:`out_of_date`, :func:`entry_out_of_date`)."""

from __future__ import annotations

import os
from collections.abc import Callable
from contextvars import ContextVar
from pathlib import Path
from typing import Any

import yaml

from tlm.config_words import safe_load  # (yaml.safe_load, its aliases bounded)
from tlm.errors import InputError
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
