"""A reference interrupted (Ctrl-C, SIGTERM, a crash) resumes from its last finished cycle.

A converged reference (:func:`tlm.experiments.reference.compute_reference`) takes minutes, hours on a
large scene. Its rounds come in cycles whose seeds do not depend on the stopping rule (cycle ``k`` of the
same length is the same whatever the tolerance and ``min_rounds``/``max_rounds``), and its running state
after a cycle is small: the cycles finished, the running mean and Welford's ``m2`` (float64, per pixel),
the change and relative standard error of each cycle, and the host seconds so far. :class:`Partial` saves
that state at the end of a cycle (not the last), atomically (:func:`tlm.storage.write_atomic`: a temporary file
of this process's own, renamed into place), in the cache beside the entry it becomes,
``references/<key>.partial.npz`` (:func:`~tlm.experiments.reference_cache.partial_path`; float64 stored
exactly), and the next compute of the key resumes from it, to the same bits as a compute never
interrupted: the same image, the same ``meta.json`` but for ``host_seconds`` (the earlier seconds added)
and ``resumed_from_round`` (the rounds it did not compute again). A save is 48 bytes a pixel (100 MB at
1080p, about 0.5 s): one of more than :data:`SMALL_SAVE` bytes is made at the end of the first cycle that
ends :data:`SAVE_SECONDS` or more after the last save (or the compute's start), not after every cycle (a
1080p cycle of 1000 photons, k 8, one round: 5.4 s, its save 9% of it); a smaller one after every cycle.
An interrupt loses the rounds since the last save, at most about :data:`SAVE_SECONDS` and a cycle.
A folder with too little space for a save (``shutil.disk_usage``) is said in one line, once, and looked
at again at the next save's time (no save tried there: a failed one would say the cache cannot be written,
though its reference, a quarter of the size, may fit).

Rounds saved under another stopping rule are resumed where the rule asked for now would not have stopped
before them; rounds past the point where it stops (more cycles than its ``max_rounds`` allows, or a cycle
before the last saved one that meets its tolerance) are not resumed (the compute starts from round 1 and
stops where that rule stops it: they are kept for a later compute that goes further), nor those of cycles
of another length (``reference.spp``) or of the other engine (``TLM_KERNELS``): a line says why, and that
they are kept (a warning where no ``say`` is given). None of them can give a compute that stops before their
last cycle, or makes cycles of another kind, its bits (they hold the state after that cycle alone), so a
compute never saves over rounds that hold more than its own: not over more cycles of its kind
(:meth:`Partial.save`), and not over more rounds of another kind (a quick compute of another ``reference.spp``
after a long one interrupted: its saves begin once it has as many rounds, :meth:`Partial._holds_more`; an
interrupt before loses its own), and its stored reference leaves them
(:func:`~tlm.experiments.reference_cache.drop_partial`). (Not
checked: that tlm's code is the one that saved them, as a cached reference is not: a change of the code
that changes a reference changes its key, :data:`~tlm.experiments.reference.KEY_VERSION`.) A damaged
file, or one of another key, is said in one line, removed and computed again; one of another layout
(:data:`PARTIAL_VERSION`: an older or newer tlm's) is said in one line and left for that tlm (this compute's
own saves replace it, as they replace rounds of cycles of another length). The saved rounds are
removed once the compute finished and its reference is stored, or could not be
(:func:`~tlm.experiments.reference_cache.drop_partial`; a compute that no caller stores, ``key`` None,
saves none).

Two processes computing one key at once save the same rounds (the same seeds) into one file, each
through a temporary file of its own: neither reads a half-written one, and the one behind does not
replace the rounds of the one ahead (:meth:`Partial.save`); one that starts while another computes the
key resumes from its rounds (the same result), and its line says so (the file names its writer, ``h<host>-<pid>``,
and when it started, ``started``, :func:`~tlm.storage_live.process_start`: an id given since to another process
names no compute). A compute that leaves its rounds (an interrupt, an error) says so in the file as it leaves
(``stopped``, :meth:`Partial.leave`): its process may live on (a notebook, a service), computing them no longer
(:func:`~tlm.cache_admin.partial_computer`: ``tlm cache`` and a resume read both).

A cache that cannot be written keeps no rounds (its one line, :mod:`tlm.caches`, says it cannot be
written): none are kept in the temporary folder, where the reference itself may go
(:func:`~tlm.experiments.reference_cache.kept_root`).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import time
from dataclasses import dataclass, field

import numpy as np

from tlm.cache_admin import human, partial_computer
from tlm.errors import EnvironmentFailure, InputError
from tlm.experiments.reference_cache import PARTIAL_VERSION, partial_info, partial_path, partial_rounds
from tlm.kernels.engine import engine
from tlm.storage import process_tag, warn, write_atomic
from tlm.storage_live import process_start

SAVE_SECONDS = 60.0  # a save of more than SMALL_SAVE bytes waits this long after the last one (or the start)
SMALL_SAVE = 4 << 20  # bytes (320 x 240 pixels: 3.7 MB, a few ms): saved after every cycle
_now = time.monotonic  # (the clock of the saves' times)
_STARTED: dict[int, int] = {}  # this process's start by its id (_started: read once; a forked child's, its own)


@dataclass
class Rounds:
    """The running state of a reference after ``k`` finished cycles: the mean and Welford's ``m2``
    ((pixels, 3) float64), the change and relative standard error after each cycle from the second, and
    the host seconds its rounds took."""

    k: int = 0
    mean: np.ndarray | None = None
    m2: np.ndarray | None = None
    changes: list[float] = field(default_factory=list)
    errors: list[float] = field(default_factory=list)
    seconds: float = 0.0


class _Damaged(Exception):
    """A saved file that is no reference's rounds, or another key's (its message: why)."""


class _OtherLayout(Exception):
    """A saved file of another layout than :data:`PARTIAL_VERSION` (another tlm's; its message: the layout)."""


def stops_at(errors: list[float], k: int, min_cycles: int, max_cycles: int, tolerance: float) -> int | None:
    """The cycle, of the first ``k``, that a compute stops at (:func:`compute_reference`'s rule: at least
    ``min_cycles``, a relative standard error below ``tolerance``, or ``max_cycles``), given the errors
    of its cycles from the second; None where it goes on past cycle ``k``."""
    for j in range(max(2, min_cycles), min(k, max_cycles) + 1):
        if errors[j - 2] < tolerance:
            return j
    return max_cycles if max_cycles <= k else None


def _started(writer: str) -> int | None:
    """When the process ``writer`` names (``h<host>-<pid>``, :func:`~tlm.storage.process_tag`) started
    (:func:`~tlm.storage_live.process_start`; None without ``/proc``): this process's read once, as it cannot
    change (a forked child, of another id, reads its own; another process's read each time)."""
    pid = int(writer.rpartition("-")[2])
    if pid in _STARTED:
        return _STARTED[pid]
    started = process_start(pid)
    if started is not None and pid == os.getpid():
        _STARTED[pid] = started
    return started


if hasattr(os, "register_at_fork"):  # (a child given the id of a process the parent read: not taken for it)
    os.register_at_fork(after_in_child=_STARTED.clear)


def _whose(info: dict) -> str:
    """Whose rounds those of header ``info`` are: a reference interrupted earlier, or one another process of this
    machine is computing now (:func:`~tlm.cache_admin.partial_computer`; the same rounds: resumed all the same)."""
    pid = partial_computer(info)
    return "a reference interrupted earlier" if pid is None else f"a reference that process {pid} is computing now"


class Partial:
    """The saved rounds of the reference ``key``, computed in cycles of ``strata`` rounds over ``pixels``
    pixels (:func:`~tlm.experiments.reference_cache.partial_path`). ``say``: called with the line that says
    a compute resumes, or why it does not (else a damaged file's line is a warning, :func:`~tlm.storage.warn`,
    and the others unsaid)."""

    def __init__(self, key: str, strata: int, pixels: int, say=None):
        self.key, self.strata, self.pixels, self.say = key, strata, pixels, say
        self.path = partial_path(key)
        self.kind = {"version": PARTIAL_VERSION, "key": key, "strata": strata, "engine": engine()}
        self.off = False  # (a save failed: the cache cannot be written; no more tries)
        self.last = _now()  # (the last save's time, or the compute's start: SAVE_SECONDS)
        self.short = False  # (a folder too full for a save was said)
        self.rule: tuple[int, int, float] | None = None  # (the compute's stopping rule, as resume was asked: kept)
        self.saved = 0  # (the rounds of this compute's last save: kept() 0 after one, they were replaced)
        self.held_off = False  # (a save not made: more rounds of another kind in the file, _holds_more)

    def _tell(self, line: str, warning: bool = False) -> None:
        if self.say is not None:
            self.say(line)
        elif warning:
            warn(line)

    def resume(self, min_cycles: int, max_cycles: int, tolerance: float) -> Rounds | None:
        """The rounds saved where a compute of that stopping rule resumes from them (the line said), else
        None (a line says why, but where none are saved)."""
        self.rule = (min_cycles, max_cycles, tolerance)
        try:
            if not (self.path.exists() or self.path.is_symlink()):
                return None
        except OSError:  # (a cache folder that cannot be looked into: its own line says so, tlm.caches)
            return None
        try:
            info, rounds = self._read()
        except _Damaged as e:
            gone = "are ignored and removed"
            try:
                self.path.unlink()
            except FileNotFoundError:  # (removed meanwhile: a prune, another process)
                pass
            except OSError as err:  # (a read-only cache: said again by the next compute, which cannot resume either)
                gone = f"are ignored (and cannot be removed: {(err.strerror or str(err)).lower()})"
            self._tell(f"reference {self.key}: the rounds saved of a reference interrupted earlier, {self.path}, "
                       f"{gone} ({e}): it is computed from round 1", warning=True)
            return None
        except _OtherLayout as e:
            self._tell(f"reference {self.key}: not resuming from the rounds saved in {self.path}, of layout {e} "
                       f"(another tlm's; this one reads layout {PARTIAL_VERSION}): they are left for it, and this "
                       "reference is computed from round 1, its own rounds saved in their place")
            return None
        done = rounds.k * info["strata"]
        why = self._why_not(info, rounds, min_cycles, max_cycles, tolerance)
        if why is not None:
            self._tell(f"reference {self.key}: not resuming from round {done} of {_whose(info)} "
                       f"({why}): it is computed from round 1{self._aside(info, done, max_cycles)}", warning=True)
            return None
        self._tell(f"reference {self.key}: resuming from round {done} of {_whose(info)} "
                   f"({rounds.k} cycles of {self.strata} rounds done in {rounds.seconds:.1f} s, saved in {self.path})")
        self.saved = done  # (its rounds in the file now: kept() says them, or that they were replaced)
        return rounds

    def kept(self) -> int:
        """The rounds the file holds now that this compute, run again (its key, cycles, engine and stopping rule),
        resumes from (:meth:`resume`), 0 for none: what an interrupted compute says it keeps
        (:func:`marked`). Its header and errors read, not its mean (a quick read, after a Ctrl-C); its
        own rounds saved, or those it resumed from, or those another process computing the key saved."""
        info = partial_info(self.path)
        rounds = partial_rounds(info)
        if self.rule is None or not rounds or not self._ours(info):
            return 0
        try:
            with np.load(self.path, allow_pickle=False) as z:
                errors = [float(x) for x in np.asarray(z["errors"], dtype=np.float64).reshape(-1)]
        except Exception:  # (damaged since its header was read, or replaced: whatever numpy or zipfile say)
            return 0
        if len(errors) != info["k"] - 1 or self._why_not(info, Rounds(info["k"], errors=errors), *self.rule):
            return 0
        return rounds

    def others(self) -> int:
        """The rounds of this key the file holds now that this compute, run again, does not resume (:meth:`kept`
        0): another compute's, of another ``reference.spp``, the other engine, or cycles past where this one's
        rule stops, which its saves do not replace until it has more (:meth:`save`); 0 for none (and for a file
        that cannot be read: damaged, gone, no regular file, :func:`~tlm.experiments.reference_cache.partial_info`)."""
        info = partial_info(self.path)
        return partial_rounds(info) if self._ours(info) else 0

    def _ours(self, info: dict | None) -> bool:
        """Whether header ``info`` (:func:`~tlm.experiments.reference_cache.partial_info`) is of rounds of this key,
        saved in this layout (:data:`PARTIAL_VERSION`)."""
        return info is not None and info.get("version") == PARTIAL_VERSION and info.get("key") == self.key

    def _holds_more(self, info: dict | None, k: int) -> bool:
        """Whether the saved rounds of header ``info`` (:func:`~tlm.experiments.reference_cache.partial_info`), of
        this key and layout, are more rounds than ``k`` cycles of this compute's: of another kind (cycles of another
        length, the other engine), they are kept for the compute that resumes them, not saved over (:meth:`save`)."""
        return self._ours(info) and partial_rounds(info) > k * self.strata

    def _aside(self, info: dict, done: int, max_cycles: int) -> str:
        """What the line of rounds not resumed adds where they are of another kind (:meth:`_why_not`): that they
        are kept, and from when this compute's own rounds are saved in their place (:meth:`_holds_more`)."""
        if info["strata"] == self.strata and info["engine"] == self.kind["engine"]:
            return ""  # (of this kind: its why says they are kept, and this compute's saves never reach them)
        if (max_cycles - 1) * self.strata < done:  # (the rounds of its last save: none at its last cycle)
            return (f"; they are kept, and this compute, of at most {max_cycles * self.strata} rounds, saves none "
                    f"of its own over them (an interrupt computes it from round 1 again; remove {self.path} to "
                    "save its own)")
        return (f"; they are kept until this compute has as many rounds ({done}), its own saved in their place from "
                "then on")

    def _why_not(self, info: dict, rounds: Rounds, min_cycles: int, max_cycles: int, tolerance: float) -> str | None:
        if info["strata"] != self.strata:
            return (f"it was computed in cycles of {info['strata']} rounds, these settings make cycles of "
                    f"{self.strata} (reference.spp, at most half of reference.max_rounds)")
        if info["engine"] != self.kind["engine"]:
            return (f"it was computed with TLM_KERNELS={info['engine']}, this run with {self.kind['engine']}: "
                    "the last bits of their estimates may differ")
        stop = stops_at(rounds.errors, rounds.k, min_cycles, max_cycles, tolerance)
        if stop is not None and stop < rounds.k:
            return (f"these reference settings stop it at round {stop * self.strata}, before that; "
                    "its rounds are kept for a compute that goes further")
        return None

    def _read(self) -> tuple[dict, Rounds]:
        try:
            with open(self.path, "rb") as fh:
                if fh.read(4) != b"PK\x03\x04":  # (np.load would read it as a pickle, and say "allow_pickle")
                    raise _Damaged("it is no .npz file")
            with np.load(self.path, allow_pickle=False) as z:
                info = json.loads(str(z["info"][()])) if "info" in z.files else None
                version = info.get("version") if isinstance(info, dict) else None
                if type(version) is int and version != PARTIAL_VERSION:  # (its arrays may be others: not read)
                    raise _OtherLayout(version)
                missing = {"info", "mean", "m2", "changes", "errors"} - set(z.files)
                if missing:
                    raise _Damaged(f"it has no {', '.join(sorted(missing))}")
                mean, m2, changes, errors = (z[n] for n in ("mean", "m2", "changes", "errors"))
        except (_Damaged, _OtherLayout):
            raise
        except Exception as e:  # (not an .npz, cut short, a folder: whatever numpy, zipfile or json say)
            raise _Damaged(f"it cannot be read: {' '.join(str(e).split()) or type(e).__name__}") from None
        if not isinstance(info, dict):
            raise _Damaged("its header is no record")
        if info.get("version") != PARTIAL_VERSION:
            raise _Damaged(f"its layout is {info.get('version')!r}, not {PARTIAL_VERSION}")
        if info.get("key") != self.key:
            raise _Damaged(f"it holds the rounds of reference {info.get('key')!r}, not {self.key}")
        k, strata, seconds = info.get("k"), info.get("strata"), info.get("seconds")
        if not (type(k) is int and k >= 1 and type(strata) is int and strata >= 1):
            raise _Damaged(f"its cycles ({k!r}) or rounds per cycle ({strata!r}) are no positive whole numbers")
        if not (isinstance(seconds, (int, float)) and not isinstance(seconds, bool) and math.isfinite(seconds)
                and seconds >= 0):
            raise _Damaged(f"its seconds ({seconds!r}) are no number of seconds")
        if not isinstance(info.get("engine"), str):
            raise _Damaged("it names no engine")
        for name, a, shape in (("mean", mean, (self.pixels, 3)), ("m2", m2, (self.pixels, 3)),
                               ("changes", changes, (k - 1,)), ("errors", errors, (k - 1,))):
            if a.dtype != np.float64 or a.shape != shape or not np.all(np.isfinite(a)):
                raise _Damaged(f"its {name} is {a.dtype} {a.shape}, not finite float64 {shape}")
        if np.any(m2 < 0):
            raise _Damaged("its m2 is negative")
        return info, Rounds(k, mean, m2, [float(x) for x in changes], [float(x) for x in errors], float(seconds))

    def save(self, rounds: Rounds) -> None:
        """Save ``rounds`` (atomically), the state at the end of a cycle; but where it is more than
        :data:`SMALL_SAVE` bytes and the last save (or the compute's start) is less than :data:`SAVE_SECONDS`
        ago, where the file holds as many cycles or more of the same kind (another process ahead on the same
        key) or more rounds of another kind (:meth:`_holds_more`), where its folder has too little space left
        (said once), or where a save failed before (the cache cannot be written)."""
        if self.off:
            return
        size = rounds.mean.nbytes + rounds.m2.nbytes + 16 * (len(rounds.errors) + 64)  # (+ headers, roughly)
        now = _now()
        if size > SMALL_SAVE and now - self.last < SAVE_SECONDS:
            return
        info = partial_info(self.path)
        if (info is not None and all(info.get(f) == v for f, v in self.kind.items())
                and type(info.get("k")) is int and info["k"] >= rounds.k):
            return
        if self._holds_more(info, rounds.k):  # (another kind's rounds, more than these: kept, the resume's line)
            self.held_off = True
            return
        writer = process_tag()  # (and when the process it names started: None without /proc)
        head = json.dumps({**self.kind, "k": rounds.k, "seconds": rounds.seconds, "writer": writer,
                           "started": _started(writer)})
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            free = shutil.disk_usage(self.path.parent).free
        except OSError:  # (a cache that cannot be written: its one line, tlm.caches)
            self.off = True
            return
        if free < size:
            self.last = now
            if not self.short:
                self.short = True
                self._tell(f"reference {self.key}: its rounds are not saved for a resume: {self.path.parent} has "
                           f"{human(free)} free, a save takes {human(size)} (looked at again every "
                           f"{SAVE_SECONDS:.0f} s; an interrupt loses the rounds since the last save)", warning=True)
            return
        try:
            with write_atomic(self.path, "wb") as fh:
                np.savez(fh, info=np.array(head), mean=np.asarray(rounds.mean, dtype=np.float64),
                         m2=np.asarray(rounds.m2, dtype=np.float64),
                         changes=np.asarray(rounds.changes, dtype=np.float64).reshape(-1),
                         errors=np.asarray(rounds.errors, dtype=np.float64).reshape(-1))
        except (OSError, EnvironmentFailure, InputError):  # (the cache's one line says it cannot be written)
            self.off = True
        else:
            self.last = _now()
            self.saved = rounds.k * self.strata

    def leave(self) -> None:
        """As the compute leaves its rounds (an interrupt, an error: :func:`marked`): its last save, where the file
        holds it still, saved again saying so (``stopped``, all else as it was; a read and a write of the file, half
        a second at 1080p), as its process may live on (a notebook, a service) and its id alive no longer means it
        computes them (:func:`~tlm.cache_admin.partial_computer`: ``tlm cache`` lists an interrupted compute's
        rounds, which a prune may remove, and a resume says a reference interrupted earlier). Not rounds another
        process saved over it, nor those this compute resumed from and did not save again (their writer's); a file
        that cannot be read or written is left as it is."""
        if not self.saved or self.off:
            return
        info = partial_info(self.path)
        if (info is None or info.get("writer") != process_tag() or info.get("stopped") is True
                or any(info.get(f) != v for f, v in self.kind.items()) or partial_rounds(info) != self.saved):
            return
        with contextlib.suppress(Exception):  # (damaged or replaced since, a cache that cannot be written: as it is)
            with np.load(self.path, allow_pickle=False) as z:
                arrays = {n: z[n] for n in z.files}
            if json.loads(str(arrays["info"][()])) == info:  # (not replaced since its header was read)
                arrays["info"] = np.array(json.dumps({**info, "stopped": True}))
                with write_atomic(self.path, "wb") as fh:
                    np.savez(fh, **arrays)


MARK = "reference_partial"  # an interrupt's attribute: the Partial of the compute it stopped (tlm.cli_report reads it)


@contextlib.contextmanager
def marked(saved: Partial | None):
    """Around a reference compute's rounds: an interrupt (or any error) that leaves them carries the compute's
    saved rounds, ``saved``, as its attribute :data:`MARK`, the innermost compute's (a command's line then says
    how many the cache keeps: :func:`tlm.cli_report.reference_cut_short`, through the API's layers), and the file
    says that no process computes them any longer (:meth:`Partial.leave`)."""
    try:
        yield
    except BaseException as e:
        if saved is not None and getattr(e, MARK, None) is None:
            with contextlib.suppress(Exception):  # (an exception that takes no attribute: said as before)
                setattr(e, MARK, saved)
        if saved is not None:
            saved.leave()
        raise
