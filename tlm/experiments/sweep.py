"""Sweeps: a base run config copied over a product of factors, one folder per point.

A sweep file (``tlm sweep FILE``)::

    description: FIFO depth against page-miss cost
    base: cornell.yaml            # a run config file (relative to this file) or a mapping
    set: {mode: rcast}            # dotted keys applied to base, for every point
    grid:                         # the full product; the first key varies slowest
      arch.fifo_depth: [1, 16, 256, 1024]
      arch.page_miss_cycles: [0, 12, 48]
    zip:                          # lists of one length, taken together
      seed: [0, 1]
      render.light_samples: [1, 4]

Points are product(grid) x zip: every combination of the grid with every zip column,
zip varying fastest. Any config key may be a factor by its dotted path, and every
point's config goes through the run config's checks before any point runs
(:mod:`tlm.experiments.sweep_file` reads, checks and keys the points). Relative
paths in the base config (``scene``, ``arch.programs``) start at its folder when
``base`` is a file, else at the sweep file's folder; an ``arch.programs`` the sweep
file itself gives (``set``, ``grid``, ``zip``) starts at the sweep file's folder, and a
``scene`` it gives is looked for from the base config's folder, then the working folder.
``tlm sweep --set KEY=VALUE`` (``overrides``) sets a key of the base after ``set``, before the
factors (one of a factor's key is refused), as ``tlm run --set`` does: its paths from the working folder.

A point is keyed by the hash of its resolved config, of the content of the files it
names (the scene and its meshes, through the functional key; the programs table) and
of tlm's code, so a rerun (or another sweep into the same folder) skips the points
already done, and recomputes those whose inputs changed. Output folder::

    sweep.yaml               the sweep as resolved: base, set, the --set strings (overrides),
                             factors, every point's hash
    sweep.jsonl              one row per point, appended as points finish (a killed sweep
                             keeps them, its last row perhaps cut off); rewritten sorted
                             when the sweep ends, or is stopped (Ctrl-C, SIGTERM, its
                             cluster lost, a point's full disk: the points done, _write_finished)
    sweep.csv                the same rows, one column per field, written then too (a
                             factor's null value as null)
    points/<hash>/           config.resolved.yaml (the arch.trace the point ran with),
                             results.json, and trace.json only where the sweep asks for
                             arch.trace: true (its base, set, a factor or a --set; else the
                             point runs with it false; its hash holds it as true but where a
                             factor gives it, so a rerun that asks for a trace runs only the
                             points done without one: point_done); or error.json when the
                             point failed (retried by a rerun)
    workers.json             a Dask sweep's events on its workers: one left out, why, its points sent again
                             and where they ran (only where one happened: sweep_rows.keep_worker_events),
                             of each run of the sweep into the folder (a sweep of other points removes it)
    report/                  tlm sweep's report, after its points: an earlier one goes as a sweep claims the folder,
                             but where it is of the rows the sweep leaves (sweep_folder.drop_report)

A point renders nothing that another point rendered: points that differ only in
``arch`` (or in settings their mode never reads: ``photons.count`` in mode rcast) share one
functional result (:mod:`tlm.arch.functional`; docs/design.md, "Why
the seam makes sweeps cheap"). One point per functional result goes first; the others
follow once it is cached, so two
workers never render the same frame. Workers: a local process pool, or Dask. A local
worker ends itself when the sweep's process dies (a killed sweep leaves none running);
a worker that dies (a crash, an OOM kill) costs the sweep only the point it ran, if that
point kills its worker again when run alone (:class:`LocalPool`). A Dask worker checks
first that it sees the sweep's folder and input files (and, a remote one, that it runs
the sweep's code: :func:`~tlm.experiments.sweep_point._check_worker_sees`, and reads the
content the sweep read: :func:`~tlm.experiments.sweep_point._check_worker_inputs`), and that it
runs the sweep's numpy, numba, Python and kernels
(:func:`~tlm.experiments.dask_workers.check_worker_versions`); a point records the
versions of the process that ran it. A lost scheduler stops the sweep with one line
(:class:`~tlm.experiments.executors.DaskPool`). One point, as a worker runs it:
:mod:`tlm.experiments.sweep_point`. The rows: :mod:`tlm.experiments.sweep_rows`. Its photon-map
references (``--reference``) and the line on its points without an image error:
:mod:`tlm.experiments.sweep_reference`.
"""

from __future__ import annotations

