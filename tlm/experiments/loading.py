"""A config's frame: its scene loaded, its BSP built, its :class:`~tlm.render.frame.Frame` made.

Every command that renders starts with this one sequence (``tlm run``, ``tlm reference``,
``tlm error-vs-cost``); :func:`load_frame` is it, with the host seconds of its two costly
stages booked in a :class:`~tlm.progress.Timer` and a progress bar told which
stage it is in.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tlm.config import RunConfig
from tlm.kernels import release_memory, threads
from tlm.kernels.traverse import build_accel
from tlm.progress import Timer
from tlm.render.frame import Frame, GBuffer, cast
from tlm.scenes.loader import load_scene
from tlm.scenes.model import Scene


def load_frame(cfg: RunConfig, base: Path | None = None, source: str | None = None,
               timer: Timer | None = None, bar=None, scene: Scene | None = None) -> Frame:
    """``cfg``'s scene (relative paths from ``base``; ``source`` names the config in an
    InputError), its BSP (``bsp.levels``, ``bsp.memory_factor``) and the frame the passes
    render. ``timer``: gets the stages ``load_scene`` and ``build_bsp``; ``bar``: a
    progress bar whose description names the BSP build while it runs; ``scene``: the
    scene when the caller loaded it already (to look up a cache before building)."""
    timer = Timer() if timer is None else timer
    if scene is None:
        with timer.stage("load_scene"):
            scene = load_scene(cfg.scene, base, cfg.resolution, source)
    if bar is not None:
        bar.set_description_str(f"build BSP ({scene.n_triangles} triangles)")
    tables = threads.background(lambda: Frame.tables(scene))  # (on a worker while the BSP is built)
    with timer.stage("build_bsp"):
        accel = build_accel(scene.triangles, levels=cfg.bsp.levels, memory_factor=cfg.bsp.memory_factor)
    release_memory()  # (the build's freed blocks)
    return Frame.create(scene, accel, cfg, tables.result())


def cast_image(frame: Frame) -> GBuffer:
    """The eye rays of every pixel of ``frame`` cast as one batch: the whole image's G-buffer."""
    cam = frame.scene.camera
    return cast(frame, np.arange(cam.width * cam.height, dtype=np.int64))
