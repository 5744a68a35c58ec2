"""A study folder's tables, read and checked for what the report's sections need of them (out of
:mod:`tlm.report.collect`, which reads every folder it is given and makes a study of these rows).

``thesis_comparison.csv`` and ``thesis_summary.json`` (``tlm thesis``: :func:`thesis_rows`, :func:`thesis_summary`);
``eq52.csv`` and ``eq52.json`` (``tlm scaling``), ``granularity.jsonl``, ``extreme.jsonl`` and an error-vs-cost
study's ``rows.jsonl`` with its ``reference.json`` (:func:`study_table`). A study's tables are written whole
(atomically), so one empty or with its last line cut off is a damaged copy, not a study with no rows: an
:class:`~tlm.errors.InputError` naming the file, as is a row or record not of the shape the sections read
(the kinds of value and the check of a record's keys: :mod:`tlm.report.checks`).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

from tlm.config import MODES
from tlm.errors import InputError
from tlm.experiments.thesis import METRICS, PM_METRICS
from tlm.report.checks import (
    BOOL,
    FINITE,
    FINITE_OR_NONE,
    LIST_OR_NONE,
    MAPPING,
    MAPPING_OR_NONE,
    NUMBER,
    NUMBER_OR_NONE,
    POSITIVE,
    PRESENT,
    TEXT,
    TEXTS,
)
from tlm.report.checks import check as _check
from tlm.report.checks import read_json as _json
from tlm.report.checks import rows_checked as _rows_checked
from tlm.report.checks import short as _short
from tlm.storage import read_jsonl
from tlm.storage_json import escaped


def _whole_file(path: Path) -> str:
    """The text of a file tlm writes whole (atomically, a study's table): an :class:`InputError`
    for one that is empty or cut off, a damaged copy, not a study with no rows."""
    try:
        with open(path, newline="", encoding="utf-8") as f:  # (as tlm wrote it: storage.write_atomic)
            text = f.read()
    except (OSError, ValueError) as e:
        raise InputError(f"cannot read: {e}", source=str(path)) from None
    if not text.strip():
        raise InputError("is empty: a damaged copy (tlm writes it whole, with at least its header line); "
                         "copy it again or run the study again", source=str(path))
    if not text.endswith(("\n", "\r")):
        raise InputError("is cut off (its last line has no end): a damaged copy (tlm writes it whole); "
                         "copy it again or run the study again", source=str(path))
    return text


def _study_jsonl(path: Path) -> list[tuple[int, dict]]:
    """A study's rows with their line numbers. The file is written whole, so a last row cut
    off is damage, not a row a killed process was appending (as in ``sweep.jsonl``, whose
    :func:`~tlm.storage.read_jsonl` leaves it out)."""
    try:
        with open(path, "rb") as f:
            last = f.read(1) if f.seek(0, 2) and f.seek(-1, 2) >= 0 else b""  # (the last byte; none if empty)
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror or e}", source=str(path)) from None
    if last == b"":  # (every study has a row a point: an empty table is a damaged copy)
        raise InputError("is empty: a damaged copy (tlm writes a row for every point); copy it again or run the "
                         "study again", source=str(path))
    if last != b"\n":
        raise InputError("is cut off (its last row has no end): a damaged copy (tlm writes it whole); "
                         "copy it again or run the study again", source=str(path))
    return read_jsonl(path)


# -- what the sections need of the files they read ------------------------------------------------------------
# (the kinds of value, the check of a record's keys and a run's results.json: tlm/report/checks.py)

THESIS_COLUMNS = {"scene": PRESENT, "mode": (lambda v: v in MODES, f"a mode ({', '.join(MODES)})"),
                  "metric": (lambda v: v in METRICS, f"a metric ({', '.join(METRICS)})"), "thesis": FINITE_OR_NONE,
                  "ours": FINITE, "rel_error": FINITE_OR_NONE, "calibrated": BOOL}
SCALING_COLUMNS = {"scene": PRESENT, "mode": PRESENT, "scheduler": PRESENT, "target": PRESENT,
                   "pipelines": POSITIVE, "simulated": POSITIVE, "analytical": NUMBER, "speedup": NUMBER}
SCALING_OPTIONAL = {"analytical_slowest": NUMBER}
EXTREME_KEYS = {"case": PRESENT, "category": PRESENT, "expect": PRESENT, "measured": PRESENT, "passed": BOOL,
                "seconds": NUMBER}
ERROR_COST_KEYS = {"filter": TEXT}
ERROR_COST_OPTIONAL = {"rel_mse": NUMBER_OR_NONE, "truth_rel_mse": NUMBER_OR_NONE, "frame_seconds": NUMBER_OR_NONE}
FIT_KEYS = {"scene": PRESENT, "mode": PRESENT, "scheduler": PRESENT, "target": PRESENT, "A": NUMBER, "B": NUMBER,
            "max_abs_rel_error": NUMBER}
FIT_SLOWEST_KEYS = {"A": NUMBER, "B": NUMBER, "max_abs_rel_error": NUMBER}
FITTED_FROM_KEYS = {"sweep": TEXT, "planned": TEXTS, "points": TEXTS}
PER_ITEM_KEYS = {"rays": NUMBER, "ours": MAPPING, "thesis": MAPPING}
PER_ITEM_OPTIONAL = {"tests_per_leaf": NUMBER_OR_NONE}


def thesis_summary(path: Path) -> dict:
    """``thesis_summary.json``: a mapping; its ``per_item`` and ``slowest_pm`` mappings of cells."""
    summary = _json(path)
    _check(summary, path, None, "a tlm thesis summary", {}, {
        "per_item": MAPPING_OR_NONE, "slowest_pm": MAPPING_OR_NONE,
        "median_abs_rel_error_held_out": NUMBER_OR_NONE})
    for cell, it in (summary.get("per_item") or {}).items():
        _check(it, path, f"per_item: {cell}", "a cell's counts per work item", PER_ITEM_KEYS, PER_ITEM_OPTIONAL)
        for side in ("ours", "thesis"):
            for k, v in it[side].items():
                if not NUMBER_OR_NONE[0](v):
                    raise InputError(f"{k!r} is {_short(v)}, not a number or empty", source=str(path),
                                     key=f"per_item: {cell}: {side}")
    for cell, it in (summary.get("slowest_pm") or {}).items():
        _check(it, path, f"slowest_pm: {cell}", "a cell's slowest PM", {})
    return summary


def _eq52(path: Path, rows: list[dict]) -> dict:
    """``eq52.json``: a mapping, its ``fits`` a list of fits (A, B and the error of each group),
    its ``fitted_from`` (where given: an older tlm wrote none) the points of each sweep fitted."""
    meta = _json(path)
    _check(meta, path, None, "a tlm eq. 5.2 file", {}, {"fits": LIST_OR_NONE, "sweeps": LIST_OR_NONE,
                                                        "fitted_from": LIST_OR_NONE})
    slowest = any("analytical_slowest" in r for r in rows)  # (the figure then draws each fit's slowest variant)
    for i, f in enumerate(meta.get("fits") or []):
        _check(f, path, f"fits[{i}]", "an eq. 5.2 fit", {**FIT_KEYS, **({"slowest": MAPPING} if slowest else {})},
               {"slowest": MAPPING})
        if "slowest" in f:
            _check(f["slowest"], path, f"fits[{i}]: slowest", "an eq. 5.2 fit", FIT_SLOWEST_KEYS)
    for s in meta.get("sweeps") or []:
        if not isinstance(s, str):
            raise InputError(f"{_short(s)} is not a folder's path", source=str(path), key="sweeps")
    for i, f in enumerate(meta.get("fitted_from") or []):
        _check(f, path, f"fitted_from[{i}]", "the points of a sweep an eq. 5.2 fit was made from", FITTED_FROM_KEYS)
    return meta



def _csv_rows(path: Path, what: str, required: dict, optional: dict | None = None) -> list[dict]:
    """The rows of a study's CSV table, values as numbers, booleans or None where they read
    as such: an :class:`InputError` naming the file for one that is empty or cut off, lacks a
    ``required`` column, has a row of more or fewer cells than its header, or a value not of
    its column's kind."""
    return [row for _, row in _csv_lines(path, what, required, optional)]


def _csv_lines(path: Path, what: str, required: dict, optional: dict | None = None) -> list[tuple[int, dict]]:
    """:func:`_csv_rows` with the line number of each row."""
    def value(v: str):
        if v == "":
            return None
        if v in ("True", "False"):
            return v == "True"
        try:
            return float(v)
        except ValueError:
            return v

    reader = csv.DictReader(io.StringIO(_whole_file(path), newline=""))
    try:
        header = reader.fieldnames or []
        missing = [k for k in required if k not in header]
        if missing:
            raise InputError(f"has no {', '.join(repr(k) for k in missing)} column{'s' if len(missing) > 1 else ''}: "
                             f"not {what}", source=str(path))
        rows = []
        for row in reader:
            if None in row or None in row.values():
                raise InputError(f"has {'more' if None in row else 'fewer'} cells than its header's {len(header)} "
                                 "columns: a damaged table", source=str(path), key=f"line {reader.line_num}")
            rows.append((reader.line_num, {k: value(v) for k, v in row.items()}))
    except csv.Error as e:
        raise InputError(f"is not a CSV table ({e})", source=str(path), key=f"line {reader.line_num}") from None
    _rows_checked(path, rows, what, required, optional)
    return rows


def thesis_rows(path: Path) -> list[dict]:
    """``thesis_comparison.csv``: its columns checked (:data:`THESIS_COLUMNS`), then its cells:
    ``tlm thesis`` writes one row of each metric (:data:`~tlm.experiments.thesis.METRICS`)
    for every scene-mode it ran, its relative error empty exactly where the thesis has no
    value. A table with no rows, a metric twice in a cell, a cell without a row of each PM
    (its slowest PM) or of FPS (the first screen's frame rates), or an error without a thesis
    value (or the other way round) is a damaged or edited copy: an :class:`InputError`. (A
    cell without its TThru row shows "–" there in the tables.)"""
    what = "a row of a tlm thesis comparison"
    lines = _csv_lines(path, what, THESIS_COLUMNS)
    if not lines:
        raise InputError("has a header but no rows: a damaged copy (tlm thesis writes a row for every metric of "
                         "every cell); copy it again or run the study again", source=str(path))
    cells: dict[tuple[str, str], dict[str, int]] = {}
    for n, row in lines:
        if (row["thesis"] is None) != (row["rel_error"] is None):
            has, lacks = ("thesis", "rel_error") if row["rel_error"] is None else ("rel_error", "thesis")
            raise InputError(f"has a {has!r} but an empty {lacks!r}: an edited or damaged row (tlm thesis writes "
                             "the error exactly where the thesis has a value)", source=str(path), key=f"line {n}")
        cell, metric = (str(row["scene"]), str(row["mode"])), str(row["metric"])
        seen = cells.setdefault(cell, {})
        if metric in seen:
            raise InputError(f"repeats the {metric} row of {cell[0]}/{cell[1]} (first on line {seen[metric]}): "
                             "an edited or damaged table", source=str(path), key=f"line {n}")
        seen[metric] = n
    for (scene, mode), seen in cells.items():
        missing = [m for m in (*PM_METRICS, "FPS") if m not in seen]
        if missing:
            raise InputError(f"has no {', '.join(missing)} row{'s' if len(missing) > 1 else ''} for {scene}/{mode}: "
                             f"an edited or damaged table (tlm thesis writes every metric, {', '.join(METRICS)}, "
                             "of every cell); copy it again or run the study again", source=str(path))
    return [row for _, row in lines]

def study_table(folder: Path, kind: str) -> tuple[list[dict], dict] | None:
    """The rows and the records (``meta``: its fits, summary or reference) of the study ``folder`` of ``kind``
    (scaling, granularity, extreme or error-vs-cost), read and checked; None for another kind. A thesis study's
    tables: :func:`thesis_rows` and :func:`thesis_summary`."""
    if kind == "scaling":
        rows = (_csv_rows(folder / "eq52.csv", "a row of a tlm eq. 5.2 table", SCALING_COLUMNS, SCALING_OPTIONAL)
                if (folder / "eq52.csv").is_file() else [])
        meta = _eq52(folder / "eq52.json", rows)
        # (eq52.csv holds a scene path of bytes not UTF-8 escaped, dir_\\xff, eq52.json as it is: the fits' name)
        named = {escaped(str(f.get("scene"))): f.get("scene") for f in meta.get("fits") or [] if isinstance(f, dict)}
        return [{**r, "scene": named.get(r.get("scene"), r.get("scene"))} for r in rows], meta
    if kind == "granularity":
        path = folder / "granularity.jsonl"
        summary = folder / "granularity_summary.json"  # (its warnings, for the report's box; none before h400)
        rows = [row for _, row in _study_jsonl(path)]
        return rows, ({"granularity_summary": _json(summary)} if summary.is_file() else {})
    if kind == "extreme":
        path = folder / "extreme.jsonl"
        return _rows_checked(path, _study_jsonl(path), "a tlm extreme case's row", EXTREME_KEYS), {}
    if kind == "error-vs-cost":
        path = folder / "rows.jsonl"
        rows = _rows_checked(path, _study_jsonl(path), "a tlm error-vs-cost row", ERROR_COST_KEYS, ERROR_COST_OPTIONAL)
        return rows, {"reference": _json(folder / "reference.json")}
    return None