import concurrent.futures as cf
import math
import numbers
import os
import queue
import re
import shutil
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterable
from contextlib import ExitStack, suppress
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from tlm import claims, storage
from tlm.caches import CACHE_WARNING, cache_warnings, cache_warnings_held
from tlm.errors import EnvironmentFailure, InputError, interrupted_by
from tlm.experiments import sweep_rows as _kept  # (what an interrupted sweep's line says it kept)
from tlm.experiments.dask_workers import machine_lines
from tlm.experiments.executors import (
    DASK_POLL,
    DaskPool,
    InProcess,
    LocalPool,
    SweepStopped,
    kernel_threads,
    open_executor,
    take_finished,
)
from tlm.experiments.executors_dask import killed_worker_line as _killed_worker_line
from tlm.experiments.frames import forget_last_frame, is_cached
from tlm.experiments.loading import keeping_accel
from tlm.experiments.provenance import code_state, versions
from tlm.experiments.run_warnings import sweep_jobs_line
from tlm.experiments.run_warnings import sweep_threads_line as threads_line
from tlm.experiments.sweep_file import Point, load_sweep
from tlm.experiments.sweep_folder import drop_report, earlier_sweep, other_folders_line, other_names, rows_dated
from tlm.experiments.sweep_point import (
    MARKER,
    Task,
    error_record,
    finished,
    run_point,
    scene_checks,
    write_error,
)
from tlm.experiments.sweep_point import seen_here as _seen_here  # (kept importable from here: tests)
from tlm.experiments.sweep_reference import (
    Held,
    clean_held,
    done_record,
    drop_references,
    held_root,
    hold_references,
    listed,
    point_done,
    sweep_references,
    unmeasured_line,
)
from tlm.experiments.sweep_rows import columns, forget_worker_events, keep_worker_events, point_row, write_rows
from tlm.experiments.worker_start import leave_if_bootstrapping
from tlm.progress import SWEEP_ETA_AFTER, checkpoint, progress_bar
from tlm.storage import check_destination, claim_folder
from tlm.storage_errors import says_disk_full


@dataclass
class Outcome:
    """What a sweep did: the rows of its points and the counts of the summary line."""

    rows: list[dict]
    ok: int
    failed: int
    skipped: int
    renders: int  # points whose functional result was rendered, not read from the cache
    seconds: float
    out: Path
    # the sweep's own warnings (run_sweep prints none; tlm sweep does): its factors and --set strings that
    # no point read (Sweep.inert_factors, inert_sets, before the points run; Sweep.unread_factors, after); the caches
    # its workers could not write; point folders that are not its points; a given render.threads past the CPUs (alone
    # or times --jobs, as it starts; a Dask machine's, once per machine after the points: dask_workers.machine_lines)
    warnings: list[str] = field(default_factory=list)
    # folders in points/ that are not this sweep's points (an earlier run of other code or config)
    other_folders: int = 0

    @property
    def table(self):
        """The rows as a pandas DataFrame, one row per point in point order, the columns as in
        ``sweep.csv`` (:func:`~tlm.experiments.sweep_rows.columns`: the point, its hash, status and
        error, then every other field as it first appears: the factors, ``scene``, ``mode``,
        ``cycles.*``, ``fps``, utilization, host seconds; those of an ok point even when no point
        is ok)."""
        import pandas as pd

        rows = sorted(self.rows, key=lambda r: r["point"])
        return pd.DataFrame(rows, columns=columns(rows))


def _clean_stale(points_dir: Path) -> None:
    """Remove temporary point folders of sweeps that were killed (their process is gone), and the
    temporary files of the rows (sweep.csv, sweep.jsonl) such a sweep left beside them."""
    storage.clean_stale(points_dir)
    storage.clean_stale_files(points_dir.parent)


def _inputs(config: dict, folder: Path, source: str) -> tuple[str, ...]:
    """The files a point's config names that are not tlm's own (those a worker has in its
    own install): its scene file and its programs table, absolute."""
    from tlm.scenes.loader import resolve_scene_path, scenes_dir

    found = []
    with suppress(InputError, OSError):  # (checked when the sweep was loaded)
        scene = Path(resolve_scene_path(config["scene"], folder, source))
        if not scene.resolve().is_relative_to(scenes_dir().resolve()):
            found.append(os.path.abspath(scene))
    table = (config.get("arch") or {}).get("programs")
    if table is not None:
        found.append(os.path.abspath(folder / table))  # (an absolute table stays itself)
    return tuple(found)


def _table_digest(config: dict, folder: Path, seen: dict[str, str | None]) -> str | None:
    """The sha256 of the text of the point's ``arch.programs`` table (None for tlm's own, part of
    the code; or for one unreadable since the sweep was loaded: its worker's load says why),
    each table read once (``seen``)."""
    from tlm.config import read_text, text_digest

    table = (config.get("arch") or {}).get("programs")
    if table is None:
        return None
    if table not in seen:
        seen[table] = None
        with suppress(InputError, OSError):
            seen[table] = text_digest(read_text(folder / table))  # (an absolute table stays itself)
    return seen[table]


