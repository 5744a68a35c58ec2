"""Which pixels two renderers can be compared at when they sample the pixel differently.

Mitsuba's film (box filter) gives each pixel the mean radiance over its square; our ray
cast traces one ray through the pixel's centre (or a few jittered ones). The two agree
wherever the radiance is smooth across the pixel, and not at silhouettes, creases,
material boundaries and the edges of a light seen directly, where a pixel's square
holds two surfaces in a proportion one central ray cannot see. :func:`smooth_pixels`
finds the pixels away from all of those, from the geometry alone (no shading): a pixel
is *smooth* when ``supersample x supersample`` rays through its square and through the
squares of its eight neighbours all meet the same plane of the same material and no
light. Checking the neighbours too catches slivers thinner than the supersampling grid:
an edge that clips a pixel's corner passes through a neighbour's sample region as well.
Shadow boundaries are not edges here: under an area light they are penumbrae, smooth
at the scale of a pixel.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tlm.kernels.camera import primary_rays
from tlm.kernels.traverse import TriangleAccel, build_accel, closest_hit
from tlm.scenes.model import Scene


def _lights_seen(scene: Scene, o: np.ndarray, d: np.ndarray, t_hit: np.ndarray) -> np.ndarray:
    """(k,) index of the nearest quad light each ray crosses before ``t_hit`` (either side), else -1."""
    seen = np.full(o.shape[0], -1, dtype=np.int64)
    best = t_hit.copy()
    for i, light in enumerate(scene.lights):
        if light.kind != "quad" or not light.area > 0:
            continue
        nl = light.normal
        c, eu, ev = (np.asarray(x, dtype=np.float64) for x in (light.corner, light.edge_u, light.edge_v))
        dn = d @ nl
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((c - o) @ nl) / dn
        t = np.where(np.isfinite(t), t, np.inf)
        p = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d - c
        gram = np.array([[eu @ eu, eu @ ev], [eu @ ev, ev @ ev]])
        a, b = np.linalg.solve(gram, np.stack([p @ eu, p @ ev]))
        hit = (t > 0) & (t <= best) & (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1)
        seen[hit] = i
        best = np.where(hit, t, best)
    return seen


def smooth_pixels(scene: Scene, supersample: int = 2, accel: TriangleAccel | None = None) -> np.ndarray:
    """(height, width) bool: the pixels whose neighbourhood shows one plane of one material.

    supersample : rays per pixel side used to look at each pixel's square.
    accel : the triangle BSP of ``scene`` (built when None).
    """
    if supersample < 1:
        raise ValueError(f"supersample must be >= 1, got {supersample}")
    cam = scene.camera
    w, h, s = cam.width, cam.height, supersample
    big = replace(cam, width=w * s, height=h * s)
    tri = np.asarray(scene.triangles, dtype=np.float64)
    accel = build_accel(tri) if accel is None else accel
    o, d = primary_rays(big, np.arange(w * h * s * s, dtype=np.int64))
    hits = closest_hit(accel, o, d, tmin=0.0, shared_origin=True)
    lo, hi = scene.bounds()
    diag = float(np.linalg.norm(hi - lo)) or 1.0
    t = np.maximum(hits.triangle, 0)
    n = np.cross(tri[t, 1] - tri[t, 0], tri[t, 2] - tri[t, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), np.finfo(float).tiny)
    offset = np.sum(n * tri[t, 0], axis=1) / diag
    material = np.asarray(scene.material_index)[t].astype(np.float64)
    key = np.column_stack([np.round(n, 6), np.round(offset, 6), material])
    key[hits.triangle < 0] = -2.0  # the background
    light = _lights_seen(scene, o, d, hits.t)
    key[light >= 0] = -3.0 - light[light >= 0, None]
    label = np.unique(key, axis=0, return_inverse=True)[1].reshape(h, s, w, s)
    from scipy import ndimage

    low = ndimage.minimum_filter(label.min(axis=(1, 3)), size=3, mode="nearest")
    high = ndimage.maximum_filter(label.max(axis=(1, 3)), size=3, mode="nearest")
    return low == high


def ray_cast_pixels(frame, g) -> np.ndarray:
    """(height, width) bool: where our ray-cast frame and Mitsuba's ``direct`` image are
    comparable: no eye ray of the pixel (or of a neighbour) sees a light, and none meets a
    mirror or glass (the ray-cast frame leaves those to the Reflect and Refract frames, by
    the thesis's pass structure; Mitsuba's direct integrator shows the light reflected there).

    frame, g : the :class:`~tlm.render.frame.Frame` and :class:`~tlm.render.frame.GBuffer`
    of a whole image.
    """
    from scipy import ndimage

    cam = frame.scene.camera
    shape = (cam.height, cam.width)
    light = ndimage.binary_dilation((~g.every(~g.sees_emitter)).reshape(shape))
    specular = (g.triangle >= 0) & (frame.kind[np.maximum(g.triangle, 0)] > 0)
    return ~light & g.every(~specular).reshape(shape)


def light_footprint(frame, supersample: int = 4) -> np.ndarray:
    """(height, width) bool: the pixels whose square shows a light, directly or as a highlight
    in a mirror or glass, looked at through ``supersample x supersample`` eye rays on a grid
    of sub-pixel centres (:func:`tlm.render.passes.sees_a_light` of that finer camera, one ray
    each). Mitsuba's film box-filters the whole square, so a highlight a pixel's few jittered
    samples miss is in the truth all the same (h472: on CornellBox-Sphere at 40x30, the light
    in the mirror sphere at one pixel, 4.10 in the truth, 0.06 in ours, 98% of the error); a
    light region the grid misses lies between its rays, narrower than 1/supersample of a pixel.
    """
    from tlm.render.frame import cast
    from tlm.render.passes import sees_a_light

    if supersample < 1:
        raise ValueError(f"supersample must be >= 1, got {supersample}")
    cam = frame.scene.camera
    s = supersample
    big = replace(cam, width=cam.width * s, height=cam.height * s)
    fine = replace(frame, scene=replace(frame.scene, camera=big),
                   cfg=replace(frame.cfg, render=replace(frame.cfg.render, spp=1)))
    g = cast(fine, np.arange(big.width * big.height, dtype=np.int64), record=False)
    return sees_a_light(fine, g).reshape(cam.height, s, cam.width, s).any(axis=(1, 3))
