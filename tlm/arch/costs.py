"""The PM programs: instruction and flush costs per work item (eq. 5.1's T_norm and T_ps).

The table is YAML (the calibrated default is ``tlm/arch/programs.yaml``, which documents
every field). Per programmable PM (``vertex``, ``traversal``, ``fragment``) it has a
``scale`` (the free parameter ``tlm calibrate`` fits) and one entry per job kind with

* ``instructions``: 4-D vector instructions per work item, issued one per cycle;
* ``flushes``: pipeline flushes per work item (each ``flush_cycles``, thesis: 4);
* ``misses``: the work key counting the job's page misses (``null``: none), each
  ``page_miss_cycles`` (thesis: 12);
* ``records`` (optional): the work keys counting the job's records (rays, pixels), each
  of which costs the PM's ``record_cycles`` on top of its instructions: the per-record part of
  a program (reading the record, the set-up, the hand-over) whose size the thesis does not
  give. ``record_cycles`` (default 0) is a second free parameter ``tlm calibrate`` fits.

The fixed-function Intersection PM has ``ray_load_cycles``, ``triangle_cycles`` and
``stages`` instead. :meth:`Programs.cost` turns a job's per-packet work counts into
per-packet cycles; T_norm is rounded on the running total, so the packets of a job sum
to the cycles of the whole job whatever the packet size.

Which work items a job may price, and which it must, come from the work schema
(:mod:`tlm.kernels.work`): a job prices only the items of the work it reads (and the
timing model's own ``items``, ``elements``, ``stream_restarts``), and names every item
the schema says it charges (weight 0 where it costs nothing). A table that does not is a
one-line :class:`~tlm.errors.InputError` naming the file and the key.
"""

from __future__ import annotations

import copy
import os
import stat
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tlm.config import read_text, text_digest, yaml_from_text
from tlm.errors import InputError, did_you_mean
from tlm.kernels import work
from tlm.storage import warn

DEFAULT_PATH = Path(__file__).with_name("programs.yaml")
PROGRAMMABLE = ("vertex", "traversal", "fragment")
JOBS = {
    "vertex": ("geometry_bsp", "photon_emit", "photon_bsp"),
    "traversal": ("rays", "shadow", "photons"),
    "fragment": ("shade", "light", "photons", "gather"),
}
FIXED_KEYS = ("ray_load_cycles", "triangle_cycles", "stages")
# work items counted apart after tables were written without them (``tlm calibrate --write``), and what such a
# table priced them within: one of them missing is read as 0, which keeps that table's costs, with a warning
_PRICED_BEFORE = {"photons_weighted": "the cone weight within photons_accepted"}


def _check_schema() -> None:
    """Every unit the work schema (:mod:`tlm.kernels.work`) names is a job of this table or
    a fixed-function unit, and every job charges some work."""
    jobs = {f"{pm}.{job}" for pm, names in JOBS.items() for job in names}
    named = set(work.units())
    for unit in named - jobs - set(work.FIXED_UNITS):
        raise ImportError(f"tlm.kernels.work names the unit {unit!r}, which is no job of {sorted(jobs)}")
    for unit in jobs - named:
        raise ImportError(f"the job {unit!r} charges no work item of tlm.kernels.work")


_check_schema()


@dataclass(frozen=True)
class JobProgram:
    instructions: dict[str, float]
    flushes: dict[str, float]
    misses: str | None
    records: tuple[str, ...] = ()


