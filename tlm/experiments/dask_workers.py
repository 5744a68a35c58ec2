"""What runs on a Dask worker, or checks one, for a sweep's point.

A point that a Dask worker runs sizes its kernel threads on the worker's own machine
(:func:`dask_worker_threads`: the sweep's machine is not the worker's), or, where its config gives
``render.threads``, says when that count oversubscribes the machine (:func:`dask_oversubscribed`; the sweep
says it once per machine, as a remote worker's line of that count past its machine's CPUs alone:
:func:`machine_lines`), names the worker
in its messages (:func:`dask_worker_where`: by its ``--name``, :func:`worker_words`), records who ran it
(:func:`ran_here`: the worker's name, host and process) and the versions of the process that ran
it (:func:`worker_versions`) and is refused on a worker whose numpy, numba or Python
differ from the sweep's (:func:`check_worker_versions`, :class:`OtherVersionsOnWorker`).
Each worker of a ``--dask local`` cluster preloads this module as it starts (:func:`dask_setup`).
The executors that hand points to the workers: :mod:`tlm.experiments.executors`.
"""

from __future__ import annotations

import os
import re
import sys
import threading
import time

_SLOTS: dict[str, tuple[float, int]] = {}  # a Dask worker's address -> (when asked, slots on its machine)
SLOTS_TTL = 60.0  # seconds a worker keeps what the scheduler said (a point asks once a minute at most)


def dask_setup(worker) -> None:
    """Run by each worker of a ``--dask local`` cluster as it starts, before any point (a Dask
    worker preload: :func:`~tlm.experiments.executors.open_executor` names this module; a
    worker the cluster restarts runs it again): the progress bars of the points it runs share a
    thread lock, not tqdm's default, a multiprocessing semaphore made with the first bar (a
    disabled one too). The worker shares the sweep's resource tracker, which writes to the
    sweep's stderr; a worker ended without its exit handlers (killed, a SIGTERM to the
    sweep's process group, or ended by the cluster's close while a point keeps it busy) could
    not unlink that semaphore, and the tracker reported it leaked after tlm's last line. A
    worker's bars are never shown: a thread lock does (the local pool's workers: the same).

    It also imports the renderer and the sweep's point code now (:data:`~tlm.experiments.worker_start.
    TLM_PRELOAD`, as a local pool's fork server does) and hashes the package then
    (:func:`~tlm.fingerprint.code_fingerprint`): the fingerprint of the code it imported, not of what the
    disk holds at its first point, which its points compare with the sweep's (``Task.own_code``)."""
    import importlib

    from tqdm import tqdm

    from tlm.experiments.worker_start import TLM_PRELOAD

    tqdm.set_lock(threading.RLock())
    for name in TLM_PRELOAD:
        importlib.import_module(name)
    from tlm.fingerprint import code_fingerprint

    code_fingerprint()


def dask_worker_threads() -> int | None:
    """In a Dask worker: the ``render.threads`` of a point whose config leaves it null (the
    sweep could not size it: the workers' machines are not the sweep's), the CPUs
    available here over the task slots of every worker on this machine (:func:`_machine_slots`),
    at least one: the points that run at once on a machine share its CPUs. A worker of 32
    threads on a 32-core machine runs 32 points at once, each on one thread, where each would
    otherwise take all 32. None outside a Dask worker. Speed only: no error leaves it."""
    worker = _dask_worker()
    if worker is None:
        return None
    from tlm.kernels.threads import shared_threads

    return shared_threads(_machine_slots(worker))  # (at most DEFAULT_MAX_THREADS)


def _machine_slots(worker) -> int:
    """The task slots of every Dask worker on ``worker``'s machine (their ``nthreads`` summed, the
    machine as the scheduler names it for this worker), at least this worker's own: the points that
    run at once there. Where the scheduler cannot be asked (or says something not understood), this
    worker's own slots; what it said is kept for :data:`SLOTS_TTL` seconds (one question a minute at
    most, whichever of :func:`dask_worker_threads` and :func:`dask_oversubscribed` asks)."""
    from distributed import get_client

    own = max(1, int(getattr(worker.state, "nthreads", 1) or 1))
    now = time.monotonic()
    kept = _SLOTS.get(worker.address)
    if kept is not None and now - kept[0] < SLOTS_TTL:
        return kept[1]
    try:
        client = get_client(timeout=5)
        try:
            listed = client.scheduler_info(n_workers=-1)["workers"]
        except TypeError:  # (an older distributed lists every worker without being asked)
            listed = client.scheduler_info()["workers"]
        host = listed[worker.address]["host"]  # (the scheduler's own name of this machine)
        slots = max(own, sum(int(w.get("nthreads") or 0) for w in listed.values() if w.get("host") == host))
    except Exception:  # (a speed hint: a scheduler that cannot say leaves this worker's slots)
        slots = own
    _SLOTS[worker.address] = (now, slots)
    return slots