def run_sweep(path: Path, out: Path, jobs: int | None = None, dask: str | None = None,
              progress: bool = False, dask_wait: float | None = None,
              warn: Callable[[str], None] | None = None, overrides: Iterable[str] = (), reference: bool = False,
              say: Callable[[str], None] | None = None, check: Callable[[Any, Path], None] | None = None) -> Outcome:
    """Run every point of the sweep file ``path`` not already done in ``out``. ``overrides``: the
    ``dotted.key=value`` strings of ``tlm sweep --set``, applied to the base config of every point
    before its factors (:func:`~tlm.experiments.sweep_file.load_sweep`): part of each point's config,
    and so of its hash (a rerun into ``out`` with other ones runs the points they change again), and
    listed in ``sweep.yaml`` (``overrides``). ``dask_wait``
    (with ``dask`` only): the seconds the sweep waits while its Dask scheduler has no worker
    before it stops (:class:`SweepStopped`); None: :data:`~tlm.experiments.executors.NO_WORKERS_WAIT`.
    ``jobs`` with a remote scheduler (``dask`` an address) is refused: its workers are the
    cluster's. ``warn`` gets each of the sweep's warning lines as it is known (its factors' lines
    before the points run, the others after them); None: none is printed, and every one is in
    :attr:`Outcome.warnings` (``tlm sweep`` prints them). ``reference`` (``tlm sweep --reference``): before
    the points, each photon-map reference that the points to run (and those done without an error) need and
    the cache lacks, or holds short of its tolerance where more rounds are allowed (as ``tlm reference``
    decides), is computed and cached (:func:`~tlm.experiments.sweep_reference.sweep_references`;
    ``say`` gets its lines, as ``tlm reference`` prints them, and ``progress`` its rounds' bar), so that
    they are measured as after a ``tlm reference``, against a copy of it that the sweep holds in ``out`` while
    they run (:func:`~tlm.experiments.sweep_reference.hold_references`: one the cache could not take, or pruned
    meanwhile, measures them all the same; what a killed sweep left there, every sweep into ``out`` removes,
    :func:`~tlm.experiments.sweep_reference.clean_held`); one that fails is a warning and its points run without
    their error. ``check``: the sweep file's data's (:func:`~tlm.experiments.sweep_file.load_sweep`)."""
    leave_if_bootstrapping()  # (a worker re-running a script that sweeps as it is imported touches no folder)
    t_start = time.perf_counter()
    # (the Dask address's form, even where every point is done and no scheduler is reached)
    dask, dask_wait = checked_options(jobs, dask, dask_wait)
    remote = dask not in (None, "local")  # (its workers check that they run the sweep's code and read its inputs)
    if jobs is None:
        from tlm.kernels.threads import available

        jobs = available()  # (the affinity mask and a container's CPU quota; not render.threads' cap of 8)
    from tlm.experiments.provenance import kernels_here
    from tlm.kernels.threads import fork_workers

    # (a bad TLM_KERNELS or TLM_FORK_WORKERS refused once, before any point; numba not imported for it where it is
    # sure to import: a sweep whose frames are all cached runs no kernel)
    kernels_here(), fork_workers()
    sweep = load_sweep(Path(path), overrides, check)  # loads every distinct programs table and scene
    out = Path(out)
    check_destination(out, MARKER)  # before anything is written or said: a bad --out is its one line
    earlier = earlier_sweep(out)  # (the folder's sweep.yaml before this sweep's: what its stale points' line names)
    said = [*sweep.inert_factors(), *sweep.inert_sets()]  # (a factor, or a --set, that no point reads)
    said += [] if remote else threads_line(sweep.points, str(sweep.path))  # (its points cached or not)
    for line in said if warn is not None else ():
        warn(line)
    fkeys = {p.hash: p.functional for p in sweep.points}
    points_dir = out / "points"
    hold: dict[str, Held] = {}  # the references the points are measured against, which the sweep holds
    if reference:  # (before the points are read: one done without an error is measured now)
        with _kept.noting_kept(lambda: _kept.rows_kept(out, fkeys), len(sweep.points)):  # (an earlier run's rows)
            failed_refs = sweep_references(sweep, points_dir, say, progress, hold)
        said += failed_refs
        for line in failed_refs if warn is not None else ():
            warn(line)

    by_hash: dict[str, list[Point]] = {}
    for p in sweep.points:
        by_hash.setdefault(p.hash, []).append(p)
    records: dict[str, dict] = {}
    todo: list[str] = []
    present = listed(points_dir)  # (a point with no folder is not done: no read of it)
    for h in by_hash:
        rec = point_done(points_dir / h, by_hash[h][0]) if h in present else None
        if rec is not None:
            records[h] = rec
        else:
            todo.append(h)
    skipped = sum(len(by_hash[h]) for h in records)

    provenance = {"versions": versions(), **code_state()}
    # --jobs x render.threads <= the CPUs: a point that leaves render.threads null gets its
    # worker's share of them (its key does not depend on it: config_hash)
    share = kernel_threads(jobs, dask, len(todo))
    if dask is None and warn is not None:  # (--jobs x a given render.threads past the CPUs: once, as it starts)
        for line in sweep_jobs_line([by_hash[h][0] for h in todo], min(jobs, len(todo))):
            said.append(line)
            warn(line)
    where = os.path.abspath(points_dir)  # (a Dask worker's working folder is not this one)
    tables: dict[str, str | None] = {}  # arch.programs -> the sha256 of its text (each table read once)
    scenes: dict[str, str] = {}  # a scene -> the files its load read (each scene loaded once: scene_checks)
    tasks = {h: Task(h, by_hash[h][0].config, by_hash[h][0].factors, str(sweep.folder), str(sweep.path),
                     os.path.join(where, h), provenance, threads=share,
                     inputs=_inputs(by_hash[h][0].config, sweep.folder, str(sweep.path)),
                     code=provenance["code_fingerprint"] if remote else None, functional=fkeys[h],
                     programs=_table_digest(by_hash[h][0].config, sweep.folder, tables) if remote else None,
                     own_code=provenance["code_fingerprint"] if dask == "local" else None,
                     scene_files=scene_checks(by_hash[h][0].config, sweep.folder, str(sweep.path), scenes)
                     if remote else "", running=len(todo))
             for h in todo}

    rows_due = False  # (the folder is this sweep's: its rows are written, when it ends and when it is cut short)
    pool, workers_kept = None, False  # (workers_kept: its workers' events written, not again as the pool closes)
    with ExitStack() as held:  # (the folder, held until the last row is written)
        held.callback(forget_last_frame)  # (the frame an in-process point read last: not kept after the sweep)
        held.enter_context(keeping_accel())  # (the BSP its last render built, kept for the next: not after it)
        try:
            with ExitStack() as stack:
                pool = open_executor(stack, jobs, dask, len(todo), dask_wait) if todo else None
                # the folder and its marker appear together, before anything else is written in it
                # (and only once the executor opened: a bad --dask leaves nothing): a second sweep
                # into it, started this instant, finds a tlm output, never a half-made folder. A
                # sweep of other points running into it refuses this one (claims.sharing); one of
                # the same points shares it
                marker = sweep.marker()
                made = claim_folder(out, MARKER, marker, existing=False)
                # (refused there, by a run or a study that claimed the folder after this sweep's check: the folder
                # and sweep.yaml this made go, h422)
                held.enter_context(claims.sharing(out, sweep.identity(), "sweep", made=MARKER if made else None))
                rows_due = True
                if not made:
                    storage.write_file(out / MARKER, marker)
                # (an earlier report, not of the rows from now on, as tlm run's goes; one of them kept)
                gone = drop_report(out, current=not todo and earlier is not None and earlier.text == marker)
                said += [gone] if gone else []
                if gone and warn is not None:
                    warn(gone)
                points_dir.mkdir(parents=True, exist_ok=True)
                forget_worker_events(out, sweep.identity())  # (those of another sweep into the folder before)
                _clean_stale(points_dir)
                clean_held(out)  # (the copies of references that killed sweeps left: --reference or not)
                present = listed(points_dir)
                for h in todo:  # a failed point's folder (or an unreadable one) is run again
                    # (another sweep into this folder may be replacing it). A finished one run again (for the
                    # trace.json it now asks for, or measured again) stays until its new folder replaces it
                    # (run_point's atomic_folder, which carries a user's files over): an interrupt loses nothing
                    if h in present and finished(points_dir / h) is None:
                        shutil.rmtree(points_dir / h, ignore_errors=True)
                if hold:  # (--reference: a copy of each its points to run need, for them to read while they run)
                    root = held_root(out)  # (named, and its removal registered, before anything is written there)
                    held.callback(drop_references, root)
                    folders, lines = hold_references(hold, root, todo)  # (hold emptied: no image kept in memory)
                    said += lines
                    for line in lines if warn is not None else ():
                        warn(line)
                    tasks = {h: replace(t, references=tuple(sorted(folders.items()))) for h, t in tasks.items()}
                if pool is not None:
                    # the rows of this sweep's points done already, in place of an earlier sweep's: while
                    # it runs (and when it is cut short) the folder's rows are this sweep's only
                    _write_rows(out, [_row(p, records[p.hash], sweep) for p in sweep.points if p.hash in records],
                                sweep)
                    _dispatch(pool, tasks, fkeys, by_hash, records, out, progress, len(sweep.points), skipped,
                              lambda p, record: _row(p, record, sweep))
                    lost = pool.lost() if isinstance(pool, DaskPool) else []  # (a worker that left with points)
                    said += lost
                    for line in lost if warn is not None else ():
                        warn(line)
                    _keep_workers(out, pool, records, sweep.identity())  # (those lines' events: workers.json)
                    workers_kept = True
        except BaseException as e:  # (interrupted, or the cluster lost: its workers are gone once the
            # executor closed; what one killed mid-point left half written goes, as after a run)
            if todo:
                _clean_stale(points_dir)
            if not rows_due:  # (before the folder was claimed: the rows an earlier run kept there, failed ones too)
                kept = _kept.rows_kept(out, fkeys)
            else:  # the rows of the points done, as a run to its end writes them
                kept = _write_finished(out, sweep, records, todo)
                with suppress(Exception):  # (what stopped the sweep is said, not a failed write of these)
                    if not workers_kept:  # (an interrupt while the executor closed: the events written already)
                        _keep_workers(out, pool, records, sweep.identity())
            _kept.note_kept(e, kept, len(sweep.points))  # (an interrupt's line says them: cli_report.sweep_cut_short)
            raise
        if todo:
            _clean_stale(points_dir)  # what workers that died (or were ended) left half written

        rows = [_row(p, records[p.hash], sweep) for p in sweep.points]
        _write_rows(out, rows, sweep)
    with _kept.noting_kept(lambda: rows, len(rows)):  # (an interrupt now: every row written, the line says them)
        computed = [r for r in rows if r["hash"] in tasks]
        failed = sum(r["status"] != "ok" for r in computed)
        renders = len({r["hash"] for r in computed if r.get("functional_cached") is False})
        unread = sweep.unread_factors([(p, records[p.hash]["results"]) for p in sweep.points
                                       if records[p.hash]["status"] == "ok"])
        unread += unmeasured_line(sweep, records, out, reference)
        with cache_warnings_held():  # (the caches as they are now, said below through warn: a line a point of this
            # process met, held, reaches warn too)
            caches = _cache_lines([records[h] for h in tasks], cache_warnings())
        # (a given render.threads past a Dask machine's CPUs at its points at once, or a remote one's alone: once per
        # machine, as its points said it)
        machines = machine_lines(w for h in tasks for w in (records[h].get("results") or {}).get("warnings") or [])
        names = other_names(points_dir, by_hash)  # (said last: next to the summary line it qualifies)
        other = len(names)
        stale = [other_folders_line(other, points_dir, earlier, sweep, provenance["code_fingerprint"], names)
                 ] if other else []
        if warn is not None:
            for line in [*machines, *unread, *caches, *stale]:
                if line not in caches or " ".join(line.split()) not in storage.SAID:  # (a cache's: said once)
                    warn(line)
        return Outcome(rows, len(computed) - failed, failed, skipped, renders, time.perf_counter() - t_start, out,
                       [*said, *machines, *unread, *caches, *stale], other)


