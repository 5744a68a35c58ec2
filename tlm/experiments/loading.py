"""A config's frame: its scene loaded, its BSP built, its :class:`~tlm.render.frame.Frame` made.

Every command that renders starts with this one sequence (``tlm run``, ``tlm reference``,
``tlm error-vs-cost``); :func:`load_frame` is it, with the host seconds of its two costly
stages booked in a :class:`~tlm.progress.Timer` and a progress bar told which
stage it is in.

While a sweep runs in this process (:func:`keeping_accel`), the last BSP built is remembered (:func:`accel_for`:
one, whatever the scene's size), so that renders of one scene and BSP one after another (a sweep's frames that
differ in what the BSP does not depend on, ``cache.pairs``, ``arch.*`` of the functional key) build it once;
elsewhere (``tlm run``, ``tlm.run`` from a notebook) nothing is kept after the render.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from tlm.config import RunConfig
from tlm.errors import InputError
from tlm.kernels import release_memory, threads
from tlm.kernels.traverse import build_accel
from tlm.progress import Timer
from tlm.render.frame import Frame, GBuffer, cast
from tlm.scenes.loader import load_scene
from tlm.scenes.model import Scene


def load_frame(cfg: RunConfig, base: Path | None = None, source: str | None = None,
               timer: Timer | None = None, bar=None, scene: Scene | None = None,
               check_photons: str | None = None) -> Frame:
    """``cfg``'s scene (relative paths from ``base``; ``source`` names the config in an
    InputError), its BSP (``bsp.levels``, ``bsp.memory_factor``) and the frame the passes
    render. ``timer``: gets the stages ``load_scene`` and ``build_bsp``; ``bar``: a
    progress bar whose description names the BSP build while it runs; ``scene``: the
    scene when the caller loaded it already (to look up a cache before building). A pmap run that nothing gives
    photons is an InputError once the scene is loaded, before its BSP, with ``check_photons`` (``"run"``: a
    run's; ``"reference"``: a reference's of no photons, its own line; :func:`check_photons_given`; not an
    error-vs-cost study's base, whose points give the count)."""
    timer = Timer() if timer is None else timer
    if scene is None:
        with timer.stage("load_scene"):
            scene = load_scene(cfg.scene, base, cfg.resolution, source)
    if check_photons:  # (a pmap run that nothing gives photons: before the BSP; h474)
        check_photons_given(scene, cfg, source, check_photons)
    if bar is not None:
        bar.set_description_str(f"build BSP ({scene.n_triangles} triangles)")
    tables = threads.background(lambda: Frame.tables(scene))  # (on a worker while the BSP is built)
    with timer.stage("build_bsp"):
        accel = accel_for(scene.triangles, cfg.bsp.levels, cfg.bsp.memory_factor)
    return Frame.create(scene, accel, cfg, threads.result(tables))


_LAST_ACCEL: list = []  # [(levels, memory_factor, accel)]: the last BSP this process built (one: its memory)
_ACCEL_LOCK = threading.Lock()
_KEEPING = [0]  # how many keeping_accel() are open in this process (a sweep's): the BSP is kept while any is


@contextmanager
def keeping_accel() -> Iterator[None]:
    """Keep the last BSP built (:func:`accel_for`) while this is open (a sweep's points in this process); let it
    go when the last one opened closes."""
    with _ACCEL_LOCK:
        _KEEPING[0] += 1
    try:
        yield
    finally:
        with _ACCEL_LOCK:
            _KEEPING[0] -= 1
            if _KEEPING[0] == 0:
                _LAST_ACCEL.clear()


def accel_for(triangles: np.ndarray, levels: int | None, memory_factor: float):
    """:func:`~tlm.kernels.traverse.build_accel` ``(triangles, levels, memory_factor)``, or the last one
    built in this process where it was built from the same arguments: triangles of the same bits (compared
    whole: a scene is never changed in place, nor is an accel by a render, whose kernels keep on it only
    what the same triangles give again, or sizes no result depends on). Only the last is kept: a scene of
    hundreds of thousands of triangles has a BSP of hundreds of MB; the one kept is let go before another is
    built, and none is kept outside :func:`keeping_accel` (a sweep's end lets it go)."""
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    with _ACCEL_LOCK:
        last = _LAST_ACCEL[0] if _LAST_ACCEL else None
    if last is not None and last[0] == levels and last[1] == memory_factor and _same_bits(last[2].triangles, tri):
        return last[2]
    forget_accel()  # (before the build: never two held at once)
    accel = build_accel(tri, levels=levels, memory_factor=memory_factor)
    release_memory()  # (the build's freed blocks)
    with _ACCEL_LOCK:
        if _KEEPING[0]:
            _LAST_ACCEL[:] = [(levels, memory_factor, accel)]
    return accel


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two float64 arrays hold the same bits (-0.0 is not 0.0, nor one NaN another)."""
    if a is b:
        return True
    return a.shape == b.shape and np.array_equal(np.ascontiguousarray(a).view(np.uint64),
                                                 np.ascontiguousarray(b).view(np.uint64))


def forget_accel() -> None:
    """Let go of the BSP :func:`accel_for` keeps (its frames' memory, once they are done)."""
    with _ACCEL_LOCK:
        _LAST_ACCEL.clear()


def cast_image(frame: Frame) -> GBuffer:
    """The eye rays of every pixel of ``frame`` cast as one batch: the whole image's G-buffer."""
    cam = frame.scene.camera
    return cast(frame, np.arange(cam.width * cam.height, dtype=np.int64))


def check_photons_given(scene: Scene, cfg: RunConfig, source: str | None = None, of: str = "run") -> None:
    """An InputError (exit status 2) naming ``scene``'s file and its key ``photons`` when ``cfg``'s mode asks for
    the photon-map pass and nothing gives it photons: the config's ``photons.count`` null and the scene file without
    ``photons:`` (or 0), where the pass would otherwise run (lights with power, a Lambertian surface). Said before
    the BSP is built or a ray cast, not as a warning after a run that renders no pmap frame and exits 0 (h474). A
    config's own ``photons.count: 0`` leaves the pass out on purpose, as before (the run warns of it). ``of``:
    ``"reference"``, for a reference whose ``reference.photons`` is null (its caller's to tell): it traces the scene
    file's count whatever the mode and ``photons.count``, and its line says what it lacks and what gives it."""
    from dataclasses import replace

    from tlm.experiments.run_warnings import BUILTIN_COUNTS
    from tlm.render.planner import plan

    reference = of == "reference"
    if scene.photons or (not reference and (cfg.mode != "pmap" or cfg.photons.count is not None)):
        return
    probe = replace(cfg, mode="pmap", photons=replace(cfg.photons, count=None)) if reference else cfg
    if not any(p.name == "pmap" and not p.run and p.by == "photons.count" for p in plan(scene, probe).passes):
        return
    if reference:  # (the k-nearest photons' estimate at the surfaces the eye sees is all it computes)
        raise InputError(
            "a photon-map reference is the estimate of each round's photons alone, but the scene file gives no "
            "photons (no photons:, or 0) and the config's reference.photons is null, so no photon would be traced "
            "and the reference would have nothing to estimate (every pixel 0): add `photons: N` "
            "to the scene file, or `reference: {photons: N}` to the config (--set reference.photons=N)"
            + f" {BUILTIN_COUNTS}", source=scene.source or source, key="photons")
    raise InputError(
        "mode 'pmap' asks for the photon-map pass, but the scene file gives no photons (no photons:, or 0) and the "
        "config's photons.count is null, so no photon would be traced and the run would have no pmap frame: add "
        "`photons: N` to the scene file, or `photons: {count: N}` to the config (--set photons.count=N)"
        + f" {BUILTIN_COUNTS}", source=scene.source or source, key="photons")
