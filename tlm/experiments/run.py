"""One experiment: load, plan, build, render every planned frame, write the run folder.

The run folder is written to a temporary sibling folder and renamed into place only
when everything succeeded, so a failed or interrupted run leaves no half-written
output. Contents::

    config.resolved.yaml      every parameter, defaults included
    results.json              scene stats, passes run and left out (with reasons),
                              work counts per pass, the timing model's cycles per PM,
                              throughput, latency and FPS with the eq. 5.1 breakdown
                              of every unit, host seconds per stage, versions
    trace.json                the timing model's timeline (Chrome trace events; opens
                              in ui.perfetto.dev), unless arch.trace is false
    images/<pass>.png         tone-mapped sRGB, one exposure for all images
    images/composite.png
    radiance/<pass>.npy       float32 (H, W, 3) linear radiance, and composite.npy
    aov/primary.npz           origin, direction, t, triangle, normal of the eye rays
    aov/work.npz              per-pixel work counts, "<pass>.<count>" -> (H, W) int32 (int64 where one does not fit)

Images and ``results.json`` are always written; ``aov/``, ``radiance/`` and ``trace.json``
are the optional :data:`OUTPUTS` (``tlm run --outputs``; all three by default).

The image is rendered in batches of consecutive pixels, ``render.batch_rays`` eye rays
each, by the render's batch loop (:func:`~tlm.render.batches.render_batches`): every
pass of a batch runs before the next batch is cast, the cache pairs carried from batch
to batch, so the radiance and work are exactly those of one whole-image packet while
memory stays bounded by the batch. A progress bar (``progress=True``, on stderr, only
when it is a terminal) follows the batches and the timing model.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from tlm.arch.costs import Programs, load_programs
from tlm.arch.functional import Functional, save_npz
from tlm.arch.model import Timing, simulate
from tlm.caches import cache_warnings
from tlm.claims import claimed
from tlm.config import ArchConfig, RunConfig, noting_reads, read_set_value, to_dict
from tlm.config_read import config_file, nameless, rerun_sets
from tlm.config_words import dump_yaml, with_overrides
from tlm.errors import InputError, check_numba_threads, did_you_mean, shell_word
from tlm.experiments.dask_workers import ran_here
from tlm.experiments.error_cost_clock import CompileClock
from tlm.experiments.loading import load_frame
from tlm.experiments.provenance import code_state, scene_identity, versions
from tlm.experiments.reference import difference_image, ensure_reference, image_error
from tlm.experiments.reference_cache import load_reference, meets_tolerance
from tlm.experiments.run_warnings import eye_hits, run_warnings, stream_warnings, unread_overrides
from tlm.kernels import release_memory, threads
from tlm.kernels.photons import PhotonTrace
from tlm.kernels.traverse import TriangleAccel
from tlm.kernels.work import WORK_KEYS
from tlm.progress import Ticking, Timer, progress_bar
from tlm.registry import plugins
from tlm.render import checks
from tlm.render.batches import Primary, render_batches
from tlm.render.frame import Frame, GBuffer, ImageGBuffer
from tlm.render.image import auto_exposure, overflow_line, to_srgb8, write_png
from tlm.render.planner import Plan, check_photon_memory, photon_count, plan
from tlm.render.pmap import radii
from tlm.scenes.model import Light, Scene
from tlm.storage import atomic_folder, check_destination, json_text, warn

OUTPUTS = ("aov", "radiance", "trace")  # what a run folder may leave out (images and results.json: always)
# what a run folder's writers put in it (its report: 'tlm report' after the run); anything else
# in a folder a run replaces is the user's and is kept (tlm.storage.atomic_folder)
RUN_FILES = ("results.json", "config.resolved.yaml", "images", "radiance", "aov", "trace.json", "report")


def parse_outputs(text: str) -> tuple[str, ...]:
    """``--outputs`` (``aov,trace``): the optional outputs named, in :data:`OUTPUTS` order.

    ``images`` may be named too (images are always written), so ``--outputs images``
    writes the images and ``results.json`` alone. An unknown name is an InputError.
    """
    names = [n.strip() for n in str(text).split(",") if n.strip()]
    bad = [n for n in names if n not in (*OUTPUTS, "images")]
    if bad or not names:
        part = f"; {', '.join(map(repr, bad))} {'are' if bad[1:] else 'is'} none of them" if names[1:] else ""
        raise InputError(f"{text!r}: expected a comma-separated list of {', '.join(('images', *OUTPUTS))}{part}"
                         + (did_you_mean(bad[0], ("images", *OUTPUTS)) if bad else ""), key="--outputs")
    return tuple(n for n in OUTPUTS if n in names)


@dataclass
class RenderResult:
    """Everything a run computed (before it is written out).

    ``radiance`` and ``work`` hold each pass's (H, W, 3) linear radiance and (H, W) work
    counts; :attr:`composite`, :attr:`aov` and :meth:`work_totals` are the views a run
    folder writes. ``gbuffer`` is the whole image's G-buffer when it was cast as one batch;
    after a batched render, an :class:`~tlm.render.frame.ImageGBuffer` that casts it
    again on first use (``pixels`` and ``spp`` at once). ``primary``: the AOVs and
    eye-ray counts. ``timing`` and ``programs`` are set by :func:`simulate_render`, which
    returns a new result; ``base``: where the config's relative paths start (the
    instruction table of ``arch.programs``), when the caller knew it. ``overrides``: the
    ``dotted.key=value`` strings the config was given, ``via`` how (``--set`` on the command
    line, ``the overrides`` through the API): what :attr:`warnings` names a key by when it was
    asked for and never read (:func:`~tlm.experiments.run_warnings.unread_overrides`).
    """

    scene: Scene
    cfg: RunConfig
    plan: Plan
    frame: Frame
    gbuffer: GBuffer | ImageGBuffer
    radiance: dict[str, np.ndarray]  # pass -> (H, W, 3)
    work: dict[str, dict[str, np.ndarray]]  # pass -> count -> (H, W)
    timer: Timer
    photons: PhotonTrace | None = None  # the traced photon map, when the pmap pass ran
    error: dict | None = None  # the photon-map frame against its reference
    timing: Timing | None = None  # the timing model's outcome (simulate_run)
    programs: Programs | None = None
    primary: Primary | None = None
    gather_maps: dict | None = None  # the pmap pass's work per photon map (pmap_pass's per_map)
    base: Path | None = None
    overrides: tuple[str, ...] = ()
    via: str = "--set"
    scene_digest: str | None = None  # the scene's inputs as render() loaded them (results.json scene_digest)

    @property
    def accel(self) -> TriangleAccel:
        return self.frame.accel

    @property
    def aov(self) -> dict[str, np.ndarray]:
        """Each pixel's first eye sample, as ``aov/primary.npz`` holds it: ``origin``,
        ``direction``, ``normal`` (H, W, 3), ``t`` (H, W; inf on a miss) and ``triangle``
        (H, W; -1 on a miss)."""
        primary = self.primary if self.primary is not None else _primary_of(self)
        h, w = self.scene.camera.height, self.scene.camera.width
        return {"origin": primary.origin.reshape(h, w, 3), "direction": primary.direction.reshape(h, w, 3),
                "t": primary.t.reshape(h, w), "triangle": primary.triangle.reshape(h, w),
                "normal": primary.normal.reshape(h, w, 3)}

    def functional(self) -> Functional:
        """The work the timing model reads: :meth:`Functional.of` over what the render
        produced (each planned pass's work, the geometry BSP, the photon trace)."""
        return Functional.of({p: self.work[p] for p in self.plan.run_names}, self.accel.tree, self.photons,
                             self.scene.camera.width)

    @property
    def warnings(self) -> list[str]:
        """What ``tlm run`` warns of for this render (``results.json`` ``warnings``, one line
        each: a light that reaches nothing, a black image, textures not rendered, a setting
        never read, a photon-map reference not converged, ...; :func:`run_warnings`), but the
        simulated stream's, which :func:`stream_warnings` gives from a :class:`~tlm.arch.model.Timing`."""
        return run_warnings(self)

    def work_totals(self) -> dict[str, dict[str, int]]:
        """Each pass's work counts summed over the image: pass -> count -> int."""
        return {name: {k: int(v.sum()) for k, v in counts.items()} for name, counts in self.work.items()}

    # the work counts a repr shows for each pass, those it has and are not 0 (work_totals(): all)
    _REPR_COUNTS = ("primary_rays", "secondary_rays", "shadow_rays", "tri_tests", "gathers", "photons_tested")

    def __repr__(self) -> str:
        """A few lines (a notebook cell that shows a result): the scene and its triangles,
        the resolution, the mode, each pass run with its main work totals (those not 0),
        the photons traced, and the timing model's throughput when the result holds it (one
        :func:`simulate_render` made; :func:`tlm.simulate` returns its timing and leaves the
        result as it is, so the line says what the result holds, not whether it was simulated)."""
        name = self.scene.name if len(self.scene.name) <= 40 else self.scene.name[:37] + "..."
        cam = self.scene.camera
        lines = [f"RenderResult: scene {name!r}, {self.scene.n_triangles:,} triangles, {cam.width}x{cam.height}, "
                 f"mode {self.cfg.mode!r}, passes run:"]
        for p in self.plan.run_names:
            counts = self.work.get(p, {})
            shown = [(k, int(counts[k].sum())) for k in self._REPR_COUNTS if k in counts]
            lines.append(f"  {p}: " + (", ".join(f"{k} {v:,}" for k, v in shown if v) or "no work"))
        if self.photons is not None:
            maps = self.photons.photons
            stored = [f"{m.n:,} {what}" for m, what in ((maps.caustic_map, "caustic"), (maps.indirect_map, "indirect"),
                                                        (maps.global_map, "global")) if m is not None]
            lines.append(f"  photons: {maps.emitted:,} emitted; stored {', '.join(stored)}")
        if self.timing is None:
            lines.append("  timing: not in this result: tlm.simulate(result) returns it (cycles, frames per second)")
        else:
            fps = self.timing.fps
            lines.append(f"  simulated: throughput {self.timing.cycles['throughput']:,} cycles per frame, "
                         + (f"{fps:,.1f} fps" if fps >= 1 else f"{fps:.3g} fps"))
        return "\n".join(lines)

    @property
    def exposure(self) -> float:
        """The one factor ``tlm run``'s ``images/*.png`` multiply the linear radiance by before the sRGB
        curve (``results.json`` ``image.exposure``): ``render.exposure``, else
        :func:`~tlm.render.image.auto_exposure` over the composite's pixels that do not see a light directly
        (:func:`image_exposure`). ``tlm.to_srgb(res)`` is ``images/composite.png``'s image,
        ``tlm.to_srgb(res.radiance[p], res.exposure)`` ``images/<p>.png``'s."""
        return image_exposure(self, self.composite)[0]

    @property
    def composite(self) -> np.ndarray:
        out = np.zeros_like(next(iter(self.radiance.values())))
        for name in self.plan.run_names:
            if name in self.radiance:  # (a work-only pass has no frame)
                out = out + self.radiance[name]
        return out


def render(cfg: RunConfig, base: Path | None = None, config_source: str | None = None,
           progress: bool = False, reference: bool = False, *, scene: Scene | None = None,
           timer: Timer | None = None, overrides: Iterable[str] = (), via: str = "--set") -> RenderResult:
    """Render every planned frame of ``cfg`` over the whole image: its frame loaded
    (:func:`~tlm.experiments.loading.load_frame`), its passes planned and rendered in
    batches of ``render.batch_rays`` eye rays (:func:`~tlm.render.batches.render_batches`),
    the photon-map frame measured against its cached reference; ``progress``: bars on
    stderr; ``reference``: the photon-map frame's reference will be computed when none is
    cached (:func:`run`), so its photons are checked against memory before the render too,
    when none is cached; ``scene``: ``cfg``'s scene when the caller loaded it already (as
    :func:`~tlm.scenes.loader.load_scene` ``(cfg.scene, base, cfg.resolution, config_source)``
    gives it: :func:`tlm.experiments.frames.cached_render`, whose key loaded it), not loaded
    again; ``timer``: the result's host seconds start from it (that load's stage);
    ``overrides`` and ``via``: the result's (:class:`RenderResult`), what its warnings name. A scene it loads
    gets its ``scene_digest``: :func:`~tlm.experiments.provenance.scene_identity` of the files the load read, from
    the digests the load computed (a scene given is not digested: None).

    The kernels run on ``render.threads`` threads (null: :func:`~tlm.kernels.threads.default_threads`), with the
    bits of one (:mod:`tlm.kernels.threads`)."""
    check_numba_threads()  # (before numba's import, which it would fail)
    with threads.using(cfg.render.threads):
        timer = Timer() if timer is None else timer
        with progress_bar(progress, desc="load scene", total=None, unit="step", leave=False) as bar, \
                noting_reads() as reads:
            frame = load_frame(cfg, base, config_source, timer, bar, scene=scene, check_photons="run")
        digest = None
        if scene is None and frame.scene.source:  # (of the load's stage: its files' digests, most of them reused)
            with timer.stage("load_scene"):
                digest = scene_identity(frame.scene.source, reads)
        the_plan = plan(frame.scene, cfg)
        if "pmap" in the_plan.run_names:  # (the global group and the caustic group's own budget)
            ph = cfg.photons
            caustic = ph.caustic_count is not None
            check_photon_memory(photon_count(frame.scene, cfg) + (ph.caustic_count or 0),
                                "photons.count + photons.caustic_count" if caustic else "photons.count",
                                config_source, " (the scene's photons)" if ph.count is None and not caustic else "")
            found = ensure_reference(frame) if reference else None
            if found is not None and found.image is None:  # (to be computed: said now, not after the render)
                check_photon_memory(found.settings.photons, "reference.photons", config_source)
        for line in checks.branching_warning(cfg, frame.scene):  # (said before a render that may not end)
            warn(line)
        done = render_batches(frame, the_plan.run_names, timer, progress)
        error = None
        if done.photons is not None:
            error = photon_error(frame, done.radiance["pmap"].reshape(-1, 3))
    return RenderResult(frame.scene, cfg, the_plan, frame, done.gbuffer, done.radiance, done.work, timer,
                        done.photons, error, primary=done.primary, gather_maps=done.gather_maps,
                        overrides=tuple(overrides), via=via, scene_digest=digest)


def programs_for(cfg: RunConfig, base: Path | None) -> Programs:
    """The instruction-cost table of ``arch.programs`` (a path relative to the config)."""
    if cfg.arch.programs is None:
        return load_programs()
    path = Path(cfg.arch.programs)
    if not path.is_absolute() and base is not None:
        path = base / path
    return load_programs(path)


def simulate_run(res: RenderResult, programs: Programs, progress: bool = False, timer: Timer | None = None
                 ) -> Timing:
    """The timing model's outcome over the rendered frame's work (the SimPy layer) under
    ``res.cfg.arch``; ``res`` is left as it is. ``progress``: a bar on stderr with the
    elapsed time while it runs; ``timer``: gets the stage ``simulate``."""
    timer = Timer() if timer is None else timer
    with timer.stage("simulate"), progress_bar(progress, desc="simulate", total=1, unit="run", leave=False,
                                               postfix=frames_said(res.cfg.arch)) as bar, Ticking(bar):
        timing = simulate(res.functional(), programs, res.cfg.arch)
        bar.update()
    release_memory()  # (the model's freed blocks, before the outputs are written)
    return timing


def frames_said(arch: ArchConfig) -> str:
    """The frames a stream of ``arch`` runs, as its progress bar says them: ``arch.frames``, or for a settling
    stream (:func:`tlm.arch.model.settling`: two images in flight, the dynamic queue, or the static tiles where
    their asked frames' gaps may not repeat) as many or more, until its completions repeat,
    :func:`tlm.arch.steady.frames_cap` at most."""
    from tlm.arch.steady import frames_cap
    from tlm.registry import SCHEDULERS, may_run_on

    settles = may_run_on(arch.scheduler, arch.images_in_flight, arch.frames)  # (model.settling)
    cap = frames_cap(arch.frames, arch.settle_frames)
    if settles and cap > arch.frames:
        if SCHEDULERS[arch.scheduler].periodic_from_warmup:  # (the static tiles: most repeat, and run arch.frames)
            return f"{arch.frames} frames, to {cap} if they do not repeat"
        return f"{arch.frames} to {cap} frames, until it settles"
    return f"{arch.frames} frames"


def simulate_render(res: RenderResult, programs: Programs, progress: bool = False) -> RenderResult:
    """``res`` simulated: a new result with its ``timing``, its ``programs`` and the stage
    ``simulate`` in its host seconds (``res`` itself is left as it is)."""
    timer = Timer(dict(res.timer.seconds), {k: list(v) for k, v in res.timer.spans.items()})  # (spans: one_off)
    timing = simulate_run(res, programs, progress, timer)
    return replace(res, timer=timer, timing=timing, programs=programs)


def timing_dict(tm: Timing, arch: ArchConfig, programs: Programs) -> dict:
    """The ``timing`` section of ``results.json``: the simulated architecture and its outcome."""
    return {
        "clock_hz": arch.clock_hz,
        "packet_size": arch.packet_size,
        "frames": len(tm.frames),  # arch.frames, or more: a dynamic stream runs on until it settles (tlm.arch.steady)
        "frames_asked": arch.frames,
        "images_in_flight": arch.images_in_flight,
        "memory": arch.memory,
        "programs": {"source": programs.source, "scale": programs.scale,
                     "record_cycles": programs.record_cycles},
        "simpy_events": tm.events,
        # the run's stop at its end: the liveness bound of the frames its stream started (model.event_bound,
        # arch.frames' worth, more for a stream that ran on), or arch.max_events where lower
        "event_bound": tm.event_budget,
        **{k: v for k, v in tm.to_dict().items() if k not in ("cycles", "fps", "events")},
    }


def photon_error(frame: Frame, pmap: np.ndarray, compute: bool = False, progress: bool = False,
                 say=None) -> dict:
    """The photon-map frame's error against its converged reference
    (:mod:`tlm.experiments.reference`): the cached one; with ``compute``, one computed and
    cached now when none is (``progress``: its bar on stderr; ``say``: a line before and
    after). ``reference_seconds``: what computing it took, when it was computed now."""
    found = ensure_reference(frame, compute=compute, bar=progress, say=say)
    cam = frame.scene.camera
    return error_against(found.key, found.settings, pmap, found.image, found.meta, found.seconds,
                         [cam.width, cam.height])


def error_against(key: str, settings, pmap: np.ndarray | None, image: np.ndarray | None, meta: dict | None,
                  seconds: float | None = None, resolution: list[int] | None = None) -> dict:
    """``results.json`` ``error`` of the photon-map frame ``pmap`` (pixels, 3) against the reference ``key``
    (``image`` and ``meta``: None where none is cached; ``settings``: the run's
    :class:`~tlm.experiments.reference_cache.ReferenceSettings`, whose stopping rule judges it;
    ``seconds``: what computing it took now): :func:`photon_error`'s, and a sweep point's of a cached frame
    (:func:`tlm.experiments.frames.cached_render`), measured against the reference cached when it is read.
    ``reference_sha256``: the sha256 of the cached reference's ``reference.npy`` as its ``meta.json`` holds it
    (``npy``), which tells a reference computed again under the same key (``tlm reference --force``, other
    ``reference.max_rounds``) from this one (:func:`tlm.experiments.sweep_reference.reference_now`): of one computed
    now too, as it was cached (:func:`~tlm.experiments.reference.ensure_reference`; where the cache could not
    take it, that of the ``reference.npy`` it would have been); None where ``meta`` holds none. What the error is
    against (h507): ``reference_photons`` (its photons a round, resolved: the scene's where ``reference.photons`` is
    null), ``reference_k_nearest``, ``reference_rounds`` and ``reference_resolution`` (``resolution``, [width,
    height]: the run's, which the key holds; None where the caller does not give it)."""
    if image is None or meta is None:
        return {"reference": key, "available": False,  # (the command and the Python API's call alike: h529)
                "hint": "run 'tlm reference CONFIG' (from Python: tlm.reference(config)) to compute and cache it"}
    npy = meta.get("npy")
    return {"reference": key, "available": True, **image_error(pmap, image),
            "reference_converged": meets_tolerance(meta, settings), "reference_rounds": meta.get("rounds"),
            "reference_standard_error": meta.get("relative_standard_error"),
            "reference_seconds": None if seconds is None else round(seconds, 3),
            "reference_sha256": npy.get("sha256") if isinstance(npy, dict) else None,
            "reference_photons": settings.photons, "reference_k_nearest": settings.k_nearest,
            "reference_resolution": None if resolution is None else [int(v) for v in resolution]}


def skipped_reference(cfg: RunConfig, config_path: str | None, overrides: Iterable[str] | None,
                      out: Path | None = None, base: Path | None = None) -> dict:
    """What ``results.json``'s ``error`` records of a photon-map reference not computed as asked:
    ``skipped``, why (``--no-reference``, the run's ``reference`` false, or the config's
    ``reference.auto: false``), and ``command``, the ``tlm reference`` command that computes it
    (:func:`reference_command`), as ``tlm run`` prints them, but to run from any folder: the config file by its
    absolute path (:func:`~tlm.config_read.config_file`), the files of ``overrides`` too
    (:func:`~tlm.config_read.rerun_sets`). A config read once (:func:`read_once`:
    ``tlm run <(...)``'s ``/dev/fd/63``, which no later command finds) is named by the config the run
    folder ``out`` keeps, ``config.resolved.yaml`` (its every setting, the ``--set`` values included), and
    ``config_read_once`` says so."""
    skipped = "--no-reference" if cfg.reference.auto else "reference.auto: false"
    once = read_once(config_path)
    if once is None or out is None:
        return {"skipped": skipped, "command": reference_command(config_file(config_path, base) or config_path,
                                                                 rerun_sets(overrides, read_set_value))}
    kept = (Path(out) / "config.resolved.yaml").absolute()
    return {"skipped": skipped, "command": reference_command(str(kept)),
            "config_read_once": f"{config_path} is {once}, read once: the command names the run's copy of it, "
                                f"{kept.name}, with every setting, the --set values included"}


def read_once(config_path: str | None) -> str | None:
    """What the config ``config_path`` is where a later command cannot read it again: ``"a pipe"`` (``tlm run
    <(...)``'s ``/dev/fd/63``, a FIFO: its text is gone once read), ``"a file descriptor's name"`` (``/dev/stdin <
    cornell.yaml``); None for a file of its own name, and for none (:func:`tlm.config_read.nameless`)."""
    once = nameless(config_path) if config_path else None
    return "a pipe" if once == "a named FIFO" else once


def reference_command(config_path: str | None, overrides: Iterable[str] | None = ()) -> str:
    """The ``tlm reference`` command that computes the reference of a run of ``config_path`` with
    ``overrides`` (its ``--set`` strings): a built-in experiment by its name (``cornell_pmap``),
    another config by its path as given; ``CONFIG`` for a config that is no file (a mapping)."""
    from tlm.builtin import configs_dir, list_experiments

    typed = str(config_path) if config_path else "CONFIG"
    path = Path(typed)
    try:
        if path.is_absolute() and path.parent.resolve() == configs_dir().resolve() and path.stem in list_experiments():
            typed = path.stem
    except OSError:
        pass
    return " ".join(["tlm reference", shell_word(typed), *(f"--set {shell_word(str(o))}" for o in overrides or ())])


def _write_difference(res: RenderResult, path: Path) -> None:
    """``images/pmap_error.png``: the photon-map frame minus its reference (signed colours,
    :func:`~tlm.experiments.reference.difference_image`), when the error was measured; its
    file and scale go into ``res.error``."""
    if not (res.error and res.error.get("available") and "pmap" in res.radiance):
        return
    found = load_reference(res.error["reference"])
    if found is None:  # (removed since the render)
        return
    rgb, scale = difference_image(res.radiance["pmap"], found[0].reshape(res.radiance["pmap"].shape))
    write_png(path, rgb)
    res.error.update(difference_image=f"images/{path.name}", difference_scale=scale)


def scene_head(scene: Scene, bounds) -> tuple[dict, np.ndarray]:
    """What every description of a scene starts with (name, source, triangles, its bounds
    as ``bounds(lo, hi)`` gives them, resolution, photons), and the triangles of each
    material."""
    lo, hi = scene.bounds()
    used = np.bincount(scene.material_index, minlength=len(scene.materials))
    return {"name": scene.name, "source": scene.source, "triangles": scene.n_triangles, "bounds": bounds(lo, hi),
            "resolution": [scene.camera.width, scene.camera.height], "photons": scene.photons}, used


def scene_stats(scene: Scene, accel: TriangleAccel) -> dict:
    """``results.json`` ``scene``: :func:`scene_head`, each material's kind, triangles and the values the
    renderer used (:meth:`~tlm.scenes.model.Material.info`: its colours, ior, emission, what its file gave that
    tlm does not render and where it came from), each light as ``tlm scene show`` lists it (its type, power and
    its kind's own fields, so that two runs whose spot cones or sun directions differ differ here too) with
    where it came from (:func:`light_record`) and the BSP's statistics."""
    head, used = scene_head(scene, lambda lo, hi: [lo.tolist(), hi.tolist()])
    return {
        **head,
        "materials": {m.name: {"kind": m.kind, "triangles": int(used[i]), **m.info()}
                      for i, m in enumerate(scene.materials)},
        "lights": [light_record(lt) for lt in scene.lights],
        "bsp": accel.tree.stats(),
    }


def light_record(lt: Light) -> dict:
    """``results.json``'s record of a light: :meth:`~tlm.scenes.model.Light.info`, with its ``from``
    (:attr:`~tlm.scenes.model.Light.origin`: ``FILE: lights[i]``, a scene file's entry; a mesh file's light, its
    file and ``KHR_lights_punctual.lights[i] 'NAME' at nodes[n]``), else its name (a Light built without one);
    the mesh light (``materials``) is its materials' emission."""
    info = lt.info()
    return {**info, "from": lt.name} if "from" not in info and lt.name and lt.kind != "mesh" else info


def results_dict(res: RenderResult, exposure: float, config_path: str | None,
                 overrides: list[str] | None = None, say_unread: bool = True) -> dict:
    """``results.json`` of ``res``; ``overrides``: the config's (default ``res.overrides``),
    which its ``overrides`` and its warnings name (:func:`run_warnings`); ``say_unread`` false: its
    warnings leave out the lines of an override this run never reads
    (:func:`~tlm.experiments.run_warnings.unread_overrides`: a study's ``--set`` that some of its
    cells do not read, which the study says once)."""
    if overrides is not None and tuple(overrides) != res.overrides:
        res = replace(res, overrides=tuple(overrides))
    work = {}
    for name, counts in res.work.items():
        total = {k: int(v.sum()) for k, v in counts.items()}
        if name == "pmap":
            gathers = total["gathers"]
            total["photons_tested_per_gather"] = total["photons_tested"] / gathers if gathers else 0.0
            total["photons_accepted_per_gather"] = total["photons_accepted"] / gathers if gathers else 0.0
        else:
            rays = total["primary_rays"] + total["secondary_rays"]
            shadow = total["shadow_rays"]
            total["tri_tests_per_ray"] = total["tri_tests"] / rays if rays else 0.0
            total["leaf_visits_per_ray"] = total["leaf_visits"] / rays if rays else 0.0
            total["tri_tests_per_shadow_ray"] = total["shadow_tri_tests"] / shadow if shadow else 0.0
        work[name] = total
    pixels, rays, hits, back = eye_hits(res)
    warnings = run_warnings(res) + stream_warnings(res.timing, res.cfg)
    if not say_unread:
        unread = set(unread_overrides(res, res.overrides, res.via))
        warnings = [w for w in warnings if w not in unread]
    return {
        "tlm": "results/1",
        "config": config_path,
        "config_file": config_file(config_path, res.base),  # (absolute: config as typed is of the working folder then)
        "overrides": list(res.overrides),
        "seed": res.cfg.seed,
        "mode": res.cfg.mode,
        "scene": scene_stats(res.scene, res.accel),
        # (the bytes of the scene file, its extends: chain, its meshes and their libraries, as the run read them)
        "scene_digest": res.scene_digest,
        "plan": res.plan.to_dict(),
        "primary": {
            "pixels": int(pixels),
            "spp": int(res.gbuffer.spp),
            "rays": int(rays),
            "hits": int(hits),
            "misses": int(rays - hits),
            "back_face_hits": int(back),
        },
        "work": work,
        "work_keys": list(WORK_KEYS),
        "photons": None if res.photons is None else {
            **res.photons.photons.stats(),
            "work": res.photons.totals(),
            "filter": res.cfg.estimate.filter,
            **radii(res.frame, res.photons.photons),
            "gather": _per_map(res),
        },
        "cycles": None if res.timing is None else res.timing.cycles,
        "fps": None if res.timing is None else res.timing.fps,
        "timing": None if res.timing is None else timing_dict(res.timing, res.cfg.arch, res.programs),
        "image": {"exposure": exposure},
        "error": res.error,
        "host_seconds": {k: round(v, 6) for k, v in res.timer.seconds.items()},
        "versions": versions(),
        **code_state(),
        "plugins": plugins(to_dict(res.cfg)),  # (the classes from outside tlm it selected, their code's digest)
        "ran": ran_here(),  # (who ran it, as a sweep point records it: worker None outside a Dask worker, host, pid)
        "warnings": warnings,
    }


def _per_map(res: RenderResult) -> dict:
    """The pmap pass's gather work per photon map, with the photons tested and accepted per gather
    of that map (``gathers``: the caustic and indirect maps are searched at every gather point, the
    global map at every final-gather ray's hit)."""
    out = {}
    for name, tally in (res.gather_maps or {}).items():
        gathers = tally.get("gathers", 0)
        out[name] = {**tally, **{f"{k}_per_gather": tally[k] / gathers if gathers else 0.0
                                 for k in ("photons_tested", "photons_accepted")}}
    return out


def write_run(res: RenderResult, out: Path, config_path: str | None = None,
              overrides: list[str] | None = None, outputs: Iterable[str] = OUTPUTS, say_unread: bool = True,
              one_off: Callable[[], list[tuple[float, float]]] | None = None) -> dict:
    """Write the run folder atomically (temporary sibling, then rename).

    outputs : which of :data:`OUTPUTS` to write besides the images and ``results.json``
    (``trace.json`` also needs the timing model's trace, ``arch.trace``). say_unread : false,
    ``results.json`` ``warnings`` leave out an override the run never reads (:func:`results_dict`).
    one_off : the run's one-off spans so far (numba compiling or loading a kernel, first imports:
    :func:`run`), booked to the stage ``one_off`` out of the others (:meth:`~tlm.progress.Timer.book_apart`)
    once the folder's seconds are measured, before ``results.json`` records them.

    ``results.json`` ``warnings`` end with the lines on tlm's caches that this process
    cannot write (:func:`tlm.caches.cache_warnings`), as a sweep point's do: each looked at again as the
    folder is written, so one fixed since an earlier run of the process is recorded no more.
    """
    outputs = set(outputs)
    unknown = outputs - set(OUTPUTS)
    if unknown:
        raise ValueError(f"outputs {sorted(unknown)} are not among {OUTPUTS}")
    t0 = time.perf_counter()
    # (finished: what is written is computed already, so a destination refused now, another program's folder put
    # there as the run worked, gets it kept beside, OUT.unsaved-<pid>, said: the render is not lost)
    with atomic_folder(out, "results.json", owned=RUN_FILES, finished=True) as tmp:
        (tmp / "images").mkdir()
        composite = res.composite
        h, w = res.scene.camera.height, res.scene.camera.width
        primary = res.primary if res.primary is not None else _primary_of(res)
        exposure, surfaces = image_exposure(res, composite, primary)  # (res.exposure)
        # (an exposure that takes pixels past the largest float: white, said once)
        overflow = overflow_line(composite, exposure, surfaces)
        del surfaces
        if "radiance" in outputs:
            (tmp / "radiance").mkdir()
        for name, rad in [*res.radiance.items(), ("composite", composite)]:
            write_png(tmp / "images" / f"{name}.png", to_srgb8(rad, exposure))
            if "radiance" in outputs:
                np.save(tmp / "radiance" / f"{name}.npy", rad.astype(np.float32))
        del composite, rad  # (50 MB each at 1080p)
        _write_difference(res, tmp / "images" / "pmap_error.png")
        if "aov" in outputs:
            (tmp / "aov").mkdir()
            # (zlib level 1, save_npz: the work counts in a fifth of savez_compressed's time, ~10% more bytes)
            save_npz(tmp / "aov" / "primary.npz", {
                "origin": primary.origin.reshape(h, w, 3),
                "direction": primary.direction.reshape(h, w, 3),
                "t": primary.t.reshape(h, w),
                "triangle": primary.triangle.reshape(h, w),
                "normal": primary.normal.reshape(h, w, 3),
            })
            save_npz(tmp / "aov" / "work.npz",
                     {f"{p}.{k}": v for p, counts in res.work.items() for k, v in counts.items()})
        (tmp / "config.resolved.yaml").write_text(dump_yaml(to_dict(res.cfg), sort_keys=False), encoding="utf-8")
        if "trace" in outputs and res.timing is not None and res.timing.trace is not None:
            res.timing.trace.write(tmp / "trace.json", res.cfg.arch.clock_hz)
        results = results_dict(res, exposure, config_path, overrides, say_unread)
        # the caches this process cannot write, as they are now (said on stderr once; a sweep's points record them too)
        results["warnings"] += [w for w in cache_warnings() if w not in results["warnings"]]
        results["warnings"] += [overflow] if overflow else []
        # (the write: the folder and the record, up to results.json's own text, as a sweep point's)
        t1 = time.perf_counter()
        res.timer.seconds["write"] = t1 - t0
        res.timer.spans["write"] = [(t0, t1)]
        if one_off is not None:
            res.timer.book_apart("one_off", one_off())
        results["host_seconds"] = {k: round(v, 6) for k, v in res.timer.seconds.items()}
        # (strict JSON: an fps of no cycles to time, inf here, is written as null)
        (tmp / "results.json").write_text(json_text(results, indent=2) + "\n", encoding="utf-8")
    return results


def image_exposure(res: RenderResult, composite: np.ndarray,
                   primary: Primary | None = None) -> tuple[float, np.ndarray]:
    """The run's one exposure for its images (:attr:`RenderResult.exposure`) given its ``composite``, and the
    (n, 3) radiance of the pixels the automatic one is set by: those whose first sample does not see a light
    directly (a light seen would set it). ``primary``: the result's AOVs, where the caller has them."""
    primary = primary if primary is not None else res.primary if res.primary is not None else _primary_of(res)
    surfaces = composite.reshape(-1, 3)[~primary.sees_light]
    return res.cfg.render.exposure or auto_exposure(surfaces), surfaces


def _primary_of(res: RenderResult) -> Primary:
    """The AOVs of a result's whole-image G-buffer (a result made by hand, not by render)."""
    g = res.gbuffer
    primary = Primary.empty(g.pixels.shape[0])
    primary.add(res.frame, g, slice(0, g.pixels.shape[0]))
    return primary


def run(cfg: RunConfig, out: Path, base: Path | None = None, config_path: str | None = None,
        overrides: list[str] | None = None, outputs: Iterable[str] = OUTPUTS, progress: bool = False,
        reference: bool = False, say=None, via: str = "--set") -> dict:
    """Render, simulate and write; returns the results dictionary.

    ``config_path`` and ``overrides`` (the ``--set`` strings) say where the config came
    from, for error messages and ``results.json``. ``outputs``: which of :data:`OUTPUTS`
    the folder gets (without ``trace``, the timing model keeps no trace: ``arch.trace``
    is false in the resolved config). ``progress``: bars on stderr when it is a terminal.
    ``reference``: a photon-map frame without a cached reference gets one computed and
    cached (host stage ``reference``; ``say`` gets a line before and after), so that its
    error is measured. A folder another process's run is writing is refused before any work
    (an InputError naming that process; the threads of one process share their folders).

    ``results.json`` ``host_seconds`` has the stage ``one_off``: the seconds of the run in which
    numba compiled or loaded a kernel, or a module was imported for the first time (a sweep
    point's ``one_off``: :class:`~tlm.experiments.error_cost_clock.CompileClock`), in a stage or
    between stages (a cold run compiles its kernels as the batches' warm-up casts its first ray),
    taken out of the stages they fell in: so the stages say where a cold run's time went, and a
    cold run's passes read as a warm one's. Only the run's own (its thread's, and the kernel pool's
    calls for it: :func:`one_off_clock`): another thread's first import or compile meanwhile is not.
    """
    t_start = time.perf_counter()
    outputs = tuple(outputs)
    if "trace" not in outputs and cfg.arch.trace:
        cfg = replace(cfg, arch=replace(cfg.arch, trace=False))
    source = with_overrides(config_path, via) if overrides else config_path  # (via: what errors call them)
    check_destination(out, "results.json")  # before any work: a bad --out fails at once
    check_numba_threads()
    # the folder is this process's until it is written: another process's run into it is refused
    # now, before any work, naming this one (tlm.claims.claimed), not silently replaced at its end
    with claimed(out, "run"), one_off_clock() as spans:
        programs = programs_for(cfg, base)  # a bad instruction table fails before the render
        res = render(cfg, base, source, progress=progress, reference=reference, overrides=tuple(overrides or ()),
                     via=via)
        res = replace(res, base=base)  # (the config's folder: results.json's config_file, config_read.config_file)
        if reference and res.error is not None and not res.error["available"]:
            with res.timer.stage("reference"):
                error = photon_error(res.frame, res.radiance["pmap"].reshape(-1, 3), compute=True,
                                     progress=progress, say=say)
            res = replace(res, error=error)
        elif res.error is not None and not res.error["available"]:  # (skipped as asked: the report says so)
            res = replace(res, error={**res.error, **skipped_reference(cfg, config_path, overrides, out, base)})
        res = simulate_render(res, programs, progress=progress)
        with progress_bar(progress, desc="write", total=1, unit="folder", leave=False) as bar, Ticking(bar):
            results = write_run(res, out, config_path, overrides, outputs,
                                one_off=lambda: spans(t_start, time.perf_counter()))
            bar.update()
    return results


_CLOCK = CompileClock()  # (one per process: runs on several threads share it, each with its own spans)


@contextmanager
def one_off_clock():
    """The run's one-off clock: the process's :class:`~tlm.experiments.error_cost_clock.CompileClock`
    (numba compiling or loading a kernel, first imports), running while any :func:`run` of this
    process runs, and what it gives: ``spans(start, end)``, this run's spans cut to that window,
    those the run's own work began (on its thread, and on the kernels' pool threads working for
    it: :meth:`~tlm.experiments.error_cost_clock.CompileClock.owned`), not another thread's first
    import or compile meanwhile; a span still open, up to ``end``."""
    with _CLOCK.owned() as mine, _CLOCK.running():
        yield lambda start, end: _CLOCK.spans_of(mine, start, end)
