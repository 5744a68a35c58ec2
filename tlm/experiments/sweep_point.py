"""One sweep point, as a worker runs it: the :class:`Task` it travels as (plain data), and
:func:`run_point`, which renders (or loads) the point's functional result, simulates it and
writes its folder, ``points/<hash>/`` (``results.json``, ``trace.json`` where its config's ``arch.trace`` is true,
only where the sweep asks for it: :func:`~tlm.experiments.sweep_file.load_sweep`; or ``error.json``:
:func:`write_error`).

A Dask worker first checks that it sees the sweep's folder and input files and, a remote
one, that it runs the sweep's code (:func:`_check_worker_sees`) and reads the content the
sweep read (:func:`_check_worker_inputs`); the versions it runs are checked by
:func:`~tlm.experiments.dask_workers.check_worker_versions`. The sweep that hands the points
out: :mod:`tlm.experiments.sweep`.
"""

from __future__ import annotations

import json
import os
import time
import traceback
from contextlib import suppress
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from tlm import storage
from tlm.caches import cache_warnings, cache_warnings_held
from tlm.config import config_from_dict
from tlm.config_words import CDumper, dump_yaml
from tlm.errors import InputError, interrupted_by
from tlm.experiments.dask_workers import (
    OtherVersionsOnWorker,
    check_worker_versions,
    dask_oversubscribed,
    dask_worker_threads,
    dask_worker_where,
    ran_here,
    worker_versions,
)
from tlm.experiments.error_cost_clock import CompileClock
from tlm.experiments.frames import SUMMARY_KEYS, cached_render
from tlm.experiments.provenance import kernels_here
from tlm.experiments.reference_cache import holding
from tlm.registry import plugins
from tlm.storage import atomic_folder
from tlm.storage_errors import says_disk_full

MARKER = "sweep.yaml"  # marks an output folder as a sweep's
POINT_FORMAT = "sweep-point/1"  # the "tlm" field of a point's results.json


@dataclass(frozen=True)
class Task:
    """What a worker needs to run one point (plain data: it travels to other processes)."""

    hash: str
    config: dict
    factors: dict[str, Any]
    folder: str  # where relative paths start
    source: str  # the sweep file, for messages
    out: str  # the point's folder (absolute: a Dask worker's working folder is not the sweep's)
    provenance: dict  # versions and git revision of the submitting host (a point records its worker's
    # versions, which a Dask worker's must match: check_worker_versions)
    threads: int | None = None  # render.threads where the config leaves it null (the worker's
    # share of the CPUs: speed only, so config.resolved.yaml keeps the config as written)
    inputs: tuple[str, ...] = ()  # the files of the sweep's folders it reads (absolute): a Dask
    # worker checks that it sees them, and the sweep's output folder, before it runs the point
    code: str | None = None  # a remote Dask worker's tlm must have this code fingerprint (the
    # sweep's, part of the point's hash): another version's cycles would be filed under it
    functional: str = ""  # the functional key of the point's frame as the sweep computed it (part of
    # its hash: the scene's content), which a remote Dask worker's own must equal
    programs: str | None = None  # the sha256 of the text of the point's arch.programs table as the sweep
    # read it (None: tlm's own table, part of the code), which a remote Dask worker's must equal
    own_code: str | None = None  # the sweep's code fingerprint, which the code a worker of the sweep's own
    # --dask local cluster imported as it started must have (run_point: else OtherCodeOnWorker)
    references: tuple[tuple[str, str], ...] = ()  # (reference key, folder): the copies of the references the
    # sweep holds in its output folder (--reference), which the point reads first (reference_cache.holding)
    scene_files: str = ""  # the files the sweep's load of the point's scene read, with what told each (JSON of
    # frame_scenes.read_checks: scene_checks), for a remote worker's line on the one that differs there
    running: int = 0  # the points the sweep runs (0: not known): no more run at once on a Dask worker's machine,
    # whatever its task slots (dask_workers.dask_oversubscribed)


