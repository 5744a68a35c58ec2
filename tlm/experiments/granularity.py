"""The TLM's second error-against-run-time curve: cycle error of coarse packets.

One packet per ray or pixel is the fine reference; coarser packets need fewer SimPy
events but blur the coupling of the PMs (a packet is the unit of transfer through the
FIFO, of preemption and of hand-over). An experiment file::

    base: {scene: cornell, mode: rcast, arch: {frames: 2}}   # a run config, or a run config file
    packet_sizes: [1, 16, 256, 4096, 1000000]                # 1 is the reference

``base`` may name a run config as a sweep's may (:func:`tlm.builtin.read_base`): a file
(``base: run.yaml``, relative to the study file), whose paths (its scene,
``arch.programs``) are then relative to that file, as they are for ``tlm run`` of it, or a
built-in run config (``base: cornell``, from a study file in any folder).

renders the frame once (its work comes from the functional cache when an identical
render was cached: only the SimPy layer reruns), simulates it at every packet size,
and writes ``granularity.csv`` and ``granularity.jsonl``: per packet size the cycles
(per PM, throughput, latency), the relative error of each against the reference, the
largest of them, the run's own estimate of how far the packets move TThru from packets
of one, over TThru (``granularity_share``, results.json ``timing.granularity.share``,
negative where they are faster; ``tlm run`` warns from 5% either way), the host wall
seconds of the simulation and its SimPy events; then (appended: the columns before keep
their places) the frames the stream simulated (``frames``: ``arch.frames``, or more where
it ran on until its completions repeated, at most ``arch.settle_frames``:
tlm/arch/steady.py, which may happen at one packet size and not at another) and the
seconds and events per frame (``simulate_seconds_per_frame``, ``simpy_events_per_frame``),
the ones to compare where the rows ran different frame counts (:func:`frames_differ`);
beside them ``config.resolved.yaml``, ``provenance.json`` (versions, git revision, host
seconds) and ``granularity_summary.json`` (:data:`SUMMARY`, the study's own record, as a thesis
study's ``thesis_summary.json``: its ``warnings``, the lines said on stderr, which the report lists;
the frame's largest phase the packet size cuts, the sizes at or past it, which run every phase as
one packet and so give the same cycles, and the line that says so: :func:`one_packet_line`).
Images do not depend on the packet size (the functional layer never sees it).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

from tlm.arch.granularity import fine_ti_cycles
from tlm.arch.model import simulate
from tlm.config import config_from_dict, file_folder
from tlm.config_words import listing, type_hint, value_text, with_overrides
from tlm.errors import InputError
from tlm.experiments.frames import cached_render
from tlm.experiments.run import programs_for
from tlm.experiments.run_warnings import empty_sets, reference_warnings
from tlm.experiments.study import read_study_base, refuse_own_keys, refuse_set, run_study, with_set
from tlm.storage import check_destination, warn

METRICS = ("vertex", "traversal", "intersection", "fragment", "throughput", "latency")
COLUMNS = ("packet_size", *METRICS, *(f"rel_error_{m}" for m in METRICS), "max_abs_rel_error",
           "granularity_share", "simulate_seconds", "simpy_events", "reference",
           # (h364, appended: a stream may run on past arch.frames at one size and not at another, and the two
           # before are totals over the frames run; these make the rows comparable)
           "frames", "simulate_seconds_per_frame", "simpy_events_per_frame")
KEYS = ("packet_sizes",)  # the study's own keys, beside base and description
SUMMARY = "granularity_summary.json"  # the study's own record (its warnings, the sizes that run as one packet)
# a BSP build's job: a packet per level of its tree at any packet size (tlm/arch/frame_program.py, _level_packets)
LEVEL_KINDS = ("geometry_bsp", "photon_bsp")


def load_granularity(path: Path, overrides: tuple[str, ...] = ()):
    """``(config, packet sizes in increasing order, the folder its relative paths start at)``
    of the study file ``path``; InputError names the file and the key (a size listed twice: as ``tlm sweep``
    refuses a value a grid lists twice, h416). ``overrides``: ``tlm granularity --set`` strings, applied to
    the base as ``tlm run --set`` applies them; one of ``arch.packet_size``, which ``packet_sizes`` sets, or of the
    study file's own keys (``packet_sizes``, ``base``, ``description``: :func:`refuse_own_keys`), is
    refused, as is a bad key or value."""
    path = Path(path)
    src = str(path)
    overrides = tuple(overrides)  # (read twice: an iterator's, once; h455)
    raw, base, base_src, folder = read_study_base(path, KEYS, overrides)
    sizes = raw.get("packet_sizes")
    if (not isinstance(sizes, list) or not sizes
            or not all(isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in sizes)):
        raise InputError(f"{value_text(sizes)} must be a non-empty list of whole numbers >= 1{_whole_hint(sizes)}"
                         f"{_twice_too(sizes)}", source=src, key="packet_sizes")
    twice = next((v for i, v in enumerate(sizes) if v in sizes[:i]), None)
    if twice is not None:  # (as tlm sweep words a value a grid lists twice: its row would be one simulation, twice)
        raise InputError(f"{value_text(twice)} given twice", source=src, key="packet_sizes")
    if overrides:
        config_from_dict(base, base_src)  # (the base's own errors first, naming its file)
        base = with_set(base, overrides, list(dict.fromkeys([folder, file_folder(path)])))
        # (the study file's own keys, not the run config's: h409 found "unknown key" here)
        refuse_own_keys(overrides, KEYS, src)
        refuse_set(overrides, {"arch.packet_size": "set by the study's packet_sizes, one simulation each: list "
                                                   "them there, not by --set"}, src)
        base_src = with_overrides(base_src)
    cfg = config_from_dict(base, base_src)
    return cfg, sorted(sizes), folder


def _whole_hint(sizes) -> str:
    """What to write instead, where ``sizes`` is a list of whole numbers >= 1 some written as floats
    (``[2e12]``, ``[4.0]``: YAML reads a number with an exponent or a point as a float), as tlm says it of
    a config's integer (:func:`tlm.config_words.type_hint`); else nothing."""
    def whole(v) -> bool:
        return ((isinstance(v, int) and not isinstance(v, bool))
                or (isinstance(v, float) and math.isfinite(v) and v.is_integer())) and v >= 1

    if not isinstance(sizes, list) or not all(whole(v) for v in sizes):
        return ""
    return type_hint(sizes, list[int], {})


