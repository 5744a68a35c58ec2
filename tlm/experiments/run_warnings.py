"""What a run warns of: ``results.json`` ``warnings``, one line each, of what gives no error
but a wrong or a misleading result.

:func:`run_warnings`: the render's (a scene, camera or image check of :mod:`tlm.render.checks`,
a setting the run never reads, an override of a key whose pass is left out:
:func:`unread_overrides`, a reference not converged or much blurrier than the run, photon paths cut with power in flight
(:mod:`tlm.experiments.photon_warnings`): :func:`reference_warnings`,
a BSP cut short); :func:`stream_warnings`: the simulated stream's (too few frames, a period whose gaps differ:
:func:`period_warnings`, packets too coarse from :data:`GRANULARITY_WARNING` on, tiles without pixels, a key set
that the timing model never read: :func:`timing_inert`). A sweep point records :func:`inert_timing_changes` too.
:func:`tlm.experiments.run.results_dict` puts them in ``results.json``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from fractions import Fraction
from typing import Any

import numpy as np

from tlm.arch.fifo import fifo_depth_alike, fifo_held
from tlm.arch.model import Timing, settling
from tlm.arch.steady import runs_alike
from tlm.config import ArchConfig, RunConfig
from tlm.config_words import sets_nothing
from tlm.experiments.photon_warnings import cut_warnings
from tlm.experiments.study import override_key, set_leaves
from tlm.registry import SCHEDULERS
from tlm.render import checks
from tlm.render.planner import inert_changes, inert_timing_settings, uses_radius, walk_inert_settings

# RenderResult (tlm.experiments.run, which imports this module) is named in annotations only and not
# imported: an import, even under TYPE_CHECKING, would make the two modules a cycle (tests/test_layers.py)


def eye_hits(res: RenderResult) -> tuple[int, int, int, int]:  # noqa: F821
    """Pixels, eye rays, their hits and their hits on the back of an opaque triangle."""
    if res.primary is not None:
        return res.primary.t.shape[0], res.primary.rays, res.primary.hits, res.primary.back
    g = res.gbuffer  # (a result made by hand, not by render)
    back = checks.back_faces(res.scene, g.triangle, g.direction)
    return g.pixels.shape[0], g.origin.shape[0], int((g.triangle >= 0).sum()), back


def run_warnings(res: RenderResult) -> list[str]:  # noqa: F821
    """What gives no error but a wrong picture (:mod:`tlm.render.checks`), a setting the run
    never reads (each key once: an override of ``res.overrides`` the run never reads, a
    photon-map key with the pass left out or a specular walk's key the mode never reads, by
    :func:`unread_overrides`, else by :func:`~tlm.render.planner.inert_changes`), an override that
    sets nothing (``render={}``: :func:`empty_sets`), a photon-map pass a setting left out (:func:`left_out_warnings`),
    a photon-map reference that is not converged (:func:`reference_warnings`), ``render.threads`` past the
    CPUs available (:func:`threads_warning`), a BSP cut short: ``results.json`` ``warnings`` but the
    simulated stream's (:func:`stream_warnings`), one line each."""
    _, rays, hits, back = eye_hits(res)
    warnings = [*checks.file_warnings(res.scene), *checks.material_warnings(res.scene),
                *checks.light_warnings(res.scene, res.accel),
                *checks.camera_warnings(rays, hits, back),
                *checks.image_warnings({n: res.radiance[n] for n in res.plan.run_names if n in res.radiance},
                                       checks.light_scale(res.scene, res.accel.scale))]
    if res.photons is not None:
        st = res.photons.photons.stats()
        warnings += checks.photon_warnings(st["emitted"], st["stored"])
    warnings += left_out_warnings(res.plan, res.cfg)
    unread = _unread(res, res.overrides)
    warnings += inert_changes(res.cfg, skip=unread)
    warnings += _unread_lines(res, unread, res.via)
    warnings += empty_sets(res.overrides, res.via)
    warnings += trace_dropped(res.cfg, res.overrides, res.via)
    warnings += reference_warnings(res.error, res.cfg, emitted_photons(res), res.scene.photons)
    warnings += checks.branching_warning(res.cfg, res.scene)
    warnings += threads_warning(res.cfg)
    if "pmap" in res.plan.run_names:
        warnings += checks.radius_warnings(res.cfg, res.accel.scale)
    if res.accel.tree.truncated:
        t = res.accel.tree
        warnings.append(f"BSP stopped at {t.levels} of {t.requested_levels} levels: the expansion would exceed "
                        f"{res.cfg.bsp.memory_factor:g}x the triangle list")
    return warnings


def left_out_warnings(plan, cfg: RunConfig) -> list[str]:
    """The photon-map pass that the run's mode asks for and a setting of its config left out
    (``photons.count`` 0, ``photons.max_bounces`` under 2: the plan's ``by``), once: no photon is
    traced and the run has no pmap frame, which its passes and images would otherwise leave unsaid."""
    return [f"mode {cfg.mode!r} asks for the photon-map pass, but {p.reason}: the pass is left out, no photon is "
            f"traced and the run has no pmap frame (its passes: {', '.join(plan.run_names)})"
            + (_COUNT_HINT if p.by == "photons.count" and cfg.photons.count is None else "")
            for p in plan.passes if p.name == "pmap" and not p.run and p.by is not None]


# (a null photons.count takes the scene file's photons:, 0 where it gives none: say where to give it)
BUILTIN_COUNTS = "(the built-in scenes give 20000 to 480000: cornell 120000, conference 200000)"
_COUNT_HINT = ("; the config's photons.count is null, so the scene file's photons: counts, and it gives 0 or "
               f"none: give the scene file photons: N, or --set photons.count=N {BUILTIN_COUNTS}")