def run_point(task: Task) -> dict:
    """Render (or load) the point's functional result, simulate it, write its folder.

    Returns ``{"status": "ok", "results": ...}``, or ``{"status": "failed", "error":
    ...}`` after writing ``error.json``: an exception never leaves the worker.

    A worker of the sweep's own ``--dask local`` cluster (``task.own_code``) is a new interpreter that
    imported tlm from the disk as it started (:func:`~tlm.experiments.dask_workers.dask_setup`, which
    hashes the package then): where the package was edited after the sweep took its fingerprint, the
    worker runs other code than the sweep hashed its points and keys with, and its points fail with
    :class:`OtherCodeOnWorker` naming both fingerprints (filing that code's frames under the sweep's
    key, or under another than the sweep reads, would be wrong either way), as a remote worker's do
    (``task.code``).
    """
    from tlm.arch.model import simulate  # the timing layer is imported where it runs
    from tlm.experiments.run import programs_for, timing_dict
    from tlm.experiments.run_warnings import inert_timing_changes, stream_warnings
    from tlm.render.planner import inert_changes

    stage = "functional"
    where = dask_worker_where()  # (None but in a Dask worker)
    ran_on = ran_here()  # (who runs it: its results.json's "ran", its row's worker, host and pid)
    try:
        # (numba compiling or loading a kernel, first imports: the point's one-off, from t0 on: the worker's checks
        # before its render, a part of its functional seconds, first import the kernels' modules and numba
        # (worker_versions) on a worker's first point, and a remote worker reads the point's scene for its key)
        with _one_off_clock() as clock:
            t0 = time.perf_counter()
            ran, cfg, folder = _checked(task, where)
            # (a cache that cannot be written: the sweep says it once; the references the sweep holds: read first)
            with cache_warnings_held(), holding(dict(task.references)):
                got = cached_render(cfg, folder, task.source)
            t1 = time.perf_counter()
            # (the engine the kernels ran, where they did: engine()'s own answer, not numba's metadata's)
            ran = {**ran, "kernels": kernels_here()}
            stage = "simulate"
            programs = programs_for(cfg, folder)
            timing = simulate(got.functional, programs, cfg.arch)
            t2 = time.perf_counter()
            one_off = clock.within(t0, t2)
        stage = "write"
        summary = got.summary
        # (a user's files carried over; the killed writers' leftovers in points/: looked for at this process's first
        # point, the sweep cleans the folder at its start and end)
        # (an error folder of the same point that a concurrent sweep's failed try put there meanwhile: replaced)
        with atomic_folder(Path(task.out), "results.json", POINT_FILES, clean_once=True,
                           replaces=("error.json",)) as tmp:
            (tmp / "config.resolved.yaml").write_text(config_text(task.config), encoding="utf-8")
            if timing.trace is not None:
                timing.trace.write(tmp / "trace.json", cfg.arch.clock_hz)
            results = {
                "tlm": POINT_FORMAT, "hash": task.hash, "sweep": task.source, "factors": task.factors,
                "seed": cfg.seed, "mode": cfg.mode,
                # (beside the scene: its inputs as this process read them for the frame's key, as a run's results.json
                # records them: frames.cached_render, a frame from the cache too; a Dask worker's, the files it read)
                "scene": summary.get("scene"), "scene_digest": got.scene_digest,
                **{k: summary.get(k) for k in SUMMARY_KEYS},
                # the render's warnings, and this point's own (its render.threads past this process's CPUs; what it
                # sets and never reads; its stream)
                "warnings": [*(summary.get("warnings") or []), *_threads_lines(task, cfg, where), *inert_changes(cfg),
                             *stream_warnings(timing, cfg),
                             *_worker_cache_warnings(task, where)],  # (the caches this worker could not write)
                # the timing keys it changed from their defaults and never read, with why (for the
                # sweep's own line on a factor no point read: Sweep.unread_factors)
                "inert": inert_timing_changes(timing, cfg),
                "cycles": timing.cycles, "fps": timing.fps,
                "timing": timing_dict(timing, cfg.arch, programs),
                "functional": {"key": got.key, "cached": got.cached, "render_host_seconds": summary["host_seconds"]},
                # (one_off: the part of functional and simulate in which numba compiled or loaded a kernel
                # from its cache or a module was first imported, for this point's own work (not another point's
                # in another thread of this process): what the first points pay; write: the point's folder, up to
                # results.json's text, measured below)
                "host_seconds": {"functional": round(t1 - t0, 6), "simulate": round(t2 - t1, 6),
                                 "write": None, "one_off": round(one_off, 6)},
                **task.provenance, "versions": ran,
                # (the classes from outside tlm its config selects, their code's digest: as a run's results.json)
                "plugins": plugins(task.config), "ran": ran_on,
            }
            # (its folder made, config.resolved.yaml, trace.json and the record: all of the write but results.json's
            # own text and the folder's move into place, which come after the seconds they would hold)
            results["host_seconds"]["write"] = round(time.perf_counter() - t2, 6)
            # (strict: inf as null)
            (tmp / "results.json").write_text(storage.json_text(results, indent=2) + "\n", encoding="utf-8")
        return {"status": "ok", "results": results, "worker": where, "ran": ran_on}
    except Exception as e:
        if (stop := interrupted_by(e)) is not None:  # Ctrl-C wrapped by a kernel: the sweep stops
            raise stop from e
        error = error_record(e, stage, traceback.format_exc())
        if where is not None and not isinstance(e, (PathNotOnWorker, OtherCodeOnWorker, OtherInputsOnWorker,
                                                         OtherVersionsOnWorker)):
            # (those say where)
            error["message"] = f"{error['message']} (on {where})"
        if says_disk_full(error["type"], error["message"]):  # (no error.json: the sweep stops on it, the point to run)
            pass
        elif task.code is None:  # (this machine's worker)
            try:
                write_error(task, error, ran_on)
            except Exception as failed:  # (a folder in the way: the row keeps the point's own error, the write's
                # said beside it; nothing leaves the worker)
                lost = error_record(failed, "write", traceback.format_exc())
                if says_disk_full(lost["type"], lost["message"]):  # (a full disk: the sweep stops on it, as on a
                    return {"status": "failed", "error": lost, "worker": where, "ran": ran_on}  # point whose own
                    # write it refused)
                error["message"] = f"{error['message']} (its error.json could not be written: {failed})"
        elif (Path(task.out).parent.parent / MARKER).is_file():  # (a remote worker without the sweep's
            with suppress(OSError, InputError):  # folder makes none: the sweep writes error.json, _seen_here)
                write_error(task, error, ran_on)
        return {"status": "failed", "error": error, "worker": where, "ran": ran_on}


