"""A sweep's rows: one tidy flat row per point, and the files that hold them.

A point's row (:func:`point_row`) is the point (its index, hash, status, error), its
factors, its scene and mode, who ran it (:func:`ran_fields`: the Dask worker's name, the host, the process,
where its record says), and for a point that ran the fields of its ``results.json``
(:func:`result_fields`): cycles per PM, fps, SimPy events, whether TThru is steady,
busy/stall/idle per PM kind averaged over the pipelines (:func:`utilization`), the bottleneck's stall
cycles per frame by cause (:func:`bottleneck_stalls`), a few work counts (:func:`work_counts`), the image
error where there is a reference, whether the frame came from the functional cache, and
host seconds, with their one-off part (``seconds.one_off``: numba compiling, first imports), and
the seconds of writing its folder (``seconds.write``).
``sweep.jsonl`` and ``sweep.csv`` hold the rows (:func:`write_rows`), the CSV
with an ok point's columns whatever the points' outcome (:func:`columns`), and a factor's null
value (``bsp.levels: [null, 6]``) as ``null``, as its YAML writes it, not as an empty cell
(:func:`csv_text`: a study's rows alike, error-vs-cost's ``rows.csv``), and a path of bytes not UTF-8 in a cell
(a failed point's error naming its folder ``run_\\xff``) with the byte escaped, ``\\xff`` (:func:`csv_cell`).
Two runs of one sweep sharing its folder write ``sweep.jsonl`` under one lock (:func:`rows_held`): each row
appended to the file the path names then (:class:`Appender`), never to one another run's rewrite replaced, and a
rewrite keeping the rows of finished points another run appended (:func:`write_rows`'s ``points``).
A sweep interrupted notes on its interrupt how many of its points' rows its folder keeps (:func:`note_kept`,
:func:`noting_kept`; before it claimed the folder, an earlier run's rows: :func:`rows_kept`). Whatever reads
``sweep.jsonl`` back takes each point's row once, its last (:func:`one_row_each`).
"""

from __future__ import annotations

import csv
import datetime
import fcntl
import io
import json
import math
import os
import re
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

from tlm import storage
from tlm.errors import error_line, interrupted_by
from tlm.experiments.sweep_file import Point
from tlm.storage_json import escaped
from tlm.storage_live import LOCK_NAME

FIRST_COLUMNS = ("point", "hash", "status", "error")
RAN_COLUMNS = ("worker", "host", "pid")  # who ran a point (its record's ``ran``: dask_workers.ran_here), after its
# mode, where its record says (a row of a sweep of before they were recorded has none)


class Row(dict):
    """A point's row: a dict of its fields, which knows which of them are the point's factors
    (``factors``: their keys), so that ``sweep.csv`` writes a factor's null as ``null``
    (:func:`write_rows`); ``sweep.jsonl`` and the API's rows see a plain dict."""

    __slots__ = ("factors",)

    def __init__(self, *args, factors: Iterable[str] = (), **kwargs):
        super().__init__(*args, **kwargs)
        self.factors = tuple(factors)


def point_row(point: Point, record: dict) -> Row:
    """One tidy flat row: the point, its factors, cycles, fps, utilization, error, host seconds."""
    row = Row({"point": point.index, "hash": point.hash, "status": record["status"], "error": None},
              factors=point.factors)
    row.update(point.factors)
    row["scene"] = point.config["scene"]
    row["mode"] = point.config["mode"]
    row.update(ran_fields(record))
    if record["status"] != "ok":
        err = record["error"]
        row["error"] = error_line(f"{err['type']}: {err['message']}", f"points/{point.hash}/error.json")
        return row
    row.update(result_fields(record["results"]))
    return row