def checked_options(jobs: int | None, dask: str | None,
                    dask_wait: float | None) -> tuple[str | None, float | None]:
    """``--jobs``, ``--dask`` and ``--dask-wait`` checked, for :func:`run_sweep` and ``tlm sweep --dry-run``
    (:func:`~tlm.experiments.sweep_plan.plan_sweep`): the Dask address (None: no Dask) and the wait in
    seconds (None: the default)."""
    dask = _dask_address(dask)
    if jobs is not None and dask not in (None, "local"):
        raise InputError(f"{jobs} with --dask {dask}: the points run on that scheduler's workers, as many at once "
                         "as they have threads, which the cluster sets (dask worker --nthreads), not the sweep; "
                         "leave --jobs out", key="--jobs")
    if jobs is not None and jobs < 1:
        raise InputError(f"{jobs} must be >= 1", key="--jobs")
    return dask, None if dask_wait is None else _wait_seconds(dask_wait, dask)


# a transport's name before ``://`` (distributed's tcp, tls, ws, wss, ucx, and a plugin's, such as ucxx)
DASK_SCHEME = re.compile(r"[A-Za-z][A-Za-z0-9+.-]*")


def _dask_address(dask: Any) -> str | None:
    """``--dask``: None, ``local``, or a scheduler's address of the form ``tcp://HOST:PORT``
    (``HOST:PORT`` is tcp's, as for Dask; ``tls://``, ``ws://``, ``ucx://``, a plugin's transport
    and ``inproc://`` too), its port a whole number 1 to 65535; else an :class:`InputError`, as is a
    dashboard's ``http(s)://`` address (Dask prints it beside the scheduler's). Its form
    only: the scheduler is reached when there are points to run (:func:`open_executor`)."""
    if dask is None or dask == "local":
        return dask
    fix = "give local (a LocalCluster of --jobs workers) or a Dask scheduler's address, tcp://HOST:PORT"
    if not isinstance(dask, str):
        raise InputError(f"{dask!r} is not a Dask scheduler's address: {fix}", key="--dask")
    if dask.strip().lower() == "local":
        raise InputError(f"{dask!r} is not local, the only name --dask takes (lower case): {fix}", key="--dask")
    scheme, sep, rest = dask.partition("://")
    if not sep:
        scheme, rest = "tcp", dask
    if scheme.lower() in ("http", "https"):  # (the one Dask prints beside the scheduler's: "dashboard at")
        raise InputError(f"{dask!r} is the address of a Dask dashboard (a web page), not of a scheduler: give the "
                         "scheduler's, tcp://HOST:8786 or the one 'dask scheduler' printed (Scheduler at: ...), "
                         "or local", key="--dask")
    if scheme == "inproc" and rest.strip() and rest == rest.strip():
        return dask
    host, colon, port = rest.rpartition(":")
    if host.startswith("[") and host.endswith("]"):  # (an IPv6 address: [::1]:8786)
        host = host[1:-1]
    well_formed = (DASK_SCHEME.fullmatch(scheme) is not None and colon and host and port.isascii() and port.isdigit()
                   and not any(c.isspace() or c in "/?#@" for c in host))
    if not well_formed:
        raise InputError(f"{dask!r} is not a Dask scheduler's address: {fix}", key="--dask")
    if not 1 <= int(port) <= 65535:
        raise InputError(f"{dask!r}: its port {port} is not a port (1 to 65535): {fix}", key="--dask")
    return dask