def _checked(task: Task, where: str | None) -> tuple[dict, Any, Path]:
    """The worker's checks before it runs ``task`` (a ``--dask local`` worker's code, a Dask worker's view of the
    sweep's files, its versions and inputs), and what the point runs with: this process's versions (what its
    ``results.json`` records), its config (``render.threads`` sized here where the config leaves it null) and the
    folder its relative paths start from."""
    if task.own_code is not None:  # (a --dask local worker: the code it imported as it started)
        _check_own_code(task.own_code, where)
    ran = worker_versions()  # (the process that runs the point: what its results.json records)
    if where is not None:
        _check_worker_sees(task, where)
        check_worker_versions(task.provenance.get("versions"), ran, where)
    threads = task.threads if task.threads is not None else dask_worker_threads()
    cfg = config_from_dict(_with_threads(task.config, threads), task.source)
    folder = Path(task.folder)
    if where is not None and task.code is not None:
        _check_worker_inputs(task, cfg, folder, where)
    return ran, cfg, folder


def _threads_lines(task: Task, cfg, where: str | None) -> list[str]:
    """The line on the ``render.threads`` the point's config gives past the CPUs available to this process
    (:func:`~tlm.experiments.run_warnings.threads_warning`), said by the process that runs the point, its frame
    cached or not: neither the frame's key nor its cached summary holds the threads or the machine's CPUs
    (:func:`~tlm.experiments.frames.cached_render`). None where the config leaves it null (the worker's share:
    :func:`_with_threads`). A remote Dask worker's (``task.code``) ends ``(on the Dask worker NAME (ADDRESS) on
    host HOST)``, its CPUs its machine's (the sweep says it once per machine as it ends:
    :func:`~tlm.experiments.dask_workers.machine_lines`); a local worker's is the line the sweep says as it starts
    (:func:`~tlm.experiments.run_warnings.sweep_threads_line`), said once. A Dask worker's point adds the line
    where that count, times the points at once on its machine, is past the machine's CPUs
    (:func:`~tlm.experiments.dask_workers.dask_oversubscribed`; the sweep says it once per machine)."""
    from tlm.experiments.run_warnings import threads_warning

    asked = (task.config.get("render") or {}).get("threads")
    if asked is None:
        return []
    lines = threads_warning(cfg)
    lines = lines if where is None or task.code is None else [f"{line} (on {where})" for line in lines]
    # (on a Dask worker: that count times the points at once on its machine past its CPUs, naming the machine)
    return lines + dask_oversubscribed(cfg.render.threads, task.running, local=task.code is None)