def threads_warning(cfg: RunConfig | None, cpus: int | None = None) -> list[str]:
    """A line when ``render.threads`` asks for more threads than the ``cpus`` this process may run on
    (default: :func:`~tlm.kernels.threads.available`, its affinity mask within a control group's CPU
    quota, which a null ``render.threads`` takes): allowed, bit for bit the same images, work and cycles,
    but slower, as the threads (or forked workers) take turns on them. None for null (the CPUs
    available) or a count no more than them. A run says it once (``results.json`` ``warnings``); a
    sweep's point records it in its own ``results.json``, as the render's other warnings."""
    asked = getattr(getattr(cfg, "render", None), "threads", None)
    if asked is None:
        return []
    if cpus is None:
        from tlm.kernels.threads import available

        cpus = available()
    if asked <= cpus:
        return []
    return [f"render.threads = {asked} is more than the {cpus} CPU{'s' if cpus != 1 else ''} available to this "
            "process (its affinity mask, within a control group's CPU quota): the kernels' threads take turns on "
            "them, which is slower, not faster (images, work and cycles are the same for every count); leave "
            "render.threads null for the CPUs available"]


# |timing.granularity.share| from which a run warns (docs/architecture.md, "Packet size": on frames of 32x32 and
# 48x48 at packets of 16 to 1024, 26 of the 30 settings it fires on measure over 5%, none under 2%)
GRANULARITY_WARNING = 0.05


def stream_warnings(timing: Timing | None, cfg: RunConfig) -> list[str]:
    """The simulated stream's warnings, one line each: too few frames for a steady-state
    throughput; packets so coarse that they move TThru from that of packets of one by a
    large share, either way (:func:`~tlm.arch.granularity.granularity_estimate`, from
    :data:`GRANULARITY_WARNING` on: :func:`granularity_line`); image tiles without pixels; and what only the run can
    tell of a setting changed from its default that it never read (:func:`timing_inert`)."""
    if timing is None:
        return []
    lines = []
    est = timing.throughput_estimate
    if est and est.get("settled") is False and not est["steady"]:  # (settled or not, steady: said in its estimate)
        a, b = est["window"]
        # (one running mean, a window of one gap: no movement to measure, its spread of 0 says nothing)
        over = ("its last steady gap alone, too few completions to tell whether it moves" if b - a < 2 else
                f"the mean gap over its last {b - a} steady completions, whose running mean moved by "
                f"{est['spread']:.2%} over their last half")
        # (the stream ran max(arch.frames, arch.settle_frames) frames: a bound at or below that changes nothing)
        lines.append(f"the stream did not settle within {est['frames']} frames (its completions "
                     f"did not repeat): cycles.throughput is {over}; raise arch.settle_frames (the most frames it "
                     f"runs) above {est['frames']} to settle it")
    elif est and not est["steady"] and est.get("settled") is None:
        lines.append(f"arch.frames={est['frames']} is too short for a steady-state throughput (at least "
                     f"{est['min_frames']} frames with arch.images_in_flight={cfg.arch.images_in_flight}): "
                     "cycles.throughput is the stream's elapsed cycles per frame")
    lines += period_warnings(timing, cfg.arch.images_in_flight)
    share = (timing.granularity or {}).get("share", 0.0)
    if abs(share) >= GRANULARITY_WARNING:
        lines.append(granularity_line(timing.granularity, timing.cycles["throughput"], cfg.arch.packet_size,
                                      cfg.arch.images_in_flight))
    tiling = timing.program.tiling or {}
    bounds = tiling.get("tiles") or []
    empty = sum(1 for x0, y0, x1, y1 in bounds if x0 == x1 or y0 == y1)
    if empty:
        width, height = max(b[2] for b in bounds), max(b[3] for b in bounds)
        queue = "" if SCHEDULERS[timing.program.scheduler].pinned else f" of the {timing.program.scheduler} queue"
        lines.append(f"arch.pipelines = {cfg.arch.pipelines}: {empty} of the {len(bounds)} image tiles{queue} have "
                     f"no pixels (a {width}x{height} image cut into a {tiling['rows']}x{tiling['cols']} grid): a "
                     "pipeline given one has no pixel work in it")
    lines += [f"{key} = {getattr(cfg.arch, key.split('.', 1)[1])!r} has no effect in this run: {why}"
              for key, why in timing_inert(timing, cfg.arch).items()]
    return lines + fifo_depth_lines(timing, cfg.arch)


# the gaps of a steady period of two frames or more apart by this share of TThru (their largest less their
# smallest) from which a run warns: two images in flight take turns, and the mean over the period jumps with the
# work (h453, Cornell refract, render.spp 1, 1 pipeline: resolution 33x31 -> 33x32, 3% more pixels, gaps
# 2526275/1800904 -> 2660842/2398486, fps 277.3 -> 237.2, -14%; 31x30 -> 31x31, period 1 -> 2 (33% apart), fps
# 259.0 -> 277.4, +7% for 3% more pixels)
PERIOD_WARNING = 0.10


