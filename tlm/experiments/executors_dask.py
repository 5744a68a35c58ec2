"""The Dask side of a sweep's executors that stands apart from the pool itself: the check that
something answers, as a Dask scheduler, at a ``--dask tcp://HOST:PORT`` address before the client
connects (:func:`answers`, within :data:`CONNECT_TIMEOUT` seconds), and :class:`SweepStopped`, the
one line that says the cluster, not a point, stopped the sweep; and :func:`host_kept`, which puts back
what a local cluster changes in this process (the variables its nannies set, distributed's loggers).

:mod:`tlm.experiments.executors` opens the executors and re-exports these names; the Dask
executor itself (:class:`~tlm.experiments.executors.DaskPool`), the seconds it waits and polls,
its worker preloads and the silencing of distributed's logs stay there. What runs on a Dask
worker: :mod:`tlm.experiments.dask_workers`. Nothing here imports distributed at import time.
"""

from __future__ import annotations

import logging
import os
import socket
import warnings
from contextlib import contextmanager

from tlm.errors import EnvironmentFailure, InputError

CONNECT_TIMEOUT = 10  # seconds to reach a Dask scheduler


SOCKET_SCHEMES = ("tcp", "tls", "ws", "wss")  # distributed's transports over a TCP connection to HOST:PORT


def answers(address: str, timeout: float = CONNECT_TIMEOUT) -> None:
    """An :class:`InputError` (``--dask``) where nothing answers at the scheduler's ``address``,
    told from one TCP connection to its host and port (a transport over TCP: :data:`SOCKET_SCHEMES`;
    any other is left to Dask): a refused one (no process listens on that port: a scheduler not
    started, or another port), an unknown host and an unreachable network are known at once,
    where distributed's connect retries them for its whole timeout and says "Timed out"; a host
    that does not answer (one that is down, a firewall that drops the packets) after ``timeout``
    seconds, as before, with a line that says so. A connection made is closed at once (the
    scheduler logs, at INFO, that one closed before its handshake), and Dask connects next."""
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, loc = parse_address(address)
        host, port = parse_host_port(loc)
    except (ValueError, TypeError):  # (a form Dask refuses itself, and says why)
        return
    if scheme not in SOCKET_SCHEMES:
        return
    where = ("the scheduler's address is the one 'dask scheduler' printed (Scheduler at: ...), "
             "tcp://HOST:8786 by default")
    try:
        with socket.create_connection((host, port), timeout=timeout) as conn:
            odd = _not_dask(conn) if scheme == "tcp" else None
    except ConnectionRefusedError:
        raise InputError(f"nothing answers at {address!r}: no process listens on port {port} of {host} (connection "
                         f"refused: no scheduler started there, or another port); {where}", key="--dask") from None
    except TimeoutError:  # (socket.timeout)
        raise InputError(f"no answer from {address!r} within {timeout:g} s (a host that is down or not there, or a "
                         f"firewall that drops the connection); {where}", key="--dask") from None
    except socket.gaierror as e:
        raise InputError(f"cannot reach {address!r}: its host {host!r} is not known ({e.strerror or e})",
                         key="--dask") from None
    except OSError as e:  # (no route to the host, an unreachable network)
        raise InputError(f"cannot reach {address!r} ({e.strerror or e}); {where}", key="--dask") from None
    if odd is not None:  # (distributed's connect would wait for it forever, or read its bytes as a frame's size)
        raise InputError(f"{address!r} answers, but not as a Dask scheduler ({odd}: a web server, such as the "
                         f"dashboard's, port 8787?); {where}", key="--dask")


HANDSHAKE_MAX = 1 << 20  # bytes: a Dask scheduler's first message (its handshake) is far smaller