def _worker_cache_warnings(task: Task, where: str | None) -> list[str]:
    """The lines on the caches this process could not write (:func:`~tlm.caches.cache_warnings`), a remote Dask
    worker's (``task.code``) ending ``(on the Dask worker ADDRESS on host NAME)``: its cache is its own machine's,
    which the sweep's lines (one each: :func:`~tlm.experiments.sweep._cache_lines`) would not tell from the sweep's
    own. A local pool's worker, or a ``--dask local`` one, has the sweep's ``TLM_CACHE``, and its lines are the
    sweep's own (said once). Each folder is looked at again (the cache as it is for this point: one fixed since a
    point before is said no more), held: the sweep says them."""
    with cache_warnings_held():
        lines = cache_warnings()
    if where is None or task.code is None:
        return lines
    return [f"{line} (on {where})" for line in lines]


_CLOCK = CompileClock()  # (one per process: a Dask worker runs points in threads, each timing its own window)
# The process's clock, running while any point of this process runs (points in threads of one Dask worker share
# it: its hooks are the process's; CompileClock.running counts its users), its spans forgotten when none does.
# Each point counts its own spans alone (CompileClock.running_own: those its work began, on its thread and the
# kernels' pool threads working for it), as tlm run does: not another point's compile in another thread.
_one_off_clock = _CLOCK.running_own


class PathNotOnWorker(OSError):
    """A Dask worker does not see a file or folder of the sweep at the path the sweep gives."""


class OtherCodeOnWorker(RuntimeError):
    """A remote Dask worker runs a tlm whose code is not the sweep's."""


class OtherInputsOnWorker(RuntimeError):
    """A remote Dask worker reads other content than the sweep did for a point: its scene (a
    built-in scene file of its own install, a file or mesh at the sweep's path on a disk of its
    own) or its programs table."""


def _check_own_code(code: str, where: str | None) -> None:
    """A worker of the sweep's own ``--dask local`` cluster runs the code the sweep hashed (``code``):
    else :class:`OtherCodeOnWorker` (the package changed on the disk after the sweep started)."""
    from tlm.fingerprint import code_fingerprint

    if code_fingerprint() != code:
        raise OtherCodeOnWorker(
            f"{where or 'a worker of the sweep'} runs other tlm code than the sweep (code fingerprint "
            f"{code_fingerprint()}, the sweep's {code}): the package changed on the disk after the sweep started; "
            "run the sweep again, and the points done keep their results")


