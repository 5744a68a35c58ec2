"""Photons that leave a closed box through a wall: a count, not a timing.

A photon ray leaving a wall skips every hit closer than ``tmin`` (``SPAWN_EPS`` times
the scene diagonal, docs/functional.md "Self-intersection"), so one leaving within
``tmin`` of an edge, toward the wall that meets it there, passes through the corner.
This script traces a scene's photons with every ray recorded (it wraps the
``closest_hit`` that ``tlm.kernels.photons.trace_photons`` calls) and counts the rays
that hit nothing, split by where they leave the triangles' bounding box: through the
box's open face (as they should) or through a wall (a leak). It also counts stored
photons and hit points outside the box (both should be 0).

    python benchmarks/photon_leaks.py [--scene cornell] [--photons 400000] [--open z-]

``--open`` names the open face of the box: an axis and a side (``z-``: the face at the
smallest z, the built-in ``cornell``'s; ``z+`` for the McGuire Cornell boxes).
"""

from __future__ import annotations

import argparse

import numpy as np

import tlm
import tlm.kernels.photons as photons
from tlm.kernels.traverse import build_accel


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="cornell", help="a built-in scene's name or a scene file")
    ap.add_argument("--photons", type=int, default=400_000)
    ap.add_argument("--open", default="z-", help="the box's open face: x-, x+, y-, y+, z- or z+")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    open_axis, open_side = "xyz".index(args.open[0]), args.open[1]

    scene = tlm.load_scene(args.scene)
    accel = build_accel(scene.triangles)
    rays: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
    closest_hit = photons.closest_hit

    def recording(accel, origins, directions, **kw):
        hit = closest_hit(accel, origins, directions, **kw)
        rays.append((origins.copy(), directions.copy(), hit.triangle.copy(), hit.t.copy()))
        return hit

    photons.closest_hit = recording
    try:
        traced = photons.trace_photons(scene, accel, args.photons, seed=args.seed, global_map=True)
    finally:
        photons.closest_hit = closest_hit
    flat = scene.triangles.reshape(-1, 3)
    lo, hi = flat.min(0), flat.max(0)
    tol = 1e-6 * float(np.linalg.norm(hi - lo))
    outside = {name: int(np.any((m.position < lo - tol) | (m.position > hi + tol), axis=1).sum())
               for name, m in (("caustic", traced.photons.caustic_map), ("indirect", traced.photons.indirect_map),
                               ("global", traced.photons.global_map))}
    o, d, tri, t = (np.concatenate(c) for c in zip(*rays, strict=True))
    hit = tri >= 0
    points = o[hit] + t[hit, None] * d[hit]
    hits_outside = int(np.any((points < lo - tol) | (points > hi + tol), axis=1).sum())
    o, d = o[~hit], d[~hit]
    with np.errstate(divide="ignore", invalid="ignore"):
        leave = np.where(d > 0, (hi - o) / d, np.where(d < 0, (lo - o) / d, np.inf))
    axis = np.argmin(leave, axis=1)
    side = np.where(d[np.arange(len(d)), axis] > 0, "+", "-")
    through_open = (axis == open_axis) & (side == open_side)
    print(f"{args.scene}: {args.photons} photons, {len(tri)} photon rays, {int((~hit).sum())} hit nothing: "
          f"{int(through_open.sum())} left through the open face {args.open}, "
          f"{int((~through_open).sum())} through a wall")
    print(f"  stored photons outside the box: {outside}; hit points outside it: {hits_outside}")


if __name__ == "__main__":
    main()