def _wait_seconds(value: Any, dask: str | None) -> float:
    """``--dask-wait``: a finite number of seconds > 0, for a sweep on Dask."""
    if dask is None:
        raise InputError(f"{value}: a wait for Dask workers, but the sweep does not run on Dask (give --dask "
                         "local or --dask tcp://HOST:PORT, or leave --dask-wait out)", key="--dask-wait")
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value) or value <= 0:
        raise InputError(f"{value!r} is not a wait: give the seconds a sweep waits while its Dask scheduler has no "
                         "worker, a finite number > 0", key="--dask-wait")
    return float(value)


def _cache_lines(records: list[dict], here: list[str]) -> list[str]:
    """The lines on tlm's caches that could not be written: this process's (``here``, most
    said as they were met: :func:`tlm.caches.cache_failed`) and the points' (their workers keep
    them: :func:`run_point`), each once."""
    lines = list(here)
    for rec in records:
        for line in (rec.get("results") or {}).get("warnings") or []:
            if isinstance(line, str) and line.startswith(CACHE_WARNING) and line not in lines:
                lines.append(line)
    return lines


def _write_finished(out: Path, sweep, records: dict[str, dict], todo: list[str]) -> list[dict] | None:
    """``sweep.jsonl`` and ``sweep.csv`` of a sweep cut short (interrupted, its cluster lost): the
    rows of its points done, those done before and those its workers finished (a point whose
    worker wrote its folder whole before the sweep took its result is done too; one done before without
    the trace.json it now asks for too, its folder kept till its new one replaces it), as the end of a
    run writes them: the records of their rows, one per row. A write that fails leaves the files as they were
    (each is written whole or not at all): None, the sweep's own error goes on, and ``sweep.jsonl`` holds the rows
    appended."""
    points_dir = out / "points"
    present = listed(points_dir)
    for h in todo:  # (and one done before without the trace.json it now asks for, not run again yet: its folder
        # kept, its results its row's, point_done aside)
        if h not in records and h in present and (rec := done_record(points_dir / h)) is not None:
            records[h] = rec
    kept = [p for p in sweep.points if p.hash in records]
    with suppress(OSError, InputError):
        _write_rows(out, [_row(p, records[p.hash], sweep) for p in kept], sweep)
        return [records[p.hash] for p in kept]
    return None