def _check_worker_sees(task: Task, where: str) -> None:
    """In a Dask worker: a remote one runs the sweep's tlm code (else :class:`OtherCodeOnWorker`),
    and the sweep's output folder and the input files the point reads are there at the
    sweep's paths (a worker on another machine sees them only on a shared file system; else
    :class:`PathNotOnWorker`), each named with the worker's address and host."""
    if task.code is not None:
        from tlm.fingerprint import code_fingerprint

        if code_fingerprint() != task.code:
            raise OtherCodeOnWorker(
                f"{where} runs other tlm code (code fingerprint {code_fingerprint()}, the sweep's {task.code}): "
                "install the sweep's tlm on the workers, and restart them after an update of it")
    sweep_dir = Path(task.out).parent.parent
    if not (sweep_dir / MARKER).is_file():
        raise PathNotOnWorker(f"the sweep's output folder {sweep_dir} is not there on {where}, which writes the "
                              "point's folder into it: share that folder with the workers' machines at the same path "
                              "(a shared file system), or give the sweep an output folder they share")
    table = (task.config.get("arch") or {}).get("programs")
    table = None if table is None else os.path.abspath(Path(task.folder) / table)
    for path in task.inputs:
        if not os.access(path, os.R_OK):
            what = "the programs table" if path == table else "the scene file"
            raise PathNotOnWorker(f"cannot read {what} {path} on {where}: copy it to that path on the worker's "
                                  "machine, or share its folder with the workers at the same path (a shared file "
                                  "system)")


def _check_worker_inputs(task: Task, cfg, folder: Path, where: str) -> None:
    """On a remote Dask worker, before the point renders: the programs table it reads holds the
    text the sweep read (the sha256 in ``task.programs``), and its point's frame has the
    functional key the sweep computed (``task.functional``: the scene file and its meshes as this
    worker reads them; a built-in scene is its own install's), else :class:`OtherInputsOnWorker`.
    The point's hash holds both, so a point of other content would be filed under this one's."""
    from tlm.config import read_text, text_digest
    from tlm.experiments.frames import render_key

    fix = "the workers must see the sweep's files as this machine does"
    if task.programs is not None and cfg.arch.programs is not None:
        table = folder / cfg.arch.programs  # (an absolute table stays itself)
        here = text_digest(read_text(table))
        if here != task.programs:
            raise OtherInputsOnWorker(
                f"{where} reads another programs table at {table} (its text's sha256 {here[:16]}, the sweep's "
                f"{task.programs[:16]}): the file differs there; {fix}")
    if task.functional:
        key = render_key(cfg, folder, task.source)  # (remembered: cached_render's own call reads it back)
        if key != task.functional:
            from tlm.scenes.loader import resolve_scene_path

            scene = resolve_scene_path(cfg.scene, folder, task.source)
            raise OtherInputsOnWorker(
                f"{where} sees other inputs for this point (its frame key {key}, the sweep's {task.functional}; "
                f"its scene file {scene}): {_which_differ(task.scene_files, str(scene))}; {fix}")


def scene_checks(config: dict, folder: Path, source: str, seen: dict[str, str]) -> str:
    """The files the sweep's load of the scene of the point of ``config`` reads (the scene file, its ``extends:``
    chain, its meshes with their libraries or buffers), each with what told it then, as JSON
    (:func:`~tlm.experiments.frame_scenes.read_checks`), for :attr:`Task.scene_files`; ``""`` where they cannot be
    told. ``seen``: those of each scene loaded so far (one load each: a remote sweep's, its scenes cached)."""
    from tlm.config import noting_reads
    from tlm.experiments.frame_scenes import read_checks
    from tlm.scenes.loader import load_scene

    ref = config.get("scene")
    key = json.dumps([ref, str(folder)], default=str)
    if key not in seen:
        seen[key] = ""
        with suppress(Exception):  # (a line's detail: a scene that cannot be told says what it did before)
            with noting_reads() as reads:
                load_scene(ref, folder, None, source)
            checks = read_checks(reads)
            seen[key] = json.dumps(checks) if checks else ""
    return seen[key]