def ran_fields(record: dict) -> dict[str, Any]:
    """Who ran the point of ``record`` (a worker's, or its ``results.json`` read back: a sweep resumed), as its
    row's :data:`RAN_COLUMNS`: the Dask worker's name (its ``--name``, else its address; null for a local
    process), the host, the process id; none where the record does not say (a point of an older tlm, one whose
    worker died before it could)."""
    ran = record.get("ran")
    if not isinstance(ran, dict):
        ran = (record.get("results") or {}).get("ran")
    if not isinstance(ran, dict):
        return {}
    return {k: ran.get(k) for k in RAN_COLUMNS}


def result_fields(res: dict) -> dict[str, Any]:
    """An ok point's fields of its row, from its ``results.json``: cycles, fps, SimPy events,
    whether TThru is steady, utilization, the bottleneck's stalls by cause, work counts, the image error (where
    there is a reference), whether the frame was cached, host seconds (and their one-off part), the seconds its
    folder's write took."""
    row: dict[str, Any] = {f"cycles.{k}": v for k, v in res["cycles"].items()}
    row["fps"] = res["fps"]
    row["simpy_events"] = res["timing"]["simpy_events"]
    # whether cycles.throughput is a steady-state TThru (false: a stream too short for one)
    row["throughput_steady"] = res["timing"].get("throughput_estimate", {}).get("steady")
    row.update(utilization(res["timing"]["units"]))
    row.update(bottleneck_stalls(res["timing"]))
    row.update(work_counts(res.get("work")))
    err = res.get("error") or {}
    if err.get("available"):
        row["error.rel_mse"] = err.get("rel_mse")
        row["error.rmse"] = err.get("rmse")
    row["functional_cached"] = res["functional"]["cached"]
    row["seconds.functional"] = res["host_seconds"]["functional"]
    row["seconds.simulate"] = res["host_seconds"]["simulate"]
    # (the part of those two in which numba compiled or loaded a kernel, or a module was first imported: the
    # one-off work of whichever points of a worker ran first; null in a results.json of before it was measured)
    row["seconds.one_off"] = res["host_seconds"].get("one_off")
    # (the writing of the point's folder, after its simulate: config.resolved.yaml, trace.json, the record; null in
    # a results.json of before it was measured)
    row["seconds.write"] = res["host_seconds"].get("write")
    return row


def result_columns() -> list[str]:
    """The columns every ok point's row has after its factors, ``scene`` and ``mode``, in its
    order: those :func:`result_fields` makes of a result of the model's shape (every PM of
    :data:`~tlm.arch.frame_program.PMS` in ``cycles`` and in the units, no image error), its values
    empty. ``sweep.csv`` has them whatever the points' outcome: empty cells for a failed point."""
    from tlm.arch.frame_program import PMS

    units = {f"pipe0.{pm}": {"busy": 0, "stalled": 0, "idle": 0, "elapsed": 0} for pm in PMS}
    shape = {"cycles": dict.fromkeys((*PMS, "throughput", "latency")), "fps": None,
             "timing": {"simpy_events": None, "throughput_estimate": {}, "units": units},
             "error": None, "functional": {"cached": None},
             "host_seconds": {"functional": None, "simulate": None, "one_off": None, "write": None}}
    return list(result_fields(shape))


def columns(rows: list[dict], factors: Iterable[str] = ()) -> list[str]:
    """The columns of ``sweep.csv`` and :attr:`~tlm.experiments.sweep.Outcome.table`: :data:`FIRST_COLUMNS`;
    the sweep's ``factors``, where given, then ``scene`` and ``mode`` (every row's fields, in its
    order: a file of no rows has them too, a sweep stopped before any point finished); every other
    field of ``rows`` as it first appears (the factors, ``scene``, ``mode``, ``cycles.*``, ``fps``,
    ...); then those of :func:`result_columns` no row has (all of them when no point is ok). Who ran the points
    (:data:`RAN_COLUMNS`, where a row has them) follows ``mode`` whatever row says it first: a sweep of an older
    tlm resumed has rows without them before those with them, which would put them after the results."""
    cols = list(FIRST_COLUMNS)
    factors = list(factors)
    cols.extend(k for k in ([*factors, "scene", "mode"] if factors else ()) if k not in cols)
    for r in rows:
        cols.extend(k for k in r if k not in cols)
    ran = [k for k in RAN_COLUMNS if k in cols]
    if ran and "mode" in cols:
        cols = [k for k in cols if k not in ran]
        at = cols.index("mode") + 1
        cols[at:at] = ran
    cols.extend(k for k in result_columns() if k not in cols)
    return cols


