"""Shading normals: one unit normal per triangle corner, interpolated across the triangle.

The thesis's vertex format carries normal indices beside the vertex indices (§IV.A): a
tessellated sphere is shaded with the sphere's normals, not its facets'. A scene's
shading normals come from its mesh file when the file has them (OBJ ``vn``, PLY and
glTF vertex normals) and are otherwise computed here with a *crease angle*
(``crease_angle`` in the scene file, degrees; default :data:`DEFAULT_CREASE_ANGLE`):

* corners are welded by exact position within a part (parts never smooth into each
  other: the ring's floor and the ring, a sphere and the box it stands on);
* a corner's normal is the sum of the unit face normals of the welded triangles whose
  face normal lies within the crease angle of its own triangle's, each weighted by the
  triangle's angle at that corner (so a fan of thin triangles does not outweigh a wide
  one); a box's 90-degree edges stay sharp, a 36x18 sphere's 10-degree facets blend;
* ``crease_angle: 0`` gives flat shading (every corner its face's normal), and a
  degenerate triangle (no face normal) keeps zero normals, for which the renderer falls
  back to the geometric normal.

The renderer (:mod:`tlm.render.passes`) interpolates the corner normals with the hit's
barycentrics and uses the result for shading and for the mirror and Snell directions;
the geometric normal still decides sides and offsets (:mod:`tlm.kernels.shade`).
"""

from __future__ import annotations

import numpy as np

DEFAULT_CREASE_ANGLE = 30.0  # degrees: smooths tessellations finer than ~12 segments per circle
PAIR_CHUNK = 1 << 22  # (corner, corner) pairs compared per block: bounds memory on large meshes


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def corner_angles(triangles: np.ndarray) -> np.ndarray:
    """(n, 3) interior angle of each triangle at each corner (0 for degenerate edges)."""
    out = np.zeros(triangles.shape[:2])
    for c in range(3):
        a = _unit(triangles[:, (c + 1) % 3] - triangles[:, c])
        b = _unit(triangles[:, (c + 2) % 3] - triangles[:, c])
        out[:, c] = np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0))
    return out


def crease_normals(triangles: np.ndarray, part: np.ndarray | None = None,
                   crease_angle: float = DEFAULT_CREASE_ANGLE) -> np.ndarray:
    """Per-corner unit shading normals (n, 3, 3) of world-space ``triangles`` (n, 3, 3).

    part : (n,) part ids (corners of different parts are never welded); None = one part.
    crease_angle : degrees; faces meeting at a larger angle keep their own normal.
    """
    tri = np.asarray(triangles, dtype=np.float64)
    n = tri.shape[0]
    face = _unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    if n == 0 or not crease_angle > 0.0:
        return np.repeat(face[:, None, :], 3, axis=1)
    part = np.zeros(n, dtype=np.int64) if part is None else np.asarray(part, dtype=np.int64)
    cos_crease = np.cos(np.radians(min(float(crease_angle), 180.0)))
    weight = corner_angles(tri).reshape(-1)
    # weld corners by exact position within a part
    key = np.concatenate([np.repeat(part, 3)[:, None].astype(np.float64), tri.reshape(-1, 3)], axis=1)
    _, vid = np.unique(key, axis=0, return_inverse=True)
    vid = vid.reshape(-1)
    order = np.argsort(vid, kind="stable")
    sorted_vid = vid[order]
    starts = np.flatnonzero(np.r_[True, sorted_vid[1:] != sorted_vid[:-1]])
    sizes = np.diff(np.r_[starts, sorted_vid.shape[0]])
    corner_face = np.arange(3 * n) // 3
    acc = np.zeros((3 * n, 3))
    # every (corner, neighbour) pair of a welded vertex, in blocks of whole vertices
    pairs = np.cumsum(sizes * sizes)
    lo = 0
    while lo < starts.shape[0]:
        base = pairs[lo - 1] if lo else 0
        hi = max(int(np.searchsorted(pairs, base + PAIR_CHUNK, side="right")), lo + 1)
        st, sz = starts[lo:hi], sizes[lo:hi]
        rep = np.repeat(np.arange(hi - lo), sz * sz)  # vertex of each pair
        within = np.arange(rep.shape[0]) - np.repeat(np.cumsum(sz * sz) - sz * sz, sz * sz)
        a = order[st[rep] + within // sz[rep]]  # the corner being shaded
        b = order[st[rep] + within % sz[rep]]  # a welded neighbour (itself included)
        fa, fb = corner_face[a], corner_face[b]
        ok = np.sum(face[fa] * face[fb], axis=1) >= cos_crease
        np.add.at(acc, a[ok], weight[b[ok], None] * face[fb[ok]])
        lo = hi
    normals = _unit(acc).reshape(n, 3, 3)
    # a corner whose neighbours cancel (or a sliver with zero angle weights) keeps its face normal
    flat = ~np.any(normals != 0.0, axis=2)
    normals[flat] = np.repeat(face[:, None, :], 3, axis=1)[flat]
    return normals


def interpolate(normals: np.ndarray, triangle: np.ndarray, u: np.ndarray, v: np.ndarray,
                geometric: np.ndarray) -> np.ndarray:
    """Unit shading normals at hits ``(triangle, u, v)`` (Möller–Trumbore barycentrics:
    ``u`` weights corner 1, ``v`` corner 2), turned to the geometric normal's side;
    ``geometric`` (k, 3) where the interpolation vanishes (degenerate input)."""
    c = normals[triangle]
    w0 = (1.0 - u - v)[:, None]
    s = _unit(w0 * c[:, 0] + u[:, None] * c[:, 1] + v[:, None] * c[:, 2])
    s = np.where((np.sum(s * geometric, axis=1) < 0.0)[:, None], -s, s)
    return np.where(np.any(s != 0.0, axis=1)[:, None], s, geometric)