def _which_differ(files: str, scene: str) -> str:
    """Which of the sweep's input files (``files``: :func:`scene_checks`'s) differ where this worker reads them
    (the first, and how many more), or that its scene file is another than the sweep's (``scene``: this worker's);
    as before where neither can be told."""
    from tlm.experiments.frame_scenes import tell

    unknown = "the scene file or its meshes differ there"
    try:
        checks = json.loads(files) if files else []
    except ValueError:
        return unknown
    differ: list[str] = []
    for check in checks:
        try:
            now = tell(check)
        except Exception:  # (a file not there, or unreadable: it differs)
            now = None
        then = check[-1]
        if now == then:
            continue
        if check[0] in ("libraries", "listed") and isinstance(then, list):  # ([path, digest] each: the mesh first)
            had = {str(p): d for p, d in then}
            got = {str(p): d for p, d in now} if isinstance(now, list) else {}
            differ += [p for p in had if got.get(p) != had[p]] or [str(check[1])]
        else:
            differ.append(str(then if check[0] == "found" else check[1]))  # (found: the file its extends: found)
    first = [c for c in checks if c and c[0] == "text"]
    if not differ and first and str(first[0][1]) != scene:  # (its scene file is not the one the sweep read)
        return f"the sweep read the scene file {first[0][1]}"
    if not differ:
        return unknown
    more = f" (and {len(differ) - 1} more of the sweep's input files)" if len(differ) > 1 else ""
    return f"the sweep's input file {differ[0]} differs there{more}"


def seen_here(record: dict, task: Task) -> dict:
    """A remote worker's point as this machine sees it: a point its worker wrote where this
    machine does not see it (its own disk, not a shared one) failed, with where it went;
    a failed point's ``error.json`` written here where its worker could not (with who ran it, the record's
    ``ran``, as the worker writes it). The worker's file is told by
    its content, the record's own (:func:`_holds`): a point run again keeps its old folder, whose
    ``results.json`` (or ``error.json`` of an earlier try) is not the worker's."""
    if record["status"] != "ok":
        if not _holds(Path(task.out) / "error.json", record["error"]):
            with suppress(OSError, InputError):
                write_error(task, record["error"], record.get("ran"))
        return record
    if _holds(Path(task.out) / "results.json", record.get("results")):
        return record
    where = record.get("worker") or "its Dask worker"
    error = error_record(PathNotOnWorker(
        f"{where} wrote {task.out}, which this machine does not see (its results are on the worker's machine): "
        "share the sweep's output folder between this machine and the workers' at the same path (a shared file "
        "system), then run the sweep again"), "worker", "")
    with suppress(OSError, InputError):
        write_error(task, error, record.get("ran"))
    return {"status": "failed", "error": error, **({"ran": record["ran"]} if "ran" in record else {})}


def _holds(path: Path, value) -> bool:
    """Whether the JSON file ``path`` here holds ``value`` (a worker's record, as written: strict JSON), or a
    mapping with each of its keys (an ``error.json``: the error with the point's hash and factors)."""
    try:
        here = json.loads(path.read_text(encoding="utf-8"))
        want = json.loads(storage.json_text(value))
    except (OSError, ValueError, TypeError):
        return False
    if isinstance(want, dict) and isinstance(here, dict):
        return all(k in here and here[k] == v for k, v in want.items())
    return here == want


def error_record(e: BaseException, stage: str, tb: str) -> dict:
    return {"type": type(e).__name__, "message": str(e), "stage": stage, "traceback": tb}


