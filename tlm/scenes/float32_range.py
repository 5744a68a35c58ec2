"""Whether a scene's sizes suit the float32 ray-triangle test (out of :mod:`tlm.scenes.loader`, which
re-exports every name): :func:`check_float32_range`, :func:`float32_sizes`."""

from __future__ import annotations

import math

import numpy as np

from tlm.errors import InputError
from tlm.scenes.model import Scene

# The ray-triangle test decides which triangle a ray hits first in float32 (the Intersection
# PM's datapath: tlm.kernels.intersect.closest_slots and its compiled twin), from
# N = E1 x E2 (degree 2 in the scene's lengths) and T.N = (O - V0).N (degree 3); a float32
# miss is never checked in float64. |T.N| <= |O - V0| |N|, so a scene is in range when
#  * its extent R (the diagonal of the box around its triangles, camera eye and lights: every
#    ray starts in it) times its largest |N| stays under float32's largest number, with a
#    margin of F32_MARGIN (the Cornell box renders exactly up to R x |N| = 3.6e38 and not
#    at 1.7e39: scales 3e10 and 5e10); and
#  * its triangles' extent L times their median |N| (of those with area: a degenerate or
#    tiny triangle among others is legal) stays above float32's smallest normal number,
#    below which T.N loses bits (the Cornell box renders exactly down to L x median |N| =
#    5.5e-42 and not at 2.0e-43: scales 3e-16 and 1e-16).
# So the Cornell box (R x max |N| = 1.35e7, L x median |N| = 2.0e5) loads at scales from
# 3.9e-15 to 2.9e9 (tests/test_float32_range.py).
F32_MAX = float(np.finfo(np.float32).max)
F32_TINY = float(np.finfo(np.float32).tiny)
F32_MARGIN = 1024.0
SIZE_HI = F32_MAX / F32_MARGIN  # the largest extent x |E1 x E2| a scene may have (3.3e35)
SIZE_LO = F32_TINY  # the smallest extent x median |E1 x E2| (1.2e-38)


def float32_sizes(scene: Scene) -> dict[str, float]:
    """The lengths the float32 triangle test's range depends on (see :data:`SIZE_HI`):
    ``extent`` (R: the diagonal of the box around the triangles, the camera's eye and the
    quad, point and spot lights), ``largest`` (the largest ``|E1 x E2|``, twice a triangle's
    area), ``span`` (L: the diagonal of the triangles' box) and ``median`` (the median
    ``|E1 x E2|`` of the triangles with area; 0 when none has any)."""
    tri = scene.triangles
    flat = tri.reshape(-1, 3)
    pts = [flat.min(axis=0), flat.max(axis=0), np.asarray(scene.camera.eye, dtype=np.float64)]
    for lt in scene.lights:
        if lt.kind in ("point", "spot"):
            pts.append(np.asarray(lt.position, dtype=np.float64))
        elif lt.kind == "quad":
            c, u, v = (np.asarray(x, dtype=np.float64) for x in (lt.corner, lt.edge_u, lt.edge_v))
            pts += [c, c + u, c + v, c + u + v]
    pts = np.array(pts)
    n = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    area = n[n > 0.0]
    return {"extent": float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))),
            "largest": float(n.max(initial=0.0)),
            "span": float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0))),
            "median": float(np.median(area)) if area.shape[0] else 0.0}


def _two_digits(x: float, up: bool) -> float:
    """``x`` rounded to two significant digits, up or down."""
    e = math.floor(math.log10(x)) - 1
    m = x / 10.0**e
    return (math.ceil(m - 1e-9) if up else math.floor(m + 1e-9)) * 10.0**e


def check_float32_range(scene: Scene, src: str, key: str, scale: float = 1.0) -> None:
    """An InputError naming ``src`` and ``key`` when the float32 ray-triangle test cannot
    handle the scene's sizes (:data:`SIZE_HI`, :data:`SIZE_LO`), with the
    ``transform: {scale}`` that brings it in range (``scale``: the scene file's)."""
    s = float32_sizes(scene)
    big, small = s["extent"] * s["largest"], s["span"] * s["median"]
    if not (big > SIZE_HI or 0.0 < small < SIZE_LO):
        return
    # a scale f multiplies both products by f**3
    most = (SIZE_HI / big) ** (1.0 / 3.0) if big > 0.0 else math.inf
    least = (SIZE_LO / small) ** (1.0 / 3.0) if small > 0.0 else 0.0
    large = big > SIZE_HI
    extent, box, of, size, product, limit, effect, bound = (
        (s["extent"], "triangles, camera eye and lights", "largest triangle's |E1 x E2| (twice its area",
         s["largest"], big, f"over {SIZE_HI:.3g} (float32's largest number / {F32_MARGIN:g})", "overflows float32",
         f"scale it down: transform: {{scale: {_two_digits(scale * most, up=False):.2g}}} or less") if large else
        (s["span"], "triangles", "triangles' median |E1 x E2| (twice the area", s["median"], small,
         f"under {SIZE_LO:.3g} (float32's smallest normal number)", "loses its precision",
         f"scale it up: transform: {{scale: {_two_digits(scale * least, up=True):.2g}}} or more"))
    what = (f"the scene is too {'large' if large else 'small'} for the float32 ray-triangle test: its extent "
            f"{extent:.3g} (the diagonal of the box around its {box}) times its {of}, {size:.3g}) is {product:.3g}, "
            f"{limit}, where the test's T.N = (O - V0).(E1 x E2) {effect}")
    if least > most:
        bound = ("no scale brings it in range: its extent (camera and lights included) is too large for the size "
                 "of its triangles")
    raise InputError(f"{what}: {bound}", source=src, key=key)