def utilization(units: dict) -> dict[str, float]:
    """busy / stall / idle fractions of elapsed per PM kind, averaged over the pipelines.

    PMs are the units named ``pipe<p>.<pm>``; memory modules and the crossbar are not PMs.
    """
    kinds: dict[str, list[dict]] = {}
    for scope, b in units.items():
        m = re.fullmatch(r"pipe\d+\.(\w+)", scope)
        if m:
            kinds.setdefault(m[1], []).append(b)
    out = {}
    for what, key in (("busy", "busy"), ("stall", "stalled"), ("idle", "idle")):
        for kind, bs in kinds.items():
            out[f"{what}.{kind}"] = round(sum(b[key] / b["elapsed"] if b["elapsed"] else 0.0 for b in bs)
                                          / len(bs), 6)
    return out


def bottleneck_stalls(timing: dict) -> dict[str, Any]:
    """The bottleneck's stall cycles per frame by cause (h542), from ``results.json`` ``timing``: the unit
    ``pipe<p>.<pm>`` of the slowest PM kind (``throughput_estimate.slowest_pm``, the one of the largest
    ``cycles.<pm>``) in the pipeline where it costs a frame most (``timing.pipelines``, the first of equal ones):
    ``bottleneck.pm``, ``bottleneck.pipeline``, then ``bottleneck.<cause>``, its data stalls of each cause of
    :data:`~tlm.arch.units.STALL_CAUSES` (``handshake``, ``swap``, ``copy``, ``preemption``, ``fifo_full``,
    ``fifo_empty``) and ``bottleneck.memory``, its page-miss cycles (``T_ms``, counted in its busy cycles), each
    over the frames the stream ran (``timing.frames``) and rounded to whole cycles. None where the record does not
    say (a results.json of an older tlm)."""
    from fractions import Fraction

    from tlm.arch.units import STALL_CAUSES

    causes = (*STALL_CAUSES, "memory")
    out: dict[str, Any] = {"bottleneck.pm": None, "bottleneck.pipeline": None}
    out.update({f"bottleneck.{c}": None for c in causes})
    pm = (timing.get("throughput_estimate") or {}).get("slowest_pm")
    pipes = [p if isinstance(p, dict) else {} for p in timing.get("pipelines") or []]
    frames = timing.get("frames")
    if not isinstance(pm, str) or not pipes or not isinstance(frames, int) or frames < 1:
        return out
    pipe = max(range(len(pipes)), key=lambda p: (pipes[p].get(pm) or 0, -p))
    unit = (timing.get("units") or {}).get(f"pipe{pipe}.{pm}")
    out["bottleneck.pm"], out["bottleneck.pipeline"] = pm, pipe
    if not isinstance(unit, dict):
        return out
    got = {**(unit.get("stall") or {}), "memory": unit.get("T_ms")}
    for c in causes:
        v = got.get(c)
        out[f"bottleneck.{c}"] = round(Fraction(v, frames)) if isinstance(v, int) else None
    return out