def _row(point: Point, record: dict, sweep) -> dict:
    """The point's row (:func:`~tlm.experiments.sweep_rows.point_row`), its ``scene`` as the sweep
    gives it, for the researcher's tables: a ``scene`` factor's value, a ``--set scene``'s (a path from
    the working folder, as ``tlm run --set`` reads it), or the one ``set`` gives, as written; else (the
    base config's) the scene file's path from the sweep file's folder (posix, ``../scenes/box.yaml``), a
    built-in scene's name as it is. The point's config names the file by its absolute path, for the
    workers (and its ``config.resolved.yaml``, which runs from anywhere); a path on the table would name
    where the project lay, not which file."""
    row = point_row(point, record)
    if "scene" in point.factors:  # (its factor column too: one column, the value as written)
        row["scene"] = point.factors["scene"]
    elif sweep.overridden("scene") and isinstance(given := _set_scene(sweep.overrides), str):
        row["scene"] = given  # (as the --set gives it: a path from the working folder, as 'tlm run --set' reads it)
    elif "scene" in sweep.set and not sweep.overridden("scene"):
        row["scene"] = sweep.set["scene"]
    elif isinstance(scene := row.get("scene"), str) and os.path.isabs(scene):
        with suppress(ValueError):  # (another drive: no path from there; the absolute path stays)
            row["scene"] = Path(os.path.relpath(scene, sweep.path.resolve().parent)).as_posix()
    return row