def period_gaps(timing: Timing) -> list[int] | None:
    """The gaps (cycles between completions) of one period of the stream's steady state, the one
    ``cycles.throughput`` is the mean over: a settled stream's ``period`` (``timing.throughput_estimate``),
    else a steady window's own shortest period where the window holds two of it at least (the static tiles'
    stream, periodic from the warm-up); None where the stream shows no period (too short, not settled)."""
    est = timing.throughput_estimate or {}
    window = est.get("window")
    if not est.get("steady") or not window or est.get("settled") is False:
        return None
    done = sorted(f["done"] for f in timing.frames)
    a, b = window
    gaps = [done[i + 1] - done[i] for i in range(a, b)]
    period = est.get("period") or next((p for p in range(1, len(gaps) // 2 + 1) if len(gaps) % p == 0
                                        and all(gaps[i] == gaps[i + p] for i in range(len(gaps) - p))), None)
    return None if period is None or period > len(gaps) else gaps[:period]


def period_warnings(timing: Timing, images_in_flight: int) -> list[str]:
    """A line when the steady state is a period of two frames or more (:func:`period_gaps`) whose gaps
    differ by :data:`PERIOD_WARNING` of ``cycles.throughput`` or more, largest less smallest: the images in
    flight take turns (one image's frame done soon after the other's, then a long wait), ``cycles.throughput``
    and ``fps`` are the mean over the period, and a small change of the work can change the turns and move
    that mean by more than the work changed, even the other way."""
    gaps = period_gaps(timing) if images_in_flight > 1 else None  # (one image: each frame alone, the same gap)
    if not gaps or len(gaps) < 2:
        return []
    mean = sum(gaps) / len(gaps)
    share = (max(gaps) - min(gaps)) / mean if mean > 0 else 0.0
    if share < PERIOD_WARNING:
        return []
    shown = (" and ".join(str(g) for g in gaps) if len(gaps) == 2 else ", ".join(str(g) for g in gaps)
             if len(gaps) <= 4 else f"from {min(gaps)} to {max(gaps)}")
    return [f"the stream settled into a period of {len(gaps)} frames whose gaps differ by {share:.0%} of "
            f"cycles.throughput ({shown} cycles; timing.frame_times): the {images_in_flight} images in flight "
            "take turns, and cycles.throughput and fps are the mean over the period, which a small change of the "
            "work (a few pixels more, another render.spp) can move by more than the work changed, even the other "
            "way (the turns change); treat differences between runs smaller than that as noise, or compare with "
            "arch.images_in_flight = 1 (each frame alone, no turns)"]


def inert_timing_changes(timing: Timing, cfg: RunConfig) -> dict[str, str]:
    """The timing model's and the cache's keys ``cfg`` changes from their defaults that this
    simulated run never read, each with why: those the config alone shows
    (:func:`~tlm.render.planner.inert_timing_settings`) and those only the run can tell
    (:func:`timing_inert`). A sweep point records them (``results.json`` ``inert``), and
    the sweep names a factor that every point it ran agrees on
    (:meth:`tlm.experiments.sweep_file.Sweep.unread_factors`)."""
    defaults = RunConfig()
    out = {key: why for key, why in inert_timing_settings(cfg).items()
           if _value(cfg, key) != _value(defaults, key)}
    out.update(timing_inert(timing, cfg.arch))
    return out


def _value(cfg: RunConfig, key: str):
    section, name = key.split(".", 1)
    return getattr(getattr(cfg, section), name)


def timing_inert(timing: Timing, arch: ArchConfig) -> dict[str, str]:
    """The arch keys set away from their defaults that this simulated run provably never
    read, each with why (the keys whose inertness the config alone shows are
    :func:`~tlm.render.planner.inert_timing_settings`'):

    * ``arch.swap_cycles`` when no PM moved to another module (the value is read at a
      swap only);
    * ``arch.context_switch_cycles`` with two images in flight when no PM was preempted
      (read at a preemption only);
    * ``arch.fifo_depth`` when every Traversal/Intersection job's FIFO behaves alike at
      this depth and the default's: every packet carries at least as many triangle
      addresses as the larger depth (each enters an empty FIFO alone at either), or the
      job's packets all fit in the smaller one together (the FIFO never fills); and, past
      packets of one, where the packets-of-one estimate (``timing.granularity``, its
      phases' rays, pixels or photons one by one at ``arch.fifo_depth``) is alike too: they
      fit in the smaller depth together, each taking an entry at least (a phase's triangle
      addresses plus ``arch.packet_size`` a packet: a coarse packet that enters alone says
      nothing of its rays); or, past those rules, where the FIFOs' peaks (``timing.fifo``)
      show every put entering the cycle it did at either depth
      (:func:`tlm.arch.fifo.fifo_depth_alike`) and the estimate does not read the depth (packets of
      one, or no ``change_cycles``); where it does, :func:`fifo_depth_lines` says the cycles alone;
    * ``arch.settle_frames`` when a settling stream stopped where its completions repeated, below this bound
      and at or below the default's, or when both bounds give ``arch.frames`` (the run at either is the same);
      and when a static stream of two images did not run as a settling one (no ``frames_cap``): the steady gaps
      among the frames asked repeat from the first (:func:`tlm.arch.model.settles`), which no bound changes.
    """
    default = ArchConfig()
    out: dict[str, str] = {}
    est = timing.throughput_estimate or {}
    cap = est.get("frames_cap")  # (a settling stream's: tlm.arch.steady.frames_cap)
    if (arch.settle_frames != default.settle_frames and cap is None and est and timing.program is not None
            and SCHEDULERS[timing.program.scheduler].periodic_from_warmup and settling(timing.program, arch)):
        out["arch.settle_frames"] = (f"the steady gaps among the {arch.frames} frames asked repeat from the first: "
                                     "the static stream ran them alone, as it does at any bound")
    if arch.settle_frames != default.settle_frames and cap is not None:
        ran, other = len(timing.frames), max(arch.frames, default.settle_frames)
        if cap == other:
            out["arch.settle_frames"] = f"arch.frames = {arch.frames} bounds the stream at this value and the default's"
        elif runs_alike(ran, cap, other):
            asked = f"the {ran} frames asked (arch.frames), settled by then" if ran == arch.frames else \
                f"{ran} frames, where it settled"
            out["arch.settle_frames"] = (f"the stream ran {asked}: within this bound and the default's ({other})")
    xb = timing.crossbar or {}
    if arch.swap_cycles != default.swap_cycles and xb.get("swaps") == 0:
        out["arch.swap_cycles"] = "no PM moved to another module (timing.crossbar.swaps is 0)"
    if (arch.context_switch_cycles != default.context_switch_cycles and arch.images_in_flight > 1
            and not any((xb.get("preemptions") or {}).values())):
        out["arch.context_switch_cycles"] = "no PM was preempted (timing.crossbar.preemptions are 0)"
    if arch.fifo_depth != default.fifo_depth:
        lo, hi = sorted((arch.fifo_depth, default.fifo_depth))
        fifo = [ph.jobs[0] for ph in timing.program.phases if len(ph.jobs) == 2 and ph.jobs[0].entries is not None]
        ways = {_fifo_alike(np.asarray(js.entries, dtype=np.int64), lo, hi) for js in fifo}
        # (the estimate's packets of one, a packet's rays, pixels or photons one by one, each an entry at least)
        fine = arch.packet_size == 1 or "change_cycles" not in (timing.granularity or {}) or all(
            int(np.asarray(js.entries, dtype=np.int64).sum()) + len(js.entries) * arch.packet_size <= lo for js in fifo)
        if ways and None not in ways and fine:
            out["arch.fifo_depth"] = {
                frozenset({"alone"}): f"every packet carries at least {hi} triangle addresses, so it enters an "
                                      f"empty FIFO alone at depth {lo} and at {hi} (lower arch.packet_size to see "
                                      "the depth)",
                frozenset({"together"}): f"every Traversal/Intersection phase's packets fit in {lo} FIFO entries "
                                         "together: the FIFO never fills"}.get(
                frozenset(ways), f"each Traversal/Intersection phase's packets either all carry at least {hi} "
                                 f"triangle addresses or fit in {lo} FIFO entries together")
        elif _estimate_blind(timing, arch) and fifo_depth_alike(getattr(timing, "fifo", None), arch.fifo_depth,
                                                                 default.fifo_depth):
            out["arch.fifo_depth"] = _fifo_why(timing.fifo, arch.fifo_depth, default.fifo_depth)
    return out


def _estimate_blind(timing: Timing, arch: ArchConfig) -> bool:
    """Whether ``timing.granularity`` reads no FIFO depth: packets of one (the estimate is 0),
    or no ``change_cycles`` (a program built by hand: no flow shop in it)."""
    return arch.packet_size == 1 or "change_cycles" not in (timing.granularity or {})


def fifo_depth_lines(timing: Timing | None, arch: ArchConfig) -> list[str]:
    """The line for an ``arch.fifo_depth`` away from its default that leaves every simulated
    cycle as at the default (the FIFOs' peaks, ``timing.fifo``:
    :func:`tlm.arch.fifo.fifo_depth_alike`) while the packets-of-one estimate
    (``timing.granularity``) may read it, so that :func:`timing_inert` does not call it
    unread: a sweep of the depth shows flat cycles, and this says why."""
    default = ArchConfig()
    if (timing is None or arch.fifo_depth == default.fifo_depth or _estimate_blind(timing, arch)
            or "arch.fifo_depth" in timing_inert(timing, arch)
            or not fifo_depth_alike(getattr(timing, "fifo", None), arch.fifo_depth, default.fifo_depth)):
        return []
    return [f"arch.fifo_depth = {arch.fifo_depth} changes no simulated cycle in this run (cycles, stalls and "
            f"frame times are those of the default {default.fifo_depth}): "
            f"{_fifo_why(timing.fifo, arch.fifo_depth, default.fifo_depth)}; only timing.granularity, the "
            "packets-of-one estimate, reads the depth (lower arch.packet_size to see it in the cycles)"]


def _fifo_why(peaks: dict, depth: int, other: int) -> str:
    """Why every put enters the cycle it did at ``depth`` and at ``other``, from the FIFOs'
    ``peaks`` (``timing.fifo``, :func:`tlm.arch.fifo.fifo_depth_alike` holding)."""
    lo, hi = sorted((depth, other))
    waited = peaks["waited"]
    parts = [f"no FIFO held more than {fifo_held(peaks)} at once (timing.fifo: peak_packets, peak_entries, "
             "peak_addresses)"]
    if peaks["peak_shared"]:
        parts.append(f"no packet entered beside others with more than {peaks['peak_shared']} triangle addresses "
                     f"held in all (timing.fifo.peak_shared), within depth {lo}")
    else:
        parts.append("every put " + ("that did not wait " if waited else "") + "found its FIFO empty")
    if not waited:
        return "; ".join(parts) + f", so no put ever waited, at depth {lo} or at {hi}"
    parts.append(f"the {waited} put{'s' if waited != 1 else ''} that waited each found one packet there that with "
                 f"it holds {peaks['least_waited']} triangle addresses or more (timing.fifo.least_waited), more than "
                 f"depth {hi}: each waited for that packet to leave at either depth")
    return "; ".join(parts) + f", so every put entered the FIFO the cycle it did at depth {lo} as at {hi}"


def granularity_line(granularity: dict, throughput: int, packet_size: int, images_in_flight: int) -> str:
    """The coarse-packet warning for ``timing.granularity`` (its ``share``, its
    ``over_slowest_pm`` against ``throughput``, TThru). With one image in flight the
    estimate is the change in TThru to the cycle, so the line gives its sign and size.
    With more, ``share`` is each Traversal/Intersection phase alone, which the other
    image's work partly fills or, rarely, widens: the measured change is mostly smaller
    and may take the other sign (Cornell refract 32x32 at 256: estimate +8.7%, measured
    -2.3%), so the line gives it as how far TThru can move either way, and
    ``over_slowest_pm`` (TThru less the slowest PM's cycles, below which packets of one
    cannot go) as the most that packets can add, in whole percent rounded up
    (docs/architecture.md, "Packet size")."""
    share = granularity.get("share", 0.0)
    size = f"{abs(share):.0%}"
    head = f"arch.packet_size = {packet_size} is coarse for this frame: "
    tail = ": measure it with 'tlm granularity', or lower arch.packet_size"
    if images_in_flight <= 1:
        how = (f"whole packets add about {size} of cycles.throughput to what packets of one ray would take (the "
               "Traversal and Intersection PMs' fill and drain of whole packets at the phase boundaries)"
               if share > 0 else
               f"packets of one ray would take about {size} of cycles.throughput more (entering the FIFO one by "
               "one, they leave the Traversal PM waiting for room more often: a whole packet enters at once, as "
               "into a deeper FIFO)")
        return f"{head}{how} (timing.granularity){tail}"
    alone = ("whole packets add that much to what packets of one ray would take, by their fill and drain at the "
             "phase boundaries" if share > 0 else
             "packets of one ray would take that much more, entering the FIFO one by one")
    over = granularity.get("over_slowest_pm")
    most = "" if over is None or throughput <= 0 else f", and add at most {math.ceil(100 * over / throughput)}%"
    cap = ("" if not most else "; over_slowest_pm, cycles.throughput less the slowest PM's cycles, is all that they "
           "can add")
    return (f"{head}with {images_in_flight} images in flight whole packets can move cycles.throughput by about {size} "
            f"either way against packets of one ray, mostly less{most} (timing.granularity: share {share:+.1%} is "
            f"each Traversal/Intersection phase alone, where {alone}; the other image's work fills part of that and "
            f"can turn the change's sign{cap}){tail}")


def _fifo_alike(entries: np.ndarray, lo: int, hi: int) -> str | None:
    """Why a job's FIFO, its packets carrying ``entries`` triangle addresses, behaves alike
    at the depths ``lo`` and ``hi`` (a packet takes min(entries, depth) entries, at least
    one): ``"alone"``, every packet fills the FIFO at both, so each enters it empty;
    ``"together"``, all of them fit at both at once, so it never fills; None: neither."""
    if entries.size and int(entries.min()) >= hi:
        return "alone"
    if int(np.clip(entries, 1, lo).sum()) <= lo:
        return "together"
    return None


PHOTON_SECTIONS = ("photons.", "estimate.", "reference.")  # read by the photon-map pass (and its reference) alone


def unread_overrides(res: RenderResult, overrides: Iterable[str] | None, via: str = "--set") -> list[str]:  # noqa: F821
    """An override of a key no pass of the run reads: a photon-map key (:data:`PHOTON_SECTIONS`)
    in a run whose photon-map pass is left out, a key of the specular walk (``render.reflect_depth``,
    ``render.refract_depth``, ``render.fresnel``, ``render.min_weight``) in a mode without the
    passes that walk (:func:`~tlm.render.planner.walk_inert_settings`): one line each, naming it as
    it was given (``--set estimate.k=9``; ``via`` ``the overrides``: ``estimate.k=9 (in the
    overrides)``). :func:`~tlm.render.planner.inert_changes` judges those keys as if every pass
    ran, since a config file may hold them for another ``--mode``; a key given as an override was
    asked for this run. A key set twice is named once, by the override that set it last (a section
    given as a mapping, ``estimate={k: 9}``, sets the keys it names, as it merges into the section:
    :func:`~tlm.experiments.study.set_leaves`, so ``estimate={}`` sets none; one that sets a key the
    run reads too names those it does not; ``estimate=null`` sets the whole section, each key of it
    set before). Not the key the photon-map pass is left out by (``--set photons.count=0``, ``--set
    photons.max_bounces=1``: the plan's ``by``), nor a section that holds it, which did what it was
    set for. Then a line each, in the same words, for an override that sets nothing in any run
    (:func:`empty_sets`: ``--set render={}``)."""
    return [*_unread_lines(res, _unread(res, overrides), via), *empty_sets(overrides, via)]


def empty_sets(overrides: Iterable[str] | None, via: str = "--set") -> list[str]:
    """A line for each override that gives a section a mapping naming no key (``--set render={}``; through
    the API ``{"render": {}}``, ``via`` ``the overrides``): a mapping merges into its section
    (:func:`~tlm.config_words.laid_over`), so it sets nothing, where it used to give the section at its
    defaults, as ``render=null`` does (:func:`~tlm.config_words.sets_nothing`). Worded as
    :func:`unread_overrides`' lines (``... has no effect in this run: ...``), so that a study that says
    those once for all its cells (``tlm thesis``) says these once too; an override given twice, once."""
    lines = []
    for item in dict.fromkeys(str(o).strip() for o in overrides or ()):
        if set_leaves(item):  # (it sets a key; a value YAML cannot read: its key, refused elsewhere)
            continue
        null = f"{override_key(item)}=null"
        lines.append(f"{_given(via)(item)} has no effect in this run: it "
                     f"{sets_nothing(f'{via} {null}' if via.startswith('-') else null)}")
    return lines


def trace_dropped(cfg: RunConfig, overrides: Iterable[str] | None, via: str = "--set") -> list[str]:
    """A line when an override asks for the timing model's trace (``--set arch.trace=true``, the last
    override of the key) and the run keeps none: ``tlm run --outputs`` without ``trace`` (``--outputs
    images``) turns ``arch.trace`` off (:func:`tlm.experiments.run.run`: the outputs name what the folder
    gets), so no ``trace.json`` is written; the line says why, naming the override as it was given, and the
    outputs as they were: ``tlm run --outputs``, or ``tlm.api.run``'s ``outputs`` where the overrides came
    through the API (``via`` not a flag: ``the overrides``)."""
    if cfg.arch.trace:
        return []
    asked = None
    for item in overrides or ():
        leaves = set_leaves(item)
        if "arch.trace" in leaves:
            asked = (item, leaves["arch.trace"])
    if asked is None or asked[1] is not True:
        return []
    where, add = (("tlm run --outputs", "--outputs images,trace") if via.startswith("-") else
                  ("tlm.api.run's outputs", 'outputs="images,trace"'))  # (h426: the API's caller has no flags)
    return [f"{_given(via)(str(asked[0]).strip())} is not kept: no trace.json is written, because the run's "
            f"outputs ({where}) do not name trace; add it ({add}) to write one"]


def _given(via: str):
    """How a line names an override given ``via``: ``--set estimate.k=9``, or ``estimate.k=9 (in the
    overrides)``."""
    return (lambda item: f"{via} {item}") if via.startswith("-") else (lambda item: f"{item} (in {via})")


def _walk_unread(res: RenderResult) -> dict[str, str]:  # noqa: F821
    """The specular walk's keys the run's mode never reads, each with why (none for a result
    made by hand that holds no config, its plan alone)."""
    cfg = getattr(res, "cfg", None)
    return {} if cfg is None else walk_inert_settings(cfg.mode)


def _photon_why(res: RenderResult) -> str | None:  # noqa: F821
    """Why an override of a photon-map key changes nothing (its pass is left out), or None when the pass runs."""
    if "pmap" in res.plan.run_names:
        return None
    left = next((p for p in res.plan.passes if p.name == "pmap" and not p.run), None)
    return f"the photon-map pass is left out ({'the photon-map pass is not run' if left is None else left.reason})"


def _unread(res: RenderResult, overrides: Iterable[str] | None) -> dict[str, str]:  # noqa: F821
    """:func:`unread_overrides`' keys, each with the override that set it last (in that order)."""
    left = next((p for p in res.plan.passes if p.name == "pmap" and not p.run), None)
    photons = _photon_why(res) is not None
    walk = _walk_unread(res)
    by = getattr(left, "by", None) or ""  # (the key that left the pass out: it did what it was set for)
    last: dict[str, str] = {}
    for item in overrides or []:
        for key in set_leaves(item):  # (a section's mapping: the keys it names, as it merges; null: the section)
            for earlier in [k for k in last if k == key or k.startswith(key + ".")]:
                del last[earlier]  # (the later override names it)
            last[key] = item.strip()
    return {key: item for key, item in last.items()
            if key in walk or (photons and (key + ".").startswith(PHOTON_SECTIONS)
                               and not (by + ".").startswith(key + "."))}


def _unread_lines(res: RenderResult, unread: dict[str, str], via: str) -> list[str]:  # noqa: F821
    """:func:`unread_overrides`' lines: one for each override that set one of ``unread``'s keys last."""
    if not unread:
        return []
    walk = _walk_unread(res)
    photon_why = _photon_why(res)
    given = _given(via)
    lines = []
    for item in dict.fromkeys(unread.values()):
        keys = [key for key, it in unread.items() if it == item]
        whys = dict.fromkeys(walk.get(key, photon_why) for key in keys)
        # (an override that sets keys the run reads too, a section given whole, names those it does not)
        named = "" if len(keys) == len(set_leaves(item)) else f": {', '.join(keys)}"
        lines.append(f"{given(item)}{named} has no effect in this run: {'; '.join(whys)}")
    return lines


def reference_warnings(error: dict | None, cfg: RunConfig, emitted: int | None = None,
                       scene_photons: int | None = None) -> list[str]:
    """A line when the photon-map frame's error (``results.json`` ``error``) was measured
    against a reference that is not converged (``reference_converged`` false: it does not meet
    ``cfg.reference``'s stopping rule), worded as ``tlm run``'s error line says it; and, given the
    run's ``emitted`` photons and the scene's (``scene_photons``, what a null ``reference.photons``
    takes), the line of :func:`blur_warnings` on a reference much blurrier than the run; before them, given the
    run's photons as ``results.json`` records them, :func:`~tlm.experiments.photon_warnings.cut_warnings`' line on
    paths ``photons.max_bounces`` cut with power still travelling (h505: its words on the error need the error)."""
    from tlm.experiments.reference_cache import rounds_advice  # (h473: the rounds that may reach the tolerance)

    blur = [*cut_warnings(emitted, cfg, error), *blur_warnings(error, cfg, emitted, scene_photons)]
    if not (error and error.get("available")) or error.get("reference_converged"):
        return blur
    rse, rounds, ref = error.get("reference_standard_error"), error.get("reference_rounds"), cfg.reference
    rule = f"reference.tolerance {ref.tolerance:g}" + (f", reference.min_rounds {ref.min_rounds}"
                                                       if isinstance(rounds, int) and rounds < ref.min_rounds else "")
    return [f"the photon-map reference {error['reference']} is NOT converged ({rounds} rounds, relative standard "
            f"error {'n/a' if rse is None else f'{rse:.4f}'}, {rule}): the pmap error against it (error.rmse, "
            f"error.rel_mse) includes its noise; raise reference.max_rounds{rounds_advice(rse, rounds, ref)} and "
            "compute it again with 'tlm reference'", *blur]


# a photon map's kernel past this many times the area of the other's (h453, per map since h465): the reference's
# k-NN rounds gather so much wider than the run that its error against the reference may measure the reference's
# blur more than its noise (configs/cornell-water.yaml: its caustic map 6.25x; configs/ring.yaml with --mode pmap:
# its global map 20x, final gathering's; the other committed configs 1x or less; a reference's cost grows with its
# photons). Not the other way round (h478): a run blurrier than its reference, a k-NN estimate.k_nearest past
# reference.k_nearest as much as a run of fewer photons, has its blur measured by the error, as it should be
BLUR_RATIO = 4


def emitted_photons(res: RenderResult) -> dict | None:  # noqa: F821
    """What :func:`blur_warnings` reads of the run's photon-map pass, as ``results.json`` ``photons`` records it:
    ``emitted``, the photons it emitted (its caustic group's own ``photons.caustic_count`` included), and
    ``caustic``, the caustic photons its maps stored (none: a scene without a mirror or glass); and ``cut_share``
    (:func:`~tlm.experiments.photon_warnings.cut_warnings`). None without the pass."""
    if res.photons is None:
        return None
    stats = res.photons.photons.stats()
    return {"emitted": int(stats["emitted"]), "caustic": int(stats["caustic"]), "cut_share": stats["cut_share"]}


def _per_map(cfg: RunConfig, photons: int | dict, n_ref: int, scene_photons: int | None) -> list[tuple]:
    """``(map, the run's photons a round, the reference's, the run's kernel photons, the key that gives them)``
    of each photon map the run gathers whose kernel follows its photons: the caustic map (none where the scene
    stores no caustic photon) and the indirect one (``global`` with final gathering). The photons each map gets a
    round are its group's: with a mirror or glass, the run's caustic group (``photons.caustic_count``, else
    ``caustic_fraction`` of its photons) feeds its caustic map, the rest its indirect one; the reference's
    (:func:`tlm.experiments.reference.reference_config`: the default caustic_fraction 0.5) half each; without
    a mirror or glass, every photon the indirect map (and no caustic map is compared, nor one the run's caustic
    group left empty: a caustic_fraction or caustic_count 0, whose caustic photons, not aimed, are not as dense
    as its count says, nor one that stored nothing). A mirror or glass is told by the caustic photons the run
    stored, or, with a ``caustic_count``, by its emitting more than ``count`` (only a scene with one emits that
    budget: h478, its caustic map empty where the specular objects are out of the light's reach). The
    reference's rounds take the k nearest of both its maps at once: each map's half is its density where that
    map's photons are most of them (a caustic's core; away from the caustics). The kernel photons are compared
    where both kernels take the k nearest at each point alike: ``estimate.k_nearest`` (``filter: knn``),
    ``radius_photons`` (the density rule of the indirect map, without final gathering: indirect light is smooth,
    so the one radius the rule fits to the map's median photon holds about that many everywhere). Elsewhere the
    photons alone (the kernel photons taken as the reference's, as h453 did): the caustic map's density rule (its
    one radius, fitted to the median caustic photon, most of which spread thin, holds many times
    ``caustic_radius_photons`` in a caustic's bright core, where the reference's k nearest shrink), and final
    gathering's global map (the indirect light at the eye's point is the mean of ``final_gather`` lookups a bounce
    away, not one kernel). None of a map whose radius the config fixes (h457: more photons make it no narrower)."""
    emitted, stored = (photons.get("emitted"), photons.get("caustic")) if isinstance(photons, dict) else (photons, None)
    p, est, k_ref = cfg.photons, cfg.estimate, cfg.reference.k_nearest
    n = p.count if p.count is not None else scene_photons  # (the global group's, beside a caustic_count)
    # (a mirror or glass: a caustic budget of its own emitted beside count, else caustic photons stored; unknown: one)
    budget = bool(p.caustic_count) and isinstance(n, int) and n > 0
    specular = emitted > n if budget else stored > 0 if isinstance(stored, int) else True
    aimed = specular and (p.caustic_count > 0 if p.caustic_count is not None else p.caustic_fraction > 0)
    caustic = (p.caustic_count if p.caustic_count is not None else round(emitted * p.caustic_fraction)) if aimed else 0
    run = {"caustic": caustic, "indirect": emitted - caustic}
    ref = Fraction(n_ref, 2 if specular else 1)
    knn, fg = not uses_radius(est.filter), est.final_gather > 0
    fixed = {"caustic": est.caustic_radius is not None or est.caustic_radius_fraction is not None,
             "indirect": est.radius is not None or est.radius_fraction is not None}
    out = []
    for name in ("indirect", "caustic") if aimed and stored != 0 else ("indirect",):
        if (not knn and fixed[name]) or run[name] <= 0:
            continue
        if knn and not (fg and name == "indirect"):
            k, how = est.k_nearest, "estimate.k_nearest"
        elif not knn and name == "indirect" and not fg:
            k, how = est.radius_photons, "estimate.radius_photons"
        else:
            k, how = k_ref, None
        out.append(("global" if name == "indirect" and fg else name, run[name], ref, k, how))
    return out


def widest_map(cfg: RunConfig, emitted: int | dict | None, scene_photons: int | None) -> tuple | None:
    """``(ratio, map, the run's photons a round, the reference's, the run's kernel photons, the key that gives
    them, the reference's photons, the run's emitted)`` of the photon map of :func:`_per_map` whose reference
    kernel is the widest against the run's (``ratio``: its area over the run's; past :data:`BLUR_RATIO`,
    :func:`blur_warnings`' line; ``tlm error-vs-cost`` weighs its points by it); None where none compares."""
    n_ref = scene_photons if cfg.reference.photons is None else cfg.reference.photons
    total = emitted.get("emitted") if isinstance(emitted, dict) else emitted
    if not isinstance(n_ref, int) or n_ref <= 0 or not isinstance(total, int) or total <= 0:
        return None
    maps = [(cfg.reference.k_nearest * run / (ref * k), name, run, ref, k, how, n_ref, total)
            for name, run, ref, k, how in _per_map(cfg, emitted, n_ref, scene_photons)]
    return max(maps, default=None, key=lambda m: m[0])


def reference_share(cfg: RunConfig, ref: Fraction, n_ref: int) -> str:
    """The reference's photons a round that a map gets (:func:`widest_map`), in words: all, or half."""
    whose = f"reference.photons {n_ref}" if cfg.reference.photons is not None else \
        f"the scene's {n_ref}: reference.photons null"
    return f"{n_ref} a round ({whose})" if ref == n_ref else f"{math.floor(ref)} a round (half of {whose})"


def blur_warnings(error: dict | None, cfg: RunConfig, emitted: int | dict | None,
                  scene_photons: int | None) -> list[str]:
    """A line when the photon-map frame's error was measured (``error`` ``available``) against a reference whose
    kernel is much wider than the run's on a photon map the run gathers (:func:`_per_map`: each map's photons a
    round, the run's by ``emitted``, :func:`emitted_photons` or its count alone, the reference's of
    ``reference.photons``, null: the scene's ``scene_photons``; and the photons each kernel holds, the reference's
    ``reference.k_nearest``). A k-NN kernel's area goes as its photons over the map's: where the reference's is
    past :data:`BLUR_RATIO` times the run's, each of its rounds converges to an image blurrier than the run's and
    the error (``error.rmse``, ``error.rel_mse``) may measure that blur more than the run's noise (h453); the line
    names the worst map, both counts and the ``reference.photons`` to give. None the other way round (h478: a
    run blurrier than its reference has its own blur measured, as the error should)."""
    wide = widest_map(cfg, emitted, scene_photons) if error and error.get("available") else None
    if wide is None or wide[0] <= BLUR_RATIO:
        return []
    ratio, name, run, ref, k, how, n_ref, total = wide
    return [f"the photon-map frame's {name} map gets {run} of the {total} photons it emits, and that map of its "
            f"reference {error['reference']} gets {reference_share(cfg, ref, n_ref)}: each k-NN round of the reference "
            f"({cfg.reference.k_nearest} photons: reference.k_nearest) "
            + (f"gathers over {float(ratio):.2f}x the area of this run's gathers of {k} ({how})" if how else
               f"gathers in a map {float(ratio):.2f}x sparser than this run's")
            + ", so the pmap error against it (error.rmse, error.rel_mse) may measure the reference's blur more "
            f"than this run's noise; raise reference.photons to {math.ceil(n_ref * ratio / BLUR_RATIO)} or more (at "
            f"most {BLUR_RATIO}x this run's on that map) and compute it again with 'tlm reference'"]


def sweep_threads_line(points: Iterable[Any], source: str, cpus: int | None = None) -> list[str]:
    """:func:`threads_warning`'s line for the most ``render.threads``
    that a point gives past the ``cpus`` available (default: the process's), once, as the sweep
    starts: a point whose frame is cached renders nothing, and so records none (a point that renders
    records it in its own ``results.json`` too). None for a Dask cluster's workers (their own CPUs)."""
    from tlm.config import config_from_dict

    most = max(points, key=lambda p: (p.config.get("render") or {}).get("threads") or 0, default=None)
    if most is None or (most.config.get("render") or {}).get("threads") is None:
        return []
    return threads_warning(config_from_dict(most.config, source), cpus)


def sweep_jobs_line(points: Iterable[Any], workers: int, cpus: int | None = None) -> list[str]:
    """A line where ``workers`` local worker processes (``--jobs``, no more than the points to run),
    each rendering with the most ``render.threads`` a point of ``points`` gives, run more threads than
    the ``cpus`` available, while that count alone is no more than them (:func:`sweep_threads_line`
    says that one): a point that leaves it null gets its worker's share (tlm.experiments.executors.
    kernel_threads), one that gives it does not. Nothing for a count of 1: where ``--jobs`` alone is past the
    CPUs a null gets 1 there too (leaving it null would change nothing), and ``--jobs`` past the CPUs by
    itself is allowed and not said (as :func:`~tlm.experiments.dask_workers.dask_oversubscribed` leaves it)."""
    if cpus is None:
        from tlm.kernels.threads import available

        cpus = available()
    most = max(((p.config.get("render") or {}).get("threads") or 0 for p in points), default=0)
    # (one thread: what a null count gets there too, which says nothing: --jobs alone is past the CPUs)
    if workers <= 1 or most <= 1 or most > cpus or workers * most <= cpus:
        return []
    return [f"--jobs: {workers} worker processes, each with render.threads = {most}, run {workers * most} kernel "
            f"threads on the {cpus} CPU{'s' if cpus != 1 else ''} available to this process: they take turns on "
            "them, which is slower, not faster (results are the same); lower --jobs, or leave render.threads null "
            "(each worker then gets its share of the CPUs)"]