def _twice_too(sizes) -> str:
    """Where ``sizes`` (a list refused for its types or values) gives one number twice, compared as numbers
    (``[4, 4.0]``, ``[4, 4, 0]``): the clause that says so, to follow the list's other error in its line, so
    that the fix of that one is not refused next for this (h435); else nothing."""
    if not isinstance(sizes, list):
        return ""
    numbers = [v for v in sizes if isinstance(v, (int, float)) and not isinstance(v, bool)]
    twice = next((v for i, v in enumerate(numbers) if v in numbers[:i]), None)
    if twice is None:
        return ""
    written = list(dict.fromkeys(value_text(v) for v in numbers if v == twice))
    whole = isinstance(twice, float) and twice.is_integer() and abs(twice) < 1e21
    also = f" (as {' and '.join(written)})" if len(written) > 1 else ""
    return f"; and {value_text(int(twice) if whole else twice)} is given twice{also}: list it once"


def run_granularity(path: Path, out: Path, progress=None, overrides: tuple[str, ...] = (), *,
                    via: str = "--set", warned=warn, start=None, noted=None) -> list[dict]:
    """Simulate the frame of ``path`` at each packet size; rows relative to the smallest.
    ``overrides``: ``tlm granularity --set`` strings (:func:`load_granularity`), in the study's
    ``config.resolved.yaml`` by their values and listed in its ``provenance.json``; one that sets
    nothing (``--set render={}``: :func:`~tlm.experiments.run_warnings.empty_sets`, naming them ``via``)
    is given to ``warned`` (default: said on stderr; :func:`tlm.api.granularity` returns it), and so is each
    of the rendered frame's own warnings, as ``tlm run`` says them, led by ``granularity: ``; those lines are
    kept in the study's ``granularity_summary.json`` (:func:`summary_record`), which the report lists.
    ``start(sizes)``, where given, gets the packet sizes (increasing, the order they are simulated in) once,
    before the first (``tlm granularity`` aligns its progress lines by the widest: h407); ``noted(record)``
    gets that record once it is known (:func:`tlm.api.granularity` returns its line and sizes)."""
    overrides = tuple(str(o) for o in overrides)
    cfg, sizes, folder = load_granularity(Path(path), overrides)
    said: list[str] = []  # (each line given to warned, kept in the study's record, which the report reads: h400)

    def say(line: str) -> None:
        said.append(line)
        warned(line)

    for line in empty_sets(overrides, via):  # (a --set render={} sets nothing: said once, as tlm run says it)
        say(line)
    check_destination(out, "granularity.jsonl")  # before the render
    programs = programs_for(cfg, folder)
    got = cached_render(cfg, folder, str(path))
    fn = got.functional
    # the frame's own warnings, as tlm run says them (a camera that sees nothing, a black image, a light that
    # reaches nothing: the study's cycles are of that frame, h394); not the photon frame's error, none of its business
    off = reference_warnings(got.summary.get("error"), cfg, got.summary.get("photons"),
                             (got.summary.get("scene") or {}).get("photons"))  # (the blur line too, h453)
    for line in dict.fromkeys(got.summary.get("warnings") or []):
        if line not in off:
            say(f"granularity: {line}")
    if any(size > 1 for size in sizes):  # the coarse sizes' estimate against packets of one, once untimed:
        # a large frame's flow shops load their compiled kernel at the first call (numba's import, ~2 s),
        # which would be booked as the first coarse size's host seconds (a small frame's take the loop)
        fine_ti_cycles(fn, programs, replace(cfg.arch, trace=False))

    largest: list[dict | None] = []  # the frame's largest phase the packet size cuts (the same at every size)
    if start is not None:
        start(list(sizes))

    def one(size: int, _folder: Path) -> dict:
        t0 = time.perf_counter()
        tm = simulate(fn, programs, replace(cfg.arch, packet_size=size, trace=False))
        secs = time.perf_counter() - t0
        if not largest:
            largest.append(largest_phase(tm.program))
        if progress is not None:
            progress(size, tm, secs)
        frames = len(tm.frames)  # (arch.frames, or more: the stream ran on until it settled, tlm/arch/steady.py)
        return {"packet_size": size, **{m: tm.cycles[m] for m in METRICS}, "simulate_seconds": round(secs, 4),
                "simpy_events": tm.events, "granularity_share": tm.granularity["share"], "frames": frames,
                "simulate_seconds_per_frame": round(secs / frames, 6),
                "simpy_events_per_frame": round(tm.events / frames, 1)}

    def relative(raw: list[dict], _folder: Path) -> list[dict]:
        ref = raw[0]  # the smallest packet size is the reference
        rows = []
        for r in raw:
            errs = {f"rel_error_{m}": (r[m] - ref[m]) / ref[m] if ref[m] else 0.0 for m in METRICS}
            rows.append({"packet_size": r["packet_size"], **{m: r[m] for m in METRICS},
                         **{k: round(v, 6) for k, v in errs.items()},
                         "max_abs_rel_error": round(max(abs(v) for v in errs.values()), 6),
                         "granularity_share": r["granularity_share"],
                         "simulate_seconds": r["simulate_seconds"], "simpy_events": r["simpy_events"],
                         "reference": sizes[0], "frames": r["frames"],
                         "simulate_seconds_per_frame": r["simulate_seconds_per_frame"],
                         "simpy_events_per_frame": r["simpy_events_per_frame"]})
        return rows

    def record(_rows: list[dict]) -> dict:
        kept = summary_record(sizes, largest[0] if largest else None, said)
        if noted is not None:
            noted(kept)
        return {SUMMARY: kept}

    return run_study(str(path), out, "granularity", sizes, one, columns=COLUMNS, config=cfg, finish=relative,
                     files=record, overrides=overrides)