def work_counts(work: Any) -> dict[str, int | None]:
    """A few of the frame's work counts (h542), from ``results.json`` ``work``, summed over the passes:
    ``work.rays`` (eye, secondary and shadow rays), ``work.tri_tests`` (ray-triangle tests, shadow rays' too) and
    ``work.gathers`` (the photon-map pass's gathers; None where no pass gathers). None where the record has
    no ``work`` (a results.json of an older tlm)."""
    out: dict[str, int | None] = {"work.rays": None, "work.tri_tests": None, "work.gathers": None}
    if not isinstance(work, dict) or not work:
        return out
    passes = [c for c in work.values() if isinstance(c, dict)]
    traced = [c for c in passes if "primary_rays" in c]
    if traced:
        out["work.rays"] = sum(int(c.get(k) or 0) for c in traced
                               for k in ("primary_rays", "secondary_rays", "shadow_rays"))
        out["work.tri_tests"] = sum(int(c.get(k) or 0) for c in traced for k in ("tri_tests", "shadow_tri_tests"))
    gathered = [c for c in passes if "gathers" in c]
    if gathered:
        out["work.gathers"] = sum(int(c["gathers"] or 0) for c in gathered)
    return out


def write_rows(out: Path, rows: list[dict], factors: Iterable[str] = ()) -> None:
    """``sweep.jsonl`` and ``sweep.csv``: the rows sorted by point; the CSV's columns are
    :func:`columns` (the sweep's ``factors``, and an ok point's result columns, even when no
    point is ok or there is no row), the JSONL's objects hold their own fields only. Each is
    written whole or not at all, as :func:`tlm.storage.write_rows` writes a study's rows, and the
    cells alike (a list or mapping as JSON, a number that is not finite empty, as null), but for
    a factor's null value (a key of ``factors``, or of a :class:`Row`'s own): ``null``
    (:func:`csv_cell`), which an empty cell (a field the row does not have: a failed point's
    ``fps``) would not tell apart. A running sweep writes them under the rows' lock (:func:`rows_held`).

    Where either write fails (a full disk, any error), ``sweep.csv`` is removed and the error goes on: the CSV there
    would contradict ``sweep.jsonl``, the rows just written or those a sweep appended since the CSV was
    (nothing but the JSONL is lost: the CSV is written from its rows)."""
    rows = sorted(rows, key=lambda r: r["point"])
    factors = list(factors)
    named = {*factors, *(k for r in rows for k in getattr(r, "factors", ()))}
    try:
        storage.write_file(out / "sweep.jsonl", "".join(storage.json_text(r) + "\n" for r in rows))
        with storage.write_atomic(out / "sweep.csv", "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=columns(rows, factors))
            w.writeheader()
            for r in rows:
                w.writerow({k: csv_cell(v, k in named) for k, v in r.items()})
    except Exception:  # (a full disk; any other, which left the CSV of before beside these rows too)
        with suppress(OSError):
            (out / "sweep.csv").unlink(missing_ok=True)
        raise


def others_rows(out: Path, rows: list[dict], points: Mapping[str, int]) -> list[dict]:
    """The rows of ``out``'s ``sweep.jsonl`` that a sweep's rewrite of it keeps beside its own ``rows`` (read under
    the rows' lock, :func:`rows_held`): each of a point of the sweep (``points``: hash -> index) that ``rows`` has
    not, ``ok``, its folder's ``results.json`` there (another run of the sweep sharing the folder finished the
    point since this one read the folder: its row stays, not lost till that run ends); a point's last such row.
    Not kept: a failed row (the point runs again), another sweep's, one whose folder is gone."""
    have = {r.get("hash") for r in rows}
    return [r for r in rows_kept(out, set(points) - have)
            if r.get("status") == "ok" and r.get("point") == points.get(r["hash"])
            and (out / "points" / r["hash"] / "results.json").is_file()]


@contextmanager
def rows_held(out: Path) -> Iterator[None]:
    """The lock under which a sweep writes ``out``'s ``sweep.jsonl`` (and ``sweep.csv``): an exclusive ``flock`` on
    the folder's guard (``.tlm-lock``, :func:`tlm.claims.sharing`'s, there while a sweep holds the folder; made
    where missing). Two runs of one sweep sharing the folder: one's rewrite (an atomic rename) and the other's
    append are never at once, and an append opens the file the path names then (:class:`Appender`). A folder
    whose file system locks nothing (or a guard that cannot be opened): written unlocked, as before."""
    fd = None
    with suppress(OSError):
        while fd is None:
            got = os.open(out / LOCK_NAME, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            try:
                fcntl.flock(got, fcntl.LOCK_EX)
            except BaseException:  # (no locks there; an interrupt while waiting)
                os.close(got)
                raise
            fd = got if _same_file(got, out / LOCK_NAME) else os.close(got)  # (removed meanwhile: opened again)
    try:
        yield
    finally:
        if fd is not None:
            os.close(fd)  # (releases the lock)


def _same_file(fd: int, path: Path) -> bool:
    """Whether ``path`` still names the file open as ``fd``."""
    try:
        return os.path.samestat(os.stat(path), os.fstat(fd))
    except OSError:
        return False


class Appender:
    """A running sweep's appends to ``out``'s ``sweep.jsonl``: the rows written (:meth:`write`) are appended at each
    :meth:`flush`, under the rows' lock (:func:`rows_held`), to the file the path names then, opened anew (another
    run of the sweep may have rewritten it since, an atomic rename: appended to the file it replaced, the rows
    were lost from ``sweep.jsonl`` till this run ended, and for good where it was killed), after cutting off a
    last row left half written (a run killed while appending). A point's rows cost the end of the file only, not
    a read of it: 10^4 points append 10^4 times. Its open, writes and close name the file where they fail
    (:func:`tlm.storage.appending`: a full disk's one line)."""

    def __init__(self, out: Path):
        self.path, self._text = Path(out) / "sweep.jsonl", []

    def __enter__(self) -> Appender:
        return self

    def __exit__(self, *exc) -> None:
        self._text = []  # (what no flush appended: nothing)

    def write(self, text: str) -> None:
        self._text.append(text)

    def flush(self) -> None:
        data, self._text = "".join(self._text), []
        if not data:
            return
        with rows_held(self.path.parent):
            trim_torn(self.path)
            with storage.appending(self.path) as f:
                f.write(data)
                f.flush()


def trim_torn(path: Path, block: int = 65536) -> None:
    """Cut off a last row left half written (a sweep killed while writing it), so that the rows appended next
    start on a line of their own: the end of the file read only (its last line, block by block from the end)."""
    with suppress(FileNotFoundError), storage.naming(path), open(path, "rb+") as f:
        end = at = f.seek(0, os.SEEK_END)
        f.seek(max(0, end - 1))
        if not end or f.read(1) == b"\n":
            return
        while at > 0:
            start = max(0, at - block)
            f.seek(start)
            i = f.read(at - start).rfind(b"\n")
            if i >= 0:
                f.truncate(start + i + 1)
                return
            at = start
        f.truncate(0)


def csv_text(rows: Iterable[dict], columns: Iterable[str] = (), values: Iterable[str] = ()) -> str:
    """The CSV of ``rows`` as :func:`tlm.storage.write_rows` writes a study's (``columns`` first, a
    column no row has included, then every other key of the rows as it first appears), each cell
    :func:`csv_cell`'s, a null of a key of ``values`` (a null that is a setting's value, not a field
    missing or of no meaning) as ``null``."""
    rows = list(rows)
    cols = list(columns)
    for r in rows:
        cols.extend(k for k in r if k not in cols)
    values = set(values)
    buffer = io.StringIO(newline="")
    w = csv.DictWriter(buffer, fieldnames=cols)
    w.writeheader()
    for r in rows:
        w.writerow({k: csv_cell(v, k in values) for k, v in r.items()})
    return buffer.getvalue()


def csv_cell(value: Any, factor: bool = False) -> Any:
    """A row's value as its ``sweep.csv`` cell: a list or mapping as JSON, a number that is not
    finite as an empty cell (strict JSON's null, as :func:`tlm.storage.write_rows` writes it), a
    factor's null (``factor``) as ``null``, as the sweep file's YAML and ``--set`` write it; text with each
    surrogate escaped (:func:`tlm.storage_json.escaped`: a path of bytes not UTF-8, ``os.fsdecode(b"run_\\xff")``,
    as ``run_\\xff``, which UTF-8 writes: the surrogate raised UnicodeEncodeError and no CSV was written); anything
    else as the CSV writes it."""
    if value is None:
        return "null" if factor else None
    if isinstance(value, (list, dict)):
        return storage.json_text(value)
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, str):
        return escaped(value)
    return value


WORKERS_FILE = "workers.json"  # a Dask sweep's events on its workers (keep_worker_events), beside its rows
WORKERS_FORMAT = "sweep-workers/1"


def keep_worker_events(out: Path, events: list[dict], sweep: str | None = None) -> None:
    """The Dask workers' ``events`` of a sweep into the folder ``out`` (:meth:`~tlm.experiments.executors_dask.
    WorkerWatch.worker_events`: a worker left out and why, the points sent again from it and where they ran, one
    re-admitted, one that left the cluster holding points), each stamped ``when`` (now, UTC: the sweep's end), after
    those of the earlier runs of the sweep into the folder (a rerun's points done earlier were run so; ``sweep``: its
    identity, :meth:`~tlm.experiments.sweep_file.Sweep.identity`, kept as the file's ``sweep``): ``workers.json``
    (``tlm: sweep-workers/1``, ``sweep``, ``events``), written whole, atomically (:func:`tlm.storage.write_file`), for
    ``tlm report``. Nothing is written for none; one of before that cannot be read, is not of this format (no
    ``tlm: sweep-workers/1``, no ``events`` list) or is another sweep's, is replaced. The file is read and written
    under the folder's lock (:func:`tlm.storage.folder_lock`): two runs of one sweep sharing the folder keep each
    one's events."""
    if not events:
        return
    when = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    with storage.folder_lock(out):
        body = {"tlm": WORKERS_FORMAT, **({"sweep": sweep} if sweep is not None else {}),
                "events": [*(kept_worker_events(out, sweep) or []), *({**e, "when": when} for e in events)]}
        storage.write_file(out / WORKERS_FILE, storage.json_text(body, indent=2) + "\n")


def kept_worker_events(out: Path, sweep: str | None = None) -> list[dict] | None:
    """The events the folder ``out``'s ``workers.json`` keeps (:func:`keep_worker_events`): [] where it has none, or
    one that cannot be read or is not of this format; None where it is another sweep's than ``sweep`` (where given:
    a sweep of other points run into the folder since)."""
    try:
        body = read_worker_events(out / WORKERS_FILE)
    except (OSError, ValueError):  # (UnicodeDecodeError among them)
        return []
    if sweep is not None and body.get("sweep") != sweep:
        return None
    return [e for e in body["events"] if isinstance(e, dict)]


def read_worker_events(path: Path) -> dict:
    """The body of the ``workers.json`` at ``path`` (:func:`keep_worker_events`); OSError where it cannot be read,
    ValueError (a UnicodeDecodeError, a JSONDecodeError, or one saying why) where it is no such file."""
    body = json.loads(path.read_text(encoding="utf-8"))
    if not isinstance(body, dict) or body.get("tlm") != WORKERS_FORMAT:
        raise ValueError(f"it is not a tlm: {WORKERS_FORMAT} file")
    if not isinstance(body.get("events"), list):
        raise ValueError("it holds no events list")
    return body


def forget_worker_events(out: Path, sweep: str) -> None:
    """``workers.json`` removed from the folder ``out`` where it is of another sweep than ``sweep`` (its identity): a
    sweep of other points now runs into the folder, whose rows its events (of points no longer its) do not tell of."""
    if kept_worker_events(out, sweep) is not None:  # (none of another sweep: nothing to do, no lock waited for)
        return
    with storage.folder_lock(out):
        if kept_worker_events(out, sweep) is None:
            (out / WORKERS_FILE).unlink(missing_ok=True)


KEPT = "kept_points"  # the attribute of a sweep's interrupt that says what its folder kept (note_kept)


def note_kept(e: BaseException, records: list[dict] | None, total: int) -> None:
    """What a sweep interrupted (``e``: a KeyboardInterrupt, or an error a C extension made of one,
    :func:`tlm.errors.interrupted_by`) kept in its folder, noted on ``e`` (its :data:`KEPT`: how many of its
    ``total`` points have a row there, those done before counted, and how many of these failed) for its
    line (:func:`tlm.cli_report.sweep_cut_short`): ``records``, the records of those points, one per row
    (None: their rows could not be written, nothing noted). Any other exception is left as it is."""
    if records is None or not (isinstance(e, KeyboardInterrupt) or interrupted_by(e) is not None):
        return
    with suppress(AttributeError, TypeError):  # (an exception that takes no attribute: its line is the bare one)
        setattr(e, KEPT, (len(records), sum(r.get("status") != "ok" for r in records), total))


@contextmanager
def noting_kept(records: Callable[[], list[dict] | None], total: int) -> Iterator[None]:
    """:func:`note_kept` on an interrupt of the block, ``records()`` its rows' records, asked then: a sweep's stage
    outside its points' (its ``--reference`` step, before them: the rows an earlier run kept, :func:`rows_kept`; its
    summary after its rows are written: those rows), whose line says them too, not a bare ``tlm: interrupted``."""
    try:
        yield
    except BaseException as e:
        with suppress(Exception):  # (what stopped the sweep goes on whatever: its line the bare one)
            note_kept(e, records(), total)
        raise


def rows_kept(out: Path, hashes: Iterable[str]) -> list[dict]:
    """The rows of ``out``'s ``sweep.jsonl`` of a sweep's points (their ``hashes``), one per row, failed ones too: what
    the folder keeps of them before the sweep claimed it (an earlier run's, which a rerun into it goes on from; a
    line cut off, one not JSON and another sweep's point's left out; a point's later row in place of its earlier,
    which a killed rerun appended after: one row per point); none where there is no such file."""
    try:
        text = (out / "sweep.jsonl").read_text(encoding="utf-8", errors="replace")
    except (OSError, ValueError):
        return []
    wanted, kept = set(hashes), []
    for line in text.splitlines(keepends=True):
        with suppress(ValueError):
            row = json.loads(line) if line.endswith("\n") else None
            if isinstance(row, dict) and isinstance(row.get("hash"), str) and row["hash"] in wanted:
                kept.append(row)
    return one_row_each(kept)


def one_row_each(rows: Iterable[Any], row: Callable[[Any], Any] = lambda r: r) -> list[Any]:
    """The rows of a ``sweep.jsonl`` read back (``row``: the row of each of ``rows``, a dict, where they are
    ``(line, row)`` pairs), each point's once: its last, where its first was. A point has two where a sweep
    appended its row after the folder already had one: two runs of one sweep sharing the folder (each appends the
    points it runs, and both may run one) killed before either rewrote the file sorted, or an older tlm's rerun
    cut short; the later is what the last run of the point found, as a rerun that goes on rewrites it. The one
    rule of :func:`rows_kept` (an interrupted sweep's count), ``tlm report``'s (:mod:`tlm.report.collect`) and
    ``tlm scaling``'s (:mod:`tlm.experiments.scaling`, :mod:`tlm.experiments.scaling_dated`). A point is its
    row's ``hash`` (one per point: :func:`~tlm.experiments.sweep_checks.one_run_one_row`); a row whose hash is
    no text (a damaged one) is kept as it is, for its reader to judge."""
    kept: dict[Any, Any] = {}
    for i, r in enumerate(rows):
        fields = row(r)
        h = fields.get("hash") if isinstance(fields, dict) else None
        key = h if isinstance(h, str) else (i,)  # (a tuple: no hash's text)
        kept[key] = r
    return list(kept.values())
