"""What a sweep would do, told before it spends anything (``tlm sweep FILE --dry-run``).

:func:`plan` reads what :func:`~tlm.experiments.sweep.run_sweep` reads before its first point, and no
more, and writes nothing (no output folder, no cache entry, no claim, no report): the sweep file and every
point's config, checked as the sweep checks them (:func:`~tlm.experiments.sweep_file.load_sweep`: the same
one-line errors), the output folder's points done (:func:`~tlm.experiments.sweep_reference.point_done`, as
the sweep skips them), the frames the points to run share (their functional keys; points that differ only in keys
their frame does not read share one) and which of them the functional cache holds
(:func:`~tlm.experiments.frames.is_cached`, as the sweep's dispatch asks it), the stale folders a sweep into
the folder removes (a killed sweep's temporary point folders, row files and held references; a failed or
unfinished point's folder, run again; one done without the trace.json it asks for, ``arch.trace``, is run
again and kept until its new folder replaces it; the folder's earlier report,
:func:`~tlm.experiments.sweep_folder.report_goes`) and those it warns of
(:func:`~tlm.experiments.sweep_folder.other_names`),
the warnings it says before its points run (:meth:`~tlm.experiments.sweep_file.Sweep.inert_factors`,
:meth:`~tlm.experiments.sweep_file.Sweep.inert_sets`, ``render.threads`` and ``--jobs`` past the CPUs available:
:mod:`tlm.experiments.run_warnings`); with ``reference`` (``--reference``), the photon-map
references it would compute, decided as :func:`~tlm.experiments.sweep_reference.sweep_references` decides
(one per distinct value of the keys a reference reads; a cached one judged by its ``meta.json`` alone, its
image neither read nor, where damaged, removed). A scene is loaded only where a key needs it: the frames'
keys (as the sweep's own check does) and, with ``reference``, the references'. That load reads the scene cache
and writes nothing to it (:func:`~tlm.scenes.cache.read_only`): a mesh of at least
:data:`~tlm.scenes.cache.MIN_TRIANGLES` triangles not in it yet is parsed and not kept, nor its crease normals or
its remembered fingerprint, and no entry read is marked used.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tlm import storage
from tlm.experiments.sweep_file import Point, Sweep, load_sweep
from tlm.experiments.sweep_point import MARKER, finished
from tlm.experiments.sweep_reference import (
    HELD,
    done_record,
    listed,
    point_done,
    reference_groups,
    strictest,
    to_measure,
)
from tlm.scenes.cache import read_only


@dataclass
class Reference:
    """A photon-map reference the sweep's points need (``--reference``): its ``key``, how many of the points
    that would run need it (``points``), and what the sweep would do: ``"compute"`` (none cached),
    ``"compute again"`` (the cached one misses the points' tolerance, and more rounds would better it),
    ``"cached"`` (it meets their tolerance: used as it is) or ``"kept"`` (it misses it, but computing again
    would not better it: used as it is, and said so)."""

    key: str
    points: int
    action: str
    saved: int = 0  # rounds saved by an interrupted compute of it (references/<key>.partial.npz), which it resumes

    @property
    def computed(self) -> bool:
        return self.action.startswith("compute")


@dataclass
class SweepPlan:
    """What ``tlm sweep`` of the sweep file ``path`` into ``out`` would do (:func:`plan`); nothing is run or
    written. Counts of points are of the sweep file's points (its rows); frames are functional results."""

    path: Path
    out: Path
    points: int  # the sweep file's points
    done: int  # done already in ``out``: skipped
    to_run: int  # run (points not done; with --reference, done ones measured again)
    measured_again: int  # of ``to_run``: points done whose reference --reference would compute (run again)
    frames: int  # the distinct frames (functional results) of the points to run
    frames_cached: int  # of ``frames``: in the functional cache now (read, not rendered)
    replaced: int  # point folders of points to run (failed, unfinished, unreadable): removed and run again
    stale: int  # temporary folders and files of killed sweeps in ``out``: removed
    other_folders: int  # point folders of no point of this sweep: kept, warned of
    references: list[Reference] | None = None  # with --reference: every reference the points to run need
    warnings: list[str] = field(default_factory=list)  # the warnings the sweep would say (before its points run)
    remote: bool = False  # a remote Dask scheduler: its workers' caches, not this machine's, decide the renders
    untraced: int = 0  # of ``kept``: points done without the trace.json they now ask for (arch.trace: true)
    kept: int = 0  # point folders of finished points run again (their trace.json, --reference): kept until replaced
    report_removed: bool = False  # ``out``'s earlier report/, which the sweep removes as it claims the folder

    @property
    def renders(self) -> int:
        """The frames the sweep would render: the points' frames not cached (one render each)."""
        return self.frames - self.frames_cached

    def record(self) -> dict[str, Any]:
        """The plan as JSON-able values (``tlm sweep --dry-run --json``)."""
        refs = None if self.references is None else [
            {"key": r.key, "points": r.points, "action": r.action, "saved_rounds": r.saved} for r in self.references]
        return {"dry_run": True, "sweep": str(self.path), "out": str(self.out), "points": self.points,
                "done": self.done, "to_run": self.to_run, "measured_again": self.measured_again,
                "frames": self.frames, "frames_cached": self.frames_cached, "renders": self.renders,
                "replaced": self.replaced, "kept": self.kept, "untraced": self.untraced, "stale": self.stale,
                "other_folders": self.other_folders, "report_removed": self.report_removed, "references": refs,
                "remote": self.remote,
                "warnings": list(self.warnings)}

    def lines(self) -> list[str]:
        """The summary ``tlm sweep --dry-run`` prints, a line each."""
        def n(count: int, word: str) -> str:
            return f"{count} {word}{'s' if count != 1 else ''}"

        again = f", {self.measured_again} of them done before and measured again (--reference)" \
            if self.measured_again else ""
        why = ("without the trace.json they ask for (arch.trace)" if self.untraced == self.kept else
               "measured again (--reference)" if not self.untraced else
               "without the trace.json they ask for (arch.trace), or measured again (--reference)")
        folders = [*([f"{n(self.replaced, 'point folder')} of failed or unfinished points removed and run again"]
                     if self.replaced else []),
                   *([f"{n(self.kept, 'point folder')} of points done {why} run again, each kept until its new "
                      "folder replaces it"] if self.kept else [])]
        replaced = f"; {'; '.join(folders)}" if folders else ""
        where = " (this machine's cache; a remote Dask worker reads its own)" if self.remote else ""
        lines = [f"dry run of {self.path} into {self.out}: nothing run, nothing written",
                 f"  {n(self.points, 'point')}: {self.done} done already (skipped), {self.to_run} to run{again}"
                 f"{replaced}",
                 f"  {n(self.frames, 'frame')} for the points to run: {self.frames_cached} cached{where}, "
                 f"{self.renders} to render"]
        if self.references is not None:
            computed = [r for r in self.references if r.computed]
            lines.append("  --reference: none needed (the photon-map points to run have theirs cached, or none runs "
                         "the pass)" if not self.references else
                         f"  --reference: {n(len(computed), 'reference')} to compute, "
                         f"{len(self.references) - len(computed)} cached")
            lines += [f"    {r.key}: {r.action} ({n(r.points, 'point')}"
                      + (f"; {n(r.saved, 'round')} saved by an interrupted compute, resumed where these settings "
                         "allow" if r.saved else "") + ")" for r in self.references]
        if self.stale:
            what = "folder or file" if self.stale == 1 else "folders or files"
            lines.append(f"  {self.stale} temporary {what} of killed sweeps in {self.out}: removed")
        if self.report_removed:  # (sweep_folder.drop_report's: not of the rows the sweep leaves)
            lines.append(f"  {self.out / 'report'}: the report of the folder's earlier sweep, removed as the sweep "
                         "claims the folder (its own is written after its points, unless --no-report)")
        if self.other_folders:
            lines.append(f"  {n(self.other_folders, 'point folder')} not this sweep's: kept (a warning says so)")
        return lines


DRY_RUN_CONNECT_TIMEOUT = 5  # seconds a dry run waits for a --dask scheduler's host to answer (the sweep: 10)


def plan_sweep(path: Path, out: Path, jobs: int | None = None, dask: str | None = None,
               dask_wait: float | None = None, overrides: Iterable[str] = (), reference: bool = False,
               check: Callable[[Any, Path], None] | None = None) -> SweepPlan:
    """What :func:`~tlm.experiments.sweep.run_sweep` of the same arguments would do, nothing run or written (``tlm
    sweep --dry-run``): its checks of them, of the environment's kernel settings, of the sweep file (every point's
    config: :func:`~tlm.experiments.sweep_file.load_sweep`) and of ``out`` first, in its order (the same errors),
    a ``--dask tcp://...`` scheduler's address (``tls://``, ``ws://``, ``wss://`` alike: no handshake) tried as
    the sweep tries it (:func:`~tlm.experiments.executors_dask.answers`: one TCP connection, closed at once, within
    :data:`DRY_RUN_CONNECT_TIMEOUT` seconds; no client made, nothing submitted), then :func:`plan`. ``check``: the
    sweep file's data's, as the sweep's (:func:`~tlm.experiments.sweep_file.load_sweep`)."""
    from tlm.experiments.provenance import kernels_here
    from tlm.experiments.sweep import checked_options
    from tlm.kernels.threads import fork_workers

    dask = checked_options(jobs, dask, dask_wait)[0]
    kernels_here(), fork_workers()  # (a bad TLM_KERNELS or TLM_FORK_WORKERS: refused as by the sweep)
    with read_only():  # (the scenes' loads read the scene cache and write nothing: no parse kept, no entry touched)
        sweep = load_sweep(Path(path), overrides, check)
        storage.check_destination(Path(out), MARKER)
    if dask not in (None, "local"):  # (a scheduler's address: tried as the sweep tries it, nothing submitted)
        from tlm.experiments.executors_dask import answers

        answers(dask, timeout=DRY_RUN_CONNECT_TIMEOUT)
    if dask is None and jobs is None:  # (the sweep's worker processes: the CPUs available)
        from tlm.kernels.threads import available

        jobs = available()
    with read_only():
        return plan(sweep, Path(out), reference, remote=dask not in (None, "local"),
                    jobs=jobs if dask is None else None)


def plan(sweep: Sweep, out: Path, reference: bool = False, remote: bool = False, jobs: int | None = None
         ) -> SweepPlan:
    """What :func:`~tlm.experiments.sweep.run_sweep` of the loaded ``sweep`` into ``out`` would do (the module's
    docstring); ``out`` checked already (:func:`~tlm.storage.check_destination`). Reads, writes nothing. Its
    warnings are the sweep's, the ``render.threads`` past the CPUs available among them (not for a remote
    scheduler's workers), and, with ``jobs`` (local worker processes; None: a Dask cluster's), ``--jobs`` times
    ``render.threads`` past them (:func:`~tlm.experiments.run_warnings.sweep_jobs_line`)."""
    from tlm.experiments.frames import is_cached
    from tlm.experiments.run_warnings import sweep_jobs_line, sweep_threads_line
    from tlm.experiments.sweep_folder import earlier_sweep, other_folders_line, other_names, report_goes

    out = Path(out)
    points_dir = out / "points"
    by_hash: dict[str, list[Point]] = {}
    for p in sweep.points:
        by_hash.setdefault(p.hash, []).append(p)
    present = listed(points_dir)
    records = {h: point_done(points_dir / h, by_hash[h][0]) if h in present else None for h in by_hash}
    todo = {h for h, rec in records.items() if rec is None}
    # (of them, done but for the trace.json the point asks for: point_done)
    untraced = sum(h in present and by_hash[h][0].traces and done_record(points_dir / h) is not None for h in todo)
    warnings = [*sweep.inert_factors(), *sweep.inert_sets()]
    warnings += [] if remote else sweep_threads_line(sweep.points, str(sweep.path))  # (as the sweep starts)
    references = again = None
    if reference:
        references, again, line = _references(sweep, records)
        warnings += line
    run = todo | (again or set())
    if jobs is not None and run:  # (--jobs x render.threads past the CPUs: as the sweep's points start)
        warnings += sweep_jobs_line([by_hash[h][0] for h in sorted(run)], min(jobs, len(run)))
    # (as run_sweep: a folder of no finished point is removed first, a finished one kept until it is replaced)
    ended = {h: finished(points_dir / h) is not None for h in run if h in present}
    replaced, kept = sum(not e for e in ended.values()), sum(ended.values())
    frames = {by_hash[h][0].functional for h in run}
    cached = sum(is_cached(k) for k in frames)
    names, earlier = other_names(points_dir, by_hash), earlier_sweep(out)
    other = len(names)
    if other:
        warnings.append(other_folders_line(other, points_dir, earlier, sweep, names=names))  # (what changed since)
    # (its earlier report: removed as the sweep claims the folder, but where it is of the rows it leaves, as run_sweep)
    gone = report_goes(out, current=not run and earlier is not None and earlier.text == sweep.marker())
    count = lambda hashes: sum(len(by_hash[h]) for h in hashes)  # noqa: E731  (a hash's points: its rows)
    return SweepPlan(sweep.path, out, len(sweep.points), count(set(by_hash) - run), count(run),
                     count(again or ()), len(frames), cached, replaced, _stale(out), other, references,
                     warnings, remote, untraced, kept, gone)


def _references(sweep: Sweep, records: dict[str, dict | None]) -> tuple[list[Reference], set[str], list[str]]:
    """``--reference``'s references, decided as :func:`~tlm.experiments.sweep_reference.sweep_references` decides
    (its points grouped by what a reference reads, a scene loaded per group), none computed: each reference the
    points to run (or those done without an error, or measured against one short of its tolerance) need, the
    hashes of the points done that computing them would measure again, and the sweep's line where no point runs
    the photon-map pass."""
    from tlm.experiments.reference_cache import verdict

    pmap = False
    needed: dict[str, tuple[dict[str, str], dict[str, Any]]] = {}  # key -> (hash -> why measured, settings by hash)
    for group, _cfg, settings, key in reference_groups(sweep):
        pmap = True
        for p in group:
            why = to_measure(records[p.hash])
            if why:
                need = needed.setdefault(key, ({}, {}))
                need[0][p.hash] = why
                need[1][p.hash] = settings
    if not pmap:
        return [], set(), ["--reference: no point of this sweep runs the photon-map pass: no reference to compute"]
    refs, again = [], set()
    for key, (measure, asked) in needed.items():
        settings = strictest(list(asked.values()))
        meta = _cached_meta(key)
        kind = "compute" if meta is None else verdict(meta, settings)
        unmeasured = [h for h, why in measure.items() if why != "again"]
        if kind == "meets":
            action = "cached"
        elif kind != "compute":
            action = "kept"
            if not unmeasured:  # (points done against the one kept: as they were; no line of the sweep's either)
                continue
        else:
            action = "compute" if meta is None else "compute again"
            again |= {h for h, why in measure.items() if why != "run"}
        hashes = measure if kind == "compute" else unmeasured
        points = sum(1 for p in sweep.points if p.hash in hashes)
        refs.append(Reference(key, points, action, _saved_rounds(key) if action.startswith("compute") else 0))
    return refs, again, []


def _saved_rounds(key: str) -> int:
    """The rounds an interrupted compute of reference ``key`` saved (its ``.partial.npz``'s header), which the
    next compute resumes from (a dry run said 'compute' alone, h460); 0 where none are saved or readable."""
    from tlm.experiments.reference_cache import partial_info, partial_path, partial_rounds

    return partial_rounds(partial_info(partial_path(key)))


def _cached_meta(key: str) -> dict | None:
    """The ``meta.json`` of the cached reference ``key`` where the entry is whole (its fields of their types, its
    seal, :func:`~tlm.fingerprint.seal_state`, or none where an older tlm wrote it, its ``reference.npy`` the file
    the metadata describes), else None: read only (a damaged one is neither said nor
    removed here: the sweep's own read does both, and computes it again). Looked at, not used: its files' access
    times stay as they were (:func:`~tlm.experiments.frame_keys.looked`), which ``tlm cache prune`` reads as their
    last use (a ``--dry-run --reference`` made a reference unused for 40 days used now)."""
    from tlm.caches import fields_problem
    from tlm.experiments.frame_keys import looked
    from tlm.experiments.reference_cache import META_FIELDS, META_FORMAT, META_OPTIONAL, cache_dir
    from tlm.fingerprint import seal_state

    folder = cache_dir() / key
    try:
        meta = json.loads(looked(folder / "meta.json").decode("utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(meta, dict) or meta.get("key", key) != key or fields_problem(meta, META_FIELDS, META_OPTIONAL):
        return None
    if seal_state(meta, META_FORMAT, "reference") not in (("older", None), (None, None)):  # (its seal, as read)
        return None  # (damaged, or another tlm's: computed again)
    npy = meta.get("npy")
    if not isinstance(npy, dict) or not isinstance(npy.get("size"), int):
        return None
    try:
        got = looked(folder / "reference.npy", digest=True)
    except OSError:  # (gone, unreadable, a folder in its place)
        return None
    return meta if (got["size"], got["sha256"]) == (npy["size"], npy.get("sha256")) else None


def _stale(out: Path) -> int:
    """The temporary folders and files that sweeps of this machine now gone (killed) left in ``out``, which
    a sweep into it removes: in ``points/`` (a point's half-written folder), beside the rows (``sweep.csv``,
    ``sweep.jsonl``) and in ``.references`` (the copies of references held, ``--reference``); as
    :func:`~tlm.storage.clean_stale` tells them (another machine's and a live process's are kept)."""
    return (len(storage.stale_folders(out / "points")) + len(storage.stale_files(out))
            + len(storage.stale_folders(out / HELD, "held")))