def finished(folder: Path) -> dict | None:
    """The ``results.json`` of a point that finished in ``folder``, or None (not run, failed, unreadable, or a
    ``results.json`` that is not this point's: another run written there, an edited file). A finished point may
    still be run again (:func:`~tlm.experiments.sweep_reference.done_record`,
    :func:`~tlm.experiments.sweep_reference.point_done`): its folder stays until the new one replaces it
    (:func:`~tlm.storage.atomic_folder`), so that an interrupt meanwhile loses nothing."""
    try:
        results = json.loads((folder / "results.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not (isinstance(results, dict) and results.get("tlm") == POINT_FORMAT and results.get("hash") == folder.name
            and all(isinstance(results.get(k), dict) for k in ("cycles", "timing", "functional", "host_seconds"))):
        return None
    return results


POINT_FILES = frozenset({"config.resolved.yaml", "results.json", "trace.json", "error.json"})  # (a point writes)


def write_error(task: Task, error: dict, ran: dict | None = None) -> None:
    """The failed point's folder: ``error.json`` (exception, message, traceback; ``ran``, who ran the point, where
    given: :func:`~tlm.experiments.dask_workers.ran_here`) and its config. Where the
    folder holds the point finished before (:func:`finished`: run again for the trace.json it now asks for, or
    to be measured again), its results stay and ``error.json`` is written beside them (where the sweep's row
    points for the whole message); the folder is still run again by a later sweep (its rerun's demand holds),
    and the new folder that replaces it does not carry the file over (:data:`POINT_FILES`). The question and
    the write are one under the folder's lock (:func:`~tlm.storage.write_into`): a concurrent sweep of the same
    point swaps its new folder in before the question or after the write, never between them (no stale
    ``error.json`` beside the good results it swapped in). One it swaps in after a question that found no
    finished point is asked about again under the lock at the error folder's swap (``atomic_folder``'s
    ``into``): ``error.json`` goes beside its results, as above (not a refusal in place of the point's error,
    with the error folder left in ``points/`` as ``<hash>.unsaved-<pid>``)."""
    body = {"hash": task.hash, "factors": task.factors, **error, **({"ran": ran} if ran is not None else {})}
    text = storage.json_text(body, indent=2) + "\n"

    def keep(folder: Path) -> bool:
        return finished(folder) is not None

    if storage.write_into(Path(task.out), "error.json", text, keep):
        return
    with atomic_folder(Path(task.out), "error.json", POINT_FILES, clean_once=True, into=keep) as tmp:
        (tmp / "config.resolved.yaml").write_text(config_text(task.config), encoding="utf-8")
        (tmp / "error.json").write_text(text, encoding="utf-8")


_C_DUMPER = CDumper  # (libyaml's emitter: None where PyYAML was built without it)
KEY_CHARS = 64  # the longest key the C dumper is given (longer ones: the two emitters choose a key's form apart)


def config_text(config: dict) -> str:
    """``config.resolved.yaml``'s text: :func:`~tlm.config_words.dump_yaml` ``(config, sort_keys=False)``
    (``yaml.safe_dump``'s text, a string that tlm's reader takes for a number quoted: ``'1e3'``), by libyaml's
    emitter (:class:`~tlm.config_words.CDumper`, a quarter of the time) where its text is the same: a mapping
    whose keys are printable ASCII of 1 to :data:`KEY_CHARS` characters and whose strings are printable ASCII,
    of plain numbers, booleans, nulls, lists and mappings (:func:`_same_text_in_c`). A string of other
    characters (a path with an accent, a newline) goes through PyYAML's own emitter, as ever: the two fold a
    long double-quoted string, and write an empty or long key, each its own way."""
    if _C_DUMPER is not None and isinstance(config, dict) and _same_text_in_c(config):
        return yaml.dump(config, Dumper=_C_DUMPER, sort_keys=False)
    return dump_yaml(config, sort_keys=False)


def _printable(text: str) -> bool:
    return text.isascii() and text.isprintable()


def _same_text_in_c(value: Any, depth: int = 0) -> bool:
    """Whether ``value`` is of what :func:`config_text` gives libyaml's emitter (see there)."""
    kind = type(value)
    if kind is str:
        return _printable(value)
    if kind in (int, float, bool) or value is None:
        return True
    if depth > 32:
        return False
    if kind is list:
        return all(_same_text_in_c(v, depth + 1) for v in value)
    if kind is dict:
        return all(type(k) is str and 0 < len(k) <= KEY_CHARS and _printable(k) and _same_text_in_c(v, depth + 1)
                   for k, v in value.items())
    return False


def _with_threads(config: dict, threads: int | None) -> dict:
    """``config`` with ``render.threads`` set to ``threads`` where the config leaves it null."""
    render = config.get("render", {})
    if threads is None or render.get("threads") is not None:
        return config
    return {**config, "render": {**render, "threads": threads}}