def _not_dask(conn: socket.socket) -> str | None:
    """Why what answers on the TCP connection ``conn`` is not a Dask scheduler, or None: a
    scheduler writes its handshake as soon as it accepts, its first 8 bytes the size of the
    message (little-endian); a web server writes nothing before a request (``conn``'s timeout:
    it said nothing), or an answer whose bytes are no such size."""
    got = b""
    try:
        while len(got) < 8:
            more = conn.recv(8 - len(got))
            if not more:
                return None if got else "it closed the connection at once"  # (a scheduler busy elsewhere: Dask's)
            got += more
    except TimeoutError:
        return "it said nothing" if not got else None
    except OSError:
        return None
    if not 0 < int.from_bytes(got, "little") <= HANDSHAKE_MAX:
        return f"its first bytes are {got!r}"
    return None


class SweepStopped(EnvironmentFailure):
    """The cluster, not a point, stopped the sweep (its Dask scheduler lost, or without
    workers too long): one line, exit status 1; the points done are kept, and a rerun
    into the folder runs the others."""


@contextmanager
def host_kept():
    """The variables of the calling process's ``os.environ`` that distributed sets, and the ``distributed``,
    ``tornado`` and ``bokeh`` loggers' handlers and ``propagate``, put back as they were once the block ends:
    distributed sets the variables its nannies' workers inherit (``OMP_NUM_THREADS=1``,
    ``MALLOC_TRIM_THRESHOLD_``, ``PYTHONHASHSEED``, ...: its ``pre-spawn-environ``) in this process, and its
    import gives those loggers a handler of its own (a notebook's session would keep both after its sweep).
    Yields the record of what it sets (a dict the caller fills: :func:`pre_spawn_env`, the nannies' own); a
    variable is put back only where its value is still what distributed wrote, so that one another thread set
    meanwhile stays (the whole environment was put back, undoing it). Their levels are
    :class:`tlm.experiments.executors._Quiet`'s."""
    env = dict(os.environ)
    written: dict[str, str] = {}
    loggers = {n: (list(logging.getLogger(n).handlers), logging.getLogger(n).propagate) for n in _HOST_LOGGERS}
    try:
        yield written
    finally:
        for k, v in written.items():
            if os.environ.get(k) == v and env.get(k) != v:  # (still distributed's, not another thread's since)
                if k in env:
                    os.environ[k] = env[k]
                else:
                    os.environ.pop(k, None)
        for name, (handlers, propagate) in loggers.items():
            logger = logging.getLogger(name)
            logger.handlers[:] = handlers
            logger.propagate = propagate


def pre_spawn_env() -> dict[str, str]:
    """The variables a local cluster's nannies will set in this process before each worker starts, as
    ``distributed.nanny.Nanny`` computes them (Dask's ``distributed.nanny.pre-spawn-environ``, a variable
    already set keeping its value; ``PYTHONHASHSEED``; ``__DASK_PARENT_PID``, for the workers' process
    titles), for :func:`host_kept` to put back: known before the cluster starts, in case its start fails."""
    import dask

    given = dask.config.get("distributed.nanny.pre-spawn-environ", None)
    env = {k: os.environ.get(k, str(v)) for k, v in (given if isinstance(given, dict) else {}).items()
           if v is not None}
    if env.get("PYTHONHASHSEED") in (None, "0"):
        env["PYTHONHASHSEED"] = "6640"  # (distributed's own choice, dask/distributed#8400)
    env["__DASK_PARENT_PID"] = str(os.getpid())
    return env


_HOST_LOGGERS = ("distributed", "tornado", "bokeh")  # the loggers distributed's import configures


def quiet_client(client_class, *args, **kwargs):
    """``client_class(*args, **kwargs)`` (a ``distributed.Client``) without Dask's ``VersionMismatchWarning``,
    which it warns as it connects where the scheduler's, the workers' and this process's packages differ (a
    table over several lines, with a file's path): the points of a worker whose numpy, numba or Python differ
    fail with tlm's own line on it (:class:`~tlm.experiments.dask_workers.OtherVersionsOnWorker`), and the
    versions each point ran with are in its ``results.json``. The filter is the process's while the client
    connects (its loop's thread warns it, and a sync client waits for that), put back after."""
    from distributed.versions import VersionMismatchWarning

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=VersionMismatchWarning)
        return client_class(*args, **kwargs)