def largest_phase(program) -> dict | None:
    """``{"phase", "items", "unit"}`` of the largest phase of ``program`` (a FrameProgram) that the packet size
    cuts into packets: its name (``rcast.rays``; the largest of its tiles'), its items (pixels, or photons in a
    ``photons.*`` phase: what its first job's packets hold, at any packet size) and their unit, with ``tiles``, the
    tiles of its stage, where it has more than one (a stage over several pipelines: the items are its largest
    tile's, not the frame's); None where no phase is cut by the packet size (a BSP build's job,
    :data:`LEVEL_KINDS`, is a packet per level at any size)."""
    best = None
    for stage in program.stages:
        for ph in (ph for tile in stage.tiles for ph in tile.phases):
            job = ph.jobs[0] if ph.jobs else None
            if job is None or job.kind in LEVEL_KINDS:
                continue
            n = int(job.items.sum())
            if best is None or n > best["items"]:
                best = {"phase": ph.name, "items": n, "unit": "photons" if ph.name.startswith("photons.") else "pixels"}
                if len(stage.tiles) > 1:  # (a tile's items, not the frame's: h402)
                    best["tiles"] = len(stage.tiles)
    return best


def one_packet_sizes(sizes: list[int], largest: dict | None) -> list[int]:
    """The packet sizes of ``sizes`` at or past the items of ``largest`` (:func:`largest_phase`; None: every
    size): at each, every phase runs as one packet, so they simulate the same program."""
    return [s for s in sizes if largest is None or s >= largest["items"]]