def _machine_host(worker) -> str:
    """``worker``'s machine as the scheduler names it (the host of its address: an IP address, as
    ``dask worker`` listens on one), else this machine's own name."""
    try:
        from distributed.comm import get_address_host

        return str(get_address_host(worker.address))
    except Exception:  # (an address not understood)
        import socket

        return socket.gethostname()


# the line of a Dask point whose given render.threads, times the points at once on its machine, oversubscribes that
# machine's CPUs (dask_oversubscribed: the points at once are its workers' task slots, or all the sweep runs where
# those are fewer); machine_lines reads it back: render.threads, host, points at once
OVERSUBSCRIBED = re.compile(r"render\.threads = (\d+) on host (\S+) with (\d+) points at once \((?:the task "
                            r"slots of its Dask workers|all the sweep runs, of its Dask workers' \d+ task slots)\) "
                            r"oversubscribes ")
# a remote Dask point's line of a given render.threads past its worker machine's CPUs alone (run_warnings.
# threads_warning's, ending "(on the Dask worker NAME (ADDRESS) on host HOST)": sweep_point._threads_lines, which
# the sweep does not say as it starts, as it does a local one's); machine_lines reads it back: render.threads, host
ALONE = re.compile(r"render\.threads = (\d+) is more than the \d+ CPUs? available to this process .*\(on the Dask "
                   r"worker .+ on host (\S+)\)$")


def dask_oversubscribed(threads: int | None, running: int = 0, local: bool = False) -> list[str]:
    """In a Dask worker: a line where a point's given ``render.threads`` (``threads``), times the points
    that run at once on this machine (the task slots of its workers, :func:`_machine_slots`, as
    :func:`dask_worker_threads` counts them, no more than ``running``, the points the sweep runs; 0: not
    known), is more kernel threads than the CPUs available here, while that count alone is no more than
    them (:func:`~tlm.experiments.run_warnings.threads_warning` says that one): the point runs as asked,
    its line naming the machine, render.threads, the points at once and the CPUs, the way the sweep's own
    ``--jobs`` line says it for its local workers (:func:`~tlm.experiments.run_warnings.sweep_jobs_line`).
    ``local``: a ``--dask local`` cluster's worker, whose slots ``--jobs`` sets. None for a null
    ``threads`` (sized to fit: :func:`dask_worker_threads`), for one thread (a null's count there too, where the
    slots alone are past the CPUs: leaving it null would change nothing) and outside a Dask worker."""
    if threads is None:
        return []
    worker = _dask_worker()
    if worker is None:
        return []
    from tlm.kernels.threads import available

    slots = _machine_slots(worker)
    at_once = min(slots, running) if running > 0 else slots
    cpus = available()
    # (one thread: what a null count gets there too, which says nothing: the slots alone are past the CPUs)
    if at_once <= 1 or threads <= 1 or threads > cpus or threads * at_once <= cpus:
        return []
    fix = ("lower --jobs" if local else
           "start that machine's Dask workers with fewer threads (dask worker --nthreads)")
    which = ("the task slots of its Dask workers" if at_once == slots else
             f"all the sweep runs, of its Dask workers' {slots} task slots")
    return [f"render.threads = {threads} on host {_machine_host(worker)} with {at_once} points at once ({which}) "
            f"oversubscribes its {cpus} CPU{'s' if cpus != 1 else ''} available "
            f"({threads * at_once} kernel threads): they take turns on them, which is slower, not faster (results "
            f"are the same); {fix}, or leave render.threads null (each point then gets its share of the machine's "
            "CPUs)"]


def machine_lines(lines) -> list[str]:
    """Of a sweep's points' warning ``lines``, their :func:`dask_oversubscribed` lines, one per machine (the
    one of the most kernel threads there), and a remote Dask worker's line of a given ``render.threads`` past its
    machine's CPUs alone (:data:`ALONE`), one per machine (the one of the most threads there), in the order the
    machines are first met: what the sweep says once for all the points that ran on it. (A machine as each line
    names it: the host of its workers' address, the host name of the worker's machine.)"""
    found: dict[tuple[str, str], tuple[int, str]] = {}
    for line in lines:
        if (read := _machine_line(line)) is None:
            continue
        key, weight = read
        if key not in found or weight > found[key][0]:
            found[key] = (weight, line)
    return [line for _, line in found.values()]


def machine_key(line) -> tuple[str, str] | None:
    """The machine a :func:`machine_lines` line is of, and its kind: ``("at once", HOST)`` for a
    :data:`OVERSUBSCRIBED` line, ``("alone", HOST)`` for an :data:`ALONE` one; None for any other line. A
    point's line of a key the sweep said once already is of a machine it said (``tlm sweep`` leaves it out of
    the points' warnings after its summary)."""
    read = _machine_line(line)
    return None if read is None else read[0]


def _machine_line(line) -> tuple[tuple[str, str], int] | None:
    """A :func:`machine_lines` line read back: its machine's key (:func:`machine_key`) and its weight (the
    kernel threads at once there, or the count alone); None for any other line."""
    if not isinstance(line, str):
        return None
    if (m := OVERSUBSCRIBED.match(line)) is not None:
        return ("at once", m.group(2)), int(m.group(1)) * int(m.group(3))
    if (m := ALONE.match(line)) is not None:
        return ("alone", m.group(2)), int(m.group(1))
    return None