@dataclass(frozen=True)
class Programs:
    """A validated instruction-cost table."""

    source: str
    scale: dict[str, float]  # per programmable PM
    jobs: dict[tuple[str, str], JobProgram]  # (pm, job) -> program
    intersection: dict[str, int]
    calibration: dict
    record_cycles: dict[str, float] = field(default_factory=lambda: dict.fromkeys(PROGRAMMABLE, 0.0))

    def cost(self, pm: str, job: str, counts: dict[str, np.ndarray], items: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-packet (instructions cycles, flushes, page misses) of one job.

        counts : work key -> (packets,) int64 summed per packet; a key the table names
        but the counts lack counts as zero. items : (packets,) int64.
        """
        prog = self.jobs[(pm, job)]
        n = items.shape[0]

        def weighted(table: dict[str, float]) -> np.ndarray:
            total = np.zeros(n)
            for key, w in table.items():
                v = items if key == "items" else counts.get(key)
                if v is not None and w:
                    total += w * np.asarray(v, dtype=np.float64)
            return total

        norm = _exact_rounding(self.scale[pm] * weighted(prog.instructions)
                               + self.record_cycles[pm] * weighted(dict.fromkeys(prog.records, 1.0)),
                               self.source, f"{pm}.{job}")
        flushes = _exact_rounding(weighted(prog.flushes), self.source, f"{pm}.{job}")
        misses = np.asarray(counts.get(prog.misses, np.zeros(n)), dtype=np.int64) if prog.misses \
            else np.zeros(n, dtype=np.int64)
        return norm, flushes, misses

    def record_count(self, pm: str, job: str, totals: dict[str, float]) -> float:
        """The records of a job's whole work that each cost ``record_cycles`` (for calibration)."""
        return float(sum(totals.get(k, 0) for k in self.jobs[(pm, job)].records))

    def with_scales(self, scales: dict[str, float], record_cycles: dict[str, float] | None = None) -> Programs:
        """The table with other free parameters (``record_cycles`` unchanged unless given)."""
        return Programs(self.source, {**self.scale, **scales}, self.jobs, self.intersection, self.calibration,
                        {**self.record_cycles, **(record_cycles or {})})


MAX_CYCLES = 2.0**62  # what a job's cycles may add up to (int64, with room for the model's sums)


def _exact_rounding(x: np.ndarray, source: str | None = None, key: str | None = None) -> np.ndarray:
    """Integers whose running sums are the rounded running sums of ``x``; an InputError
    naming the table (``source``, ``key``) where they would not fit a 64-bit cycle count."""
    total = np.cumsum(x)
    if total.size and not total[-1] < MAX_CYCLES:  # (a table's absurd scale: 1e20 cycles an instruction)
        raise InputError(f"the table's costs make {total[-1]:.3g} cycles of this run's work, more than a 64-bit "
                         f"cycle count holds ({MAX_CYCLES:.3g})", source=source, key=key)
    c = np.rint(total).astype(np.int64)
    return np.diff(np.concatenate([[0], c]))


def _number(v, source: str, key: str, integer: bool = False) -> float:
    try:  # (an integer too large for a float is no number of cycles either)
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(float(v)) and v >= 0
    except OverflowError:
        ok = False
    if integer:
        ok = ok and float(v).is_integer()
    if not ok:
        kind = "a whole number" if integer else "a number"
        raise InputError(f"{v!r} must be {kind} >= 0", source=source, key=key)
    return int(v) if integer else float(v)


def _mapping(v, source: str, key: str) -> dict:
    if v is None:
        return {}
    if not isinstance(v, dict):
        raise InputError(f"must be a mapping, got {v!r}", source=source, key=key)
    return v


def _unknown(raw: dict, allowed, source: str, prefix: str) -> None:
    for k in raw:
        if k not in allowed:
            raise InputError(f"unknown key{did_you_mean(str(k), allowed)}", source=source, key=f"{prefix}.{k}")


MEMO_SIZE = 8  # the tables one process remembers (the least recently used goes)
_MEMO: OrderedDict[tuple[str, str], Programs] = OrderedDict()  # (source, sha256 of the text) -> table
_MEMO_LOCK = threading.Lock()
# (a pipe's table, ``--set arch.programs=<(...)``: its text is gone once read, and each case of a study reads the
# table again, so it is remembered by the pipe, its path and inode, while that is open: _pipe_of; never a named
# FIFO, whose next writer gives another table)
_PIPED: OrderedDict[tuple[str, int, int], Programs] = OrderedDict()


def load_programs(path: str | Path | None = None) -> Programs:
    """Read and check an instruction-cost table (default: the calibrated one).

    A table read before in this process (:data:`MEMO_SIZE` of them, the least recently used
    forgotten) is not parsed again while its file holds the same text: it is remembered by the
    path as given and the sha256 of the text, so an edited file is read again. Each call
    returns its own copy, which the caller may change."""
    p = Path(path) if path is not None else DEFAULT_PATH
    source = str(p)
    pipe = _pipe_of(p)
    with _MEMO_LOCK:
        got = _PIPED.get(pipe) if pipe is not None else None
    if got is not None:  # (read once: a second read of the pipe finds nothing)
        return copy.deepcopy(got)
    try:  # (read once, bounded: a pipe's table too, ``--set arch.programs=<(...)``; a folder, a device said as such)
        text = read_text(p)
    except InputError as e:
        raise e.replaced(key="arch.programs") from None
    key = (source, text_digest(text))
    with _MEMO_LOCK:
        got = _MEMO.get(key)
        if got is not None:
            _MEMO.move_to_end(key)
    if got is None:
        got = _parse_programs(yaml_from_text(text, p), source)
        with _MEMO_LOCK:
            _MEMO[key] = got
            while len(_MEMO) > MEMO_SIZE:
                _MEMO.popitem(last=False)
    if pipe is not None:
        with _MEMO_LOCK:
            _PIPED[pipe] = got
            while len(_PIPED) > MEMO_SIZE:
                _PIPED.popitem(last=False)
    return copy.deepcopy(got)  # (the remembered table stays as it was read)


def _pipe_of(path: Path) -> tuple[str, int, int] | None:
    """``(path, device, inode)`` of the anonymous pipe ``path`` names (``/dev/fd/N`` of ``<(...)``,
    ``/proc/PID/fd/N``: a descriptor's link that reads ``pipe:[inode]``), whose text a read takes away; None for
    anything else: a file is read again (an edit is seen), and so is a named FIFO (each writer gives a new text)."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):  # (not there, a NUL in the name: read_text says what it is)
        return None
    if not stat.S_ISFIFO(st.st_mode):
        return None
    link = str(path)
    for _ in range(40):  # (links to links: a descriptor's name, as /dev/fd/N is, ends at "pipe:[inode]")
        try:
            target = os.readlink(link)
        except OSError:  # (not a link: a named FIFO itself)
            return None
        if target.startswith("pipe:["):
            return str(path), st.st_dev, st.st_ino
        link = os.path.join(os.path.dirname(link), target)
    return None


def _parse_programs(raw, source: str) -> Programs:
    """The checked table of the YAML data ``raw`` read from ``source``."""
    raw = _mapping(raw, source, "(top)")
    _unknown(raw, ("calibration", *PROGRAMMABLE, "intersection"), source, "programs")
    scale, jobs, record_cycles = {}, {}, {}
    for pm in PROGRAMMABLE:
        if pm not in raw:
            raise InputError("missing section", source=source, key=pm)
        sec = _mapping(raw[pm], source, pm)
        _unknown(sec, ("scale", "record_cycles", *JOBS[pm]), source, pm)
        scale[pm] = _number(sec.get("scale", 1.0), source, f"{pm}.scale")
        record_cycles[pm] = _number(sec.get("record_cycles", 0.0), source, f"{pm}.record_cycles")
        for job in JOBS[pm]:
            if job not in sec:
                raise InputError("missing job program", source=source, key=f"{pm}.{job}")
            keys = work.job_keys(f"{pm}.{job}")  # the work it reads (tlm.kernels.work)
            js = _mapping(sec.get(job), source, f"{pm}.{job}")
            for part in ("instructions", "flushes"):
                for k in _mapping(js.get(part), source, f"{pm}.{job}.{part}"):
                    if k not in keys:
                        raise InputError(f"unknown work item{did_you_mean(str(k), keys)}", source=source,
                                         key=f"{pm}.{job}.{part}.{k}")
            _unknown(js, ("instructions", "flushes", "misses", "records"), source, f"{pm}.{job}")
            raw_items = js.get("records", [])
            if not isinstance(raw_items, list) or not all(isinstance(k, str) for k in raw_items):
                raise InputError(f"{raw_items!r} must be a list of work keys", source=source, key=f"{pm}.{job}.records")
            for k in raw_items:
                if k not in keys:
                    raise InputError(f"unknown work item{did_you_mean(k, keys)}", source=source,
                                     key=f"{pm}.{job}.records.{k}")
            if len(set(raw_items)) != len(raw_items):
                raise InputError(f"{raw_items!r} names a key twice", source=source, key=f"{pm}.{job}.records")
            ins = {str(k): _number(v, source, f"{pm}.{job}.instructions.{k}")
                   for k, v in _mapping(js.get("instructions"), source, f"{pm}.{job}.instructions").items()}
            fl = {str(k): _number(v, source, f"{pm}.{job}.flushes.{k}")
                  for k, v in _mapping(js.get("flushes"), source, f"{pm}.{job}.flushes").items()}
            misses = js.get("misses")
            if misses is not None and (not isinstance(misses, str) or misses not in keys):
                raise InputError(f"{misses!r} must be a work key or null{did_you_mean(str(misses), keys)}",
                                 source=source, key=f"{pm}.{job}.misses")
            priced = {*ins, *fl, *raw_items, misses}
            for item in work.job_items(f"{pm}.{job}"):
                if item.name in priced:
                    continue
                if item.name in _PRICED_BEFORE:  # (a table written before the item was counted apart: its costs)
                    ins[item.name] = 0.0
                    warn(f"{source}: {pm}.{job}: prices no {item.name!r}, counted apart since the table was written "
                         f"(it priced {_PRICED_BEFORE[item.name]}): read as 0, which keeps its costs; give "
                         f"{item.name} a weight to silence this")
                    continue
                raise InputError(f"does not price the work item {item.name!r}, which this job charges "
                                 f"(tlm/kernels/work.py; give it a weight, 0 if it costs nothing)",
                                 source=source, key=f"{pm}.{job}")
            jobs[(pm, job)] = JobProgram(ins, fl, misses, tuple(raw_items))
    isect = _mapping(raw.get("intersection"), source, "intersection")
    _unknown(isect, FIXED_KEYS, source, "intersection")
    defaults = {"ray_load_cycles": 2, "triangle_cycles": 3, "stages": 11}
    fixed = {k: _number(isect.get(k, defaults[k]), source, f"intersection.{k}", integer=True) for k in FIXED_KEYS}
    calibration = _mapping(raw.get("calibration"), source, "calibration")
    return Programs(source, scale, jobs, fixed, calibration, record_cycles)