def one_packet_line(sizes: list[int], largest: dict | None) -> str:
    """The line ``tlm granularity`` says under its table, and its record keeps, where two or more packet sizes of
    ``sizes`` are at or past the frame's largest phase (:func:`one_packet_sizes`): each phase runs as one packet
    at each, so their cycles are the same (h394/h397: at 16x16, 256 to 102400 gave the same row, unsaid); "" where
    fewer are (one size alone gives no row another repeats; the record lists it in ``one_packet``)."""
    at = one_packet_sizes(sizes, largest)
    if len(at) < 2:
        return ""
    listed = listing(at)
    same = "so their cycles, errors and events are the same"
    if largest is None:  # (no phase cut: every size runs the same program)
        return (f"packet sizes {listed}: the frame has no pixel or photon phase for a packet size to cut (its BSP "
                f"builds are a packet per level), {same}")
    n, unit = largest["items"], largest["unit"]
    of = f", in the largest of its {largest['tiles']} tiles" if largest.get("tiles") else ""  # (a tile's items: h402)
    return (f"packet sizes {listed} are at or past the {n} {unit if n != 1 else unit[:-1]} of the frame's largest "
            f"phase ({largest['phase']}{of}): each phase runs as one packet at each, {same}")


def summary_record(sizes: list[int], largest: dict | None, warnings: list[str]) -> dict:
    """The study's ``granularity_summary.json`` (:data:`SUMMARY`): its ``warnings`` (the lines said on stderr,
    each once: the overrides' and the frame's own; the report lists them), the frame's ``largest_phase``
    (:func:`largest_phase`), the ``one_packet`` sizes (:func:`one_packet_sizes`) and ``notes``, the line
    saying so (:func:`one_packet_line`; none where it is "")."""
    line = one_packet_line(sizes, largest)
    return {"warnings": list(dict.fromkeys(warnings)), "largest_phase": largest,
            "one_packet": one_packet_sizes(sizes, largest), "notes": [line] if line else []}


def frames_differ(rows: list[dict]) -> dict[int, list[int]]:
    """``{frames: [packet sizes]}`` (frames increasing) of a granularity study's rows where they ran
    different frame counts (a stream that ran on past ``arch.frames`` until its completions repeated,
    at some sizes and not at others: tlm/arch/steady.py); ``{}`` where they ran the same, or rows
    written before the ``frames`` column."""
    ran: dict[int, list[int]] = {}
    for r in rows:
        f = r.get("frames")
        if not isinstance(f, int) or isinstance(f, bool):
            return {}
        ran.setdefault(f, []).append(r["packet_size"])
    return dict(sorted(ran.items())) if len(ran) > 1 else {}
