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

The renderer (:func:`tlm.render.frame.shading_normals`) interpolates the corner normals with the hit's
barycentrics and uses the result for shading and for the mirror and Snell directions;
the geometric normal still decides sides and offsets (:mod:`tlm.kernels.shade`).
"""

from __future__ import annotations

import numpy as np

DEFAULT_CREASE_ANGLE = 30.0  # degrees: smooths tessellations finer than ~12 segments per circle


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


def _row_hash(pts: np.ndarray, part: np.ndarray) -> np.ndarray:
    """(m,) uint64 hash of the bits of each ``(x, y, z)`` row and its part."""
    bits = np.ascontiguousarray(pts).view(np.uint64)
    h = bits[:, 0] * np.uint64(0x9E3779B97F4A7C15)
    h ^= bits[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F)
    h ^= bits[:, 2] * np.uint64(0x165667B19E3779F9)
    h ^= part.astype(np.int64).view(np.uint64) * np.uint64(0x27D4EB2F165667C5)
    h ^= h >> np.uint64(29)
    return h


def _weld(points: np.ndarray, part: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Group equal ``(part, x, y, z)`` rows (float equality: -0.0 welds to 0.0).

    Returns ``order`` (row indices, grouped, ascending within a group), and each group's
    ``starts`` and ``sizes`` in ``order``. Rows are grouped by a stable sort of a hash of
    their bits (equal rows have equal hashes, so they end up in one run), and every run
    is checked to hold equal rows only; a collision (or a NaN) falls back to an exact
    lexicographic sort, which groups the same way.
    """
    pts = points + 0.0  # -0.0 -> +0.0, so that equal values have equal bits
    m = pts.shape[0]
    if np.isfinite(pts).all():
        h = _row_hash(pts, part)
        order = np.argsort(h, kind="stable")
        hs = h[order]
        starts = np.flatnonzero(np.r_[True, hs[1:] != hs[:-1]])
        sizes = np.diff(np.r_[starts, m])
        head = np.repeat(starts, sizes)  # each grouped row's group's first row
        rows, parts = pts[order], part[order]
        if np.array_equal(rows, rows[head]) and np.array_equal(parts, parts[head]):
            return order, starts, sizes
    order = np.lexsort((pts[:, 2], pts[:, 1], pts[:, 0], part))
    s = pts[order]
    p = part[order]
    new = np.r_[True, (s[1:] != s[:-1]).any(axis=1) | (p[1:] != p[:-1])]
    starts = np.flatnonzero(new)
    return order, starts, np.diff(np.r_[starts, m])


def crease_normals(triangles: np.ndarray, part: np.ndarray | None = None,
                   crease_angle: float = DEFAULT_CREASE_ANGLE) -> np.ndarray:
    """Per-corner unit shading normals (n, 3, 3) of world-space ``triangles`` (n, 3, 3).

    part : (n,) part ids (corners of different parts are never welded); None = one part.
    crease_angle : degrees; faces meeting at a larger angle keep their own normal.

    A corner's sum runs over its welded neighbours in ascending corner order (itself
    included), one neighbour rank at a time over all corners at once.
    """
    tri = np.asarray(triangles, dtype=np.float64)
    n = tri.shape[0]
    face = _unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    if n == 0 or not crease_angle > 0.0:
        return np.repeat(face[:, None, :], 3, axis=1)
    part = np.zeros(n, dtype=np.int64) if part is None else np.asarray(part, dtype=np.int64)
    cos_crease = np.cos(np.radians(min(float(crease_angle), 180.0)))
    weight = corner_angles(tri).reshape(-1)
    # weld corners by exact position within a part; largest groups first, so that the
    # corners with a j-th neighbour are always a prefix of the (grouped) corner list
    order, starts, sizes = _weld(tri.reshape(-1, 3), np.repeat(part, 3))
    big = np.argsort(-sizes, kind="stable")
    starts, sizes = starts[big], sizes[big]
    new_starts = np.cumsum(sizes) - sizes
    within = np.arange(3 * n) - np.repeat(new_starts, sizes)
    order = order[np.repeat(starts, sizes) + within]
    head = np.repeat(new_starts, sizes)  # where each grouped corner's group starts
    per_size = np.bincount(sizes) * np.arange(int(sizes.max()) + 1)  # corners in groups of each size
    active = np.cumsum(per_size[::-1])[::-1]  # active[j]: corners with a j-th neighbour (1-based)
    f = face[order // 3]
    fx, fy, fz = f[:, 0].copy(), f[:, 1].copy(), f[:, 2].copy()
    w = weight[order]
    ax, ay, az = np.zeros(3 * n), np.zeros(3 * n), np.zeros(3 * n)
    # sum over each corner's welded neighbours in ascending corner order (itself included),
    # the j-th neighbour of every corner at once
    for j in range(1, active.shape[0]):
        m = int(active[j])
        q = head[:m] + (j - 1)
        bx, by, bz = fx[q], fy[q], fz[q]
        ok = (fx[:m] * bx + fy[:m] * by) + fz[:m] * bz >= cos_crease  # = np.sum(.., axis=1)
        wq = np.where(ok, w[q], 0.0)  # a skipped neighbour adds +-0.0: the sum stays the same bits
        ax[:m] += wq * bx
        ay[:m] += wq * by
        az[:m] += wq * bz
    acc = np.empty((3 * n, 3))
    acc[order] = np.stack([ax, ay, az], axis=1)
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