def _set_scene(overrides: Iterable[str]) -> Any:
    """The value of the last ``--set scene=...`` of ``overrides`` as written, read as the run's ``--set`` reads it
    (:func:`~tlm.config.read_set_value`: a byte not UTF-8 kept, ``scene=dir_\\xff/x.yaml``), or None."""
    import yaml

    from tlm.config import read_set_value
    from tlm.experiments.study import override_key

    given = [str(o).partition("=")[2] for o in overrides if override_key(str(o)) == "scene"]
    with suppress(yaml.YAMLError):
        return read_set_value(given[-1]) if given else None
    return None


def _keep_workers(out: Path, pool, records: dict[str, dict], sweep: str) -> None:
    """A Dask sweep's events on its workers (a worker left out, why, its points sent again and where they ran, ...:
    :meth:`~tlm.experiments.executors_dask.WorkerWatch.worker_events`) kept in its folder, ``workers.json``, after
    those of the earlier runs of the sweep (``sweep``: its identity) into it."""
    if isinstance(pool, DaskPool) and hasattr(pool, "watch"):
        keep_worker_events(out, pool.watch.worker_events(records), sweep)


def _write_rows(out: Path, rows: list[dict], sweep) -> None:
    """The ``sweep``'s rows (:func:`~tlm.experiments.sweep_rows.write_rows`, under the rows' lock, another run's of
    its points kept: h471); with no row, which would name them, its factors name the CSV's factor columns."""
    with _kept.rows_held(out), rows_dated(out):  # (rows unchanged: their time too, h493)
        rows = [*rows, *_kept.others_rows(out, rows, {p.hash: p.index for p in sweep.points})]
        write_rows(out, rows) if rows else write_rows(out, rows, sweep.factors)


