"""The photon-map frame a point of :mod:`tlm.experiments.error_cost` simulates: its work, as
:meth:`~tlm.arch.functional.Functional.of` builds it for ``tlm run`` (:func:`frame_functional`; the
passes other than the photon map computed once for every point that shares them, keyed by
:func:`others_key`), and the simulated frame's row columns (:func:`frame_time`). Moved out of
error_cost.py, which imports them from here.
"""

from __future__ import annotations

import json

import numpy as np

from tlm.arch.functional import Functional, TreeWork
from tlm.config import RunConfig, to_dict
from tlm.render.frame import Frame, GBuffer
from tlm.render.passes import PASS_FUNCTIONS, TRACED_BY
from tlm.render.planner import plan


def others_key(cfg: RunConfig, names: tuple[str, ...]) -> str:
    """What the passes other than the photon map depend on: the config but its photon,
    estimate and timing settings (and the reference's, which only the error reads)."""
    keep = {k: v for k, v in to_dict(cfg).items() if k not in ("photons", "estimate", "arch", "reference")}
    return json.dumps([list(names), keep], sort_keys=True, default=str)


def own_passes(names) -> tuple[str, ...]:
    """The planned passes computed on their own (not the photon map, nor what it traces)."""
    return tuple(n for n in names if n != "pmap" and n not in TRACED_BY)


def frame_functional(frame: Frame, g: GBuffer, geometry: TreeWork, others: dict[str, dict], traced,
                     pmap_work: dict[str, np.ndarray], fg_work: dict[str, np.ndarray] | None = None) -> Functional:
    """The work of the point's whole photon-map frame, as :meth:`Functional.of` builds it for
    ``tlm run``: the passes the planner runs for ``frame.cfg``, in plan order.

    ``others`` caches the work of the passes other than the photon map, keyed by what it
    depends on (computed here when missing, once for every point that shares it);
    ``traced`` is the point's photon trace and ``pmap_work`` its photon-map pass's work,
    ``fg_work`` its final-gather rays' (``g.memo["fgather_work"]`` after :func:`pmap_pass`).
    """
    names = tuple(plan(frame.scene, frame.cfg).run_names)
    rest = own_passes(names)
    key = others_key(frame.cfg, rest)
    if key not in others:  # (radiance, work) of each pass
        others[key] = {n: PASS_FUNCTIONS[n](frame, g) for n in rest}
    work = {n: w for n, (_, w) in others[key].items()}
    with_pmap = "pmap" in names
    if with_pmap:
        work["pmap"] = pmap_work
    if "fgather" in names:
        if fg_work is None:
            raise ValueError("frame_functional: the plan has final gathering: pass its rays' work (fg_work)")
        work["fgather"] = fg_work
    return Functional(  # the render's dicts, converted to the typed work by Functional
        passes=names,
        work={p: work[p] for p in names},
        geometry=geometry,
        photon_work=traced.work if with_pmap else None,
        photon_tree=TreeWork.of_maps(traced.photons) if with_pmap else None,
        pixels=int(g.pixels.shape[0]), width=int(frame.scene.camera.width),
    )


def frame_time(cycles: dict, clock_hz: float) -> dict:
    """A simulated frame's columns: throughput and latency cycles, seconds and FPS."""
    thr = int(cycles["throughput"])
    return {"throughput_cycles": thr, "latency_cycles": int(cycles["latency"]),
            "frame_seconds": thr / clock_hz, "fps": clock_hz / thr if thr > 0 else None}