def _dask_worker():
    """The Dask worker whose task runs in this thread, or None (not in a worker's task)."""
    if "distributed" not in sys.modules:  # (not imported: not a Dask worker)
        return None
    from distributed import get_worker

    try:
        return get_worker()
    except ValueError:  # (not in a worker's task)
        return None


def worker_name(name, address) -> str:
    """A Dask worker as its user knows it: the name it was given (``dask worker --name w1``; ``w1-0``, ``w1-1``
    with ``--nworkers 2``), else its ``address`` (a worker given no name is named by its address; those of a
    ``--dask local`` cluster are numbered by the cluster, 0, 1, ...: their addresses tell them apart)."""
    return name if isinstance(name, str) and name and name != address else str(address)


def worker_words(name, address, host: str | None = None) -> str:
    """``the Dask worker NAME (ADDRESS) on host HOST`` for the lines on a worker: its :func:`worker_name`, its
    address beside a name it was given, its host where it is known."""
    label = worker_name(name, address)
    at = f" ({address})" if label != str(address) else ""
    return f"the Dask worker {label}{at}" + (f" on host {host}" if host else "")


def dask_worker_where() -> str | None:
    """In a Dask worker's task: ``the Dask worker NAME (ADDRESS) on host HOST`` (:func:`worker_words`), for the
    messages of a point that failed there; None elsewhere."""
    worker = _dask_worker()
    if worker is None:
        return None
    import socket

    return worker_words(getattr(worker, "name", None), worker.address, socket.gethostname())


def ran_here() -> dict:
    """Who runs a point in this process, as its ``results.json`` records it (``ran``) and its row's ``worker``,
    ``host`` and ``pid`` columns say (:func:`~tlm.experiments.sweep_rows.point_row`): ``worker``, the Dask
    worker's :func:`worker_name` (its ``--name``, else its address; None outside a Dask worker: a local pool's
    process, or the sweep's own with ``--jobs 1``), ``host``, this machine's name, and ``pid``, this process's
    id. Plain data; read at no cost, no error leaves it."""
    import socket

    worker = _dask_worker()
    name = None if worker is None else worker_name(getattr(worker, "name", None), getattr(worker, "address", ""))
    return {"worker": name, "host": socket.gethostname(), "pid": os.getpid()}


# the versions (provenance.versions' keys) that can change a point's bits: a Dask worker that differs
# from the sweep in one is refused (Python by its major.minor). The kernels (TLM_KERNELS) are recorded,
# not refused: the compiled and numpy engines give the same bits (tests/test_engines.py, test_golden.py).
RESULT_VERSIONS = ("python", "numpy", "numba")
_LABELS = {"python": "Python"}
_VERSIONS: dict[str, dict[str, str]] = {}  # TLM_KERNELS as set -> this process's versions


class OtherVersionsOnWorker(RuntimeError):
    """A Dask worker runs another numpy, numba or Python (major.minor) than the sweep: its points
    could have other bits than the sweep's."""


def worker_versions() -> dict[str, str]:
    """This process's :func:`~tlm.experiments.provenance.versions`, which a point records: those of
    the worker that ran it. Read once per process and ``TLM_KERNELS`` value (a point reads them
    at no cost)."""
    from tlm.experiments.provenance import versions

    key = os.environ.get("TLM_KERNELS", "")
    if key not in _VERSIONS:
        _VERSIONS[key] = versions()
    return dict(_VERSIONS[key])


def check_worker_versions(sweeps: dict | None, here: dict, where: str) -> None:
    """In a Dask worker ``where``: :class:`OtherVersionsOnWorker`, naming each of
    :data:`RESULT_VERSIONS` in which ``here`` (the worker's :func:`worker_versions`) differs
    from ``sweeps`` (the sweep's), with both versions; numba only where the worker runs the compiled
    kernels (``here["kernels"]``). None for ``sweeps``: nothing to compare."""
    if sweeps is None:
        return
    # numba's version matters only where the worker runs the compiled kernels: its numpy engine is the
    # reference the compiled one is checked against, whatever numba is there (or none)
    names = [k for k in RESULT_VERSIONS if k != "numba" or here.get("kernels", "numba") == "numba"]
    differ = [f"{_LABELS.get(k, k)} {_result_version(here, k)} (the sweep's {_result_version(sweeps, k)})"
              for k in names if _result_version(here, k) != _result_version(sweeps, k)]
    if differ:
        from tlm.config_words import listing

        raise OtherVersionsOnWorker(
            f"{where} runs {listing(differ)}: its points could give other results than the sweep's; install "
            "the sweep's versions on the workers and restart them")


def _result_version(versions: dict, name: str) -> str:
    v = str(versions.get(name, "unknown"))
    return ".".join(v.split(".")[:2]) if name == "python" else v