def _dispatch(pool: cf.Executor, tasks: dict[str, Task], fkeys: dict[str, str], by_hash: dict[str, list[Point]],
              records: dict[str, dict], out: Path, progress: bool, total: int, skipped: int,
              row: Callable[[Point, dict], dict] = point_row) -> None:
    """Run the tasks: one per functional key first, the rest of its group once it is cached.
    ``row``: a point's row (``sweep.jsonl``) of its record (:func:`_row`).

    A point's future, once done, enters the queue ``finished`` (its done-callback): the loop
    takes the points as they finish, at a constant cost each, where ``cf.wait`` on every
    future in flight cost the sweep a time quadratic in its points."""
    groups: dict[str, deque[str]] = {}
    for h in tasks:
        groups.setdefault(fkeys[h], deque()).append(h)
    futures: dict[cf.Future, str] = {}
    finished: queue.SimpleQueue[cf.Future] = queue.SimpleQueue()

    def submit(h: str) -> None:
        f = pool.submit(run_point, tasks[h])
        futures[f] = h
        f.add_done_callback(finished.put)

    def release(key: str, everything: bool) -> None:
        group = groups[key]
        while group:
            submit(group.popleft())
            if not everything:
                break

    # a remote cluster's workers have caches of their own: this machine's says nothing of them
    remote = isinstance(pool, DaskPool) and pool.remote
    bar = None
    try:
        for key in groups:
            release(key, everything=is_cached(key) and not remote)
        bar = progress_bar(progress, eta_after=SWEEP_ETA_AFTER, total=total, initial=skipped, unit="point",
                           desc="sweep")
        failed = 0
        with _kept.Appender(out) as jsonl:  # (under the rows' lock, the file opened anew: h471; a full disk named)
            while futures:
                checkpoint()  # (a signal whose interrupt got lost stops the sweep here: its workers too, below)
                if isinstance(pool, (InProcess, LocalPool)):
                    pool.run_next()
                done = take_finished(finished, DASK_POLL if isinstance(pool, DaskPool) else None)
                cancelled = [f for f in done if f.cancelled()]  # (by the cluster: the sweep cancelled none)
                full = None  # (a full disk's message: the sweep stops once the points finished with it are taken)
                for f in done:
                    if f in cancelled:
                        continue
                    h = futures.pop(f)
                    record = _record(f, tasks[h])
                    if record["status"] != "ok" and says_disk_full(record["error"]["type"], record["error"]["message"]):
                        full = full or record["error"]["message"]
                        continue
                    if isinstance(pool, DaskPool) and pool.send_again(h, record):  # (its worker left out: the point
                        submit(h)  # to the other workers, once)
                        continue
                    if remote:
                        ok, record = record["status"] == "ok", _seen_here(record, tasks[h])
                        if ok and record["status"] != "ok" and pool.send_again(h, record):  # (its results on its
                            submit(h)  # worker's own disk, not seen here: PathNotOnWorker, sent again as above)
                            continue
                    records[h] = record
                    for p in by_hash[h]:
                        jsonl.write(storage.json_text(row(p, record)) + "\n")
                    jsonl.flush()
                    failed += record["status"] != "ok"
                    # the frame is cached unless the point failed while rendering it (or its
                    # worker died): then the next point of the group renders, one at a time
                    rendered = record["status"] == "ok" or record["error"]["stage"] in ("simulate", "write")
                    release(fkeys[h], everything=rendered)
                    bar.update(len(by_hash[h]))
                    if failed:
                        bar.set_postfix(failed=failed)
                if full is not None:  # (the rows of the points done beside it written, and counted, first)
                    raise _disk_full(full, records, by_hash, total, out)
                if isinstance(pool, DaskPool):  # the cluster itself gone (or without workers): a line, not rows
                    why = pool.trouble(cancelled=bool(cancelled))
                    if why is not None:
                        n_done = sum(len(by_hash[h]) for h, r in records.items() if r["status"] == "ok")
                        raise SweepStopped(
                            f"{why}: the sweep stopped with {n_done} of {total} points done, kept in {out}; "
                            "run it again into that folder to run the others")
    except BaseException:
        for f in futures:
            f.cancel()
        if isinstance(pool, LocalPool):  # the workers are killed, not waited for
            _wait_gone(pool.stop())
            _clean_stale(out / "points")
        elif isinstance(pool, InProcess):
            pool.shutdown(wait=False, cancel_futures=True)
        elif isinstance(pool, DaskPool):  # (a local cluster's workers ended now, not waited for)
            pool.stop()
        else:
            pool.shutdown(wait=False)
        raise
    finally:
        if bar is not None:
            bar.close()
    pool.shutdown(wait=True)


def _disk_full(message: str, records: dict[str, dict], by_hash: dict[str, list[Point]], total: int,
               out: Path) -> EnvironmentFailure:
    """The line that stops a sweep at its first point whose folder could not be written for a full disk (the
    next would fail alike): not that point's failure, which runs again, as an interrupted one does."""
    n_done = sum(len(by_hash[h]) for h, r in records.items() if r["status"] == "ok")
    return EnvironmentFailure(f"{message}: the sweep stopped with {n_done} of {total} points done, kept in {out}; "
                              "with room, run it again into that folder to run the others")


def _wait_gone(pids: list[int], timeout: float = 2.0) -> None:
    """Wait (a little) until the killed workers ``pids`` are gone, so that their temporary
    folders can be told from a live process's."""
    deadline = time.monotonic() + timeout
    while pids and time.monotonic() < deadline:
        pids = [pid for pid in pids if storage.pid_alive(pid)]
        if pids:
            time.sleep(0.02)


def _record(f: cf.Future, task: Task) -> dict:
    """The worker's record, or a failed one when the worker itself died or could not be reached."""
    try:
        return f.result()
    except Exception as e:  # a worker process that died, a Dask KilledWorker, an unpicklable result
        if (stop := interrupted_by(e)) is not None:
            raise stop from e
        error = error_record(e, "worker", "".join(traceback.format_exception(e)))
        if (killed := _killed_worker_line(e)) is not None:
            error["message"] = killed
        with suppress(OSError, InputError):  # the row still says what happened (a full disk: none, the sweep stops)
            if not says_disk_full(error["type"], error["message"]):
                write_error(task, error)
        return {"status": "failed", "error": error}
