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


_SMALL_GROUP = 256  # welded groups of more corners are summed by :func:`_group_sums`
_CLUSTER_RADIUS = 1e-6  # radians: face normals this close share one crease decision
_WIDE = 0.45  # a second try: clusters of up to this fraction of the crease angle (a pole's fan, a flat apex)
_MAX_CLUSTERS = 16
_MARGIN = 1e-9  # on the cosine: far above the rounding of a dot product of unit vectors


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (radians) between the rows of ``a`` and the vector ``b`` (accurate near 0 and pi)."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))  # (no BLAS call)


def _clusters(f: np.ndarray, cos_crease: float, radius: float = _CLUSTER_RADIUS,
              centred: bool = False) -> tuple[np.ndarray, np.ndarray] | None:
    """Label the face normals ``f`` (k, 3) of one welded group by cluster (each the normals
    within ``radius`` radians of its reference: the first normal left, or with ``centred``
    their mean direction where that is near any), and decide the crease test between every
    two clusters once for all their members: ``(labels, ok)``
    with ``ok[a, b]`` the bits that ``dot(f_i, f_j) >= cos_crease`` gives for every ``i``
    in ``a`` and ``j`` in ``b``; None where a pair of clusters (or a cluster with itself) lies
    too near the crease angle to decide for all members (or there are too many clusters)."""
    k = f.shape[0]
    if not np.isfinite(f).all():
        return None
    labels = np.full(k, -1, dtype=np.int64)
    zero = ~np.any(f != 0.0, axis=1)  # a degenerate face: its dot with any normal is +-0.0
    refs: list[np.ndarray] = []
    radii: list[float] = []
    rest = np.flatnonzero(~zero)
    while rest.size:
        if len(refs) == _MAX_CLUSTERS:
            return None
        ref = f[rest[0]]
        ang = _angle(f[rest], ref)
        if centred:  # (a fan's normals around a pole: one cluster about their mean, none about the first)
            mean = np.sum(f[rest], axis=0)
            size = float(np.sqrt(np.sum(mean * mean)))
            if size > 0.0 and np.isfinite(size):
                about = _angle(f[rest], mean / size)
                if np.count_nonzero(about <= radius) > np.count_nonzero(ang <= radius):
                    ref, ang = mean / size, about
        inside = ang <= radius
        labels[rest[inside]] = len(refs)
        refs.append(ref)
        radii.append(float(ang[inside].max()))
        rest = rest[~inside]
    u = len(refs)
    ok = np.zeros((u + 1, u + 1), dtype=bool)
    ok[u, :] = ok[:, u] = cos_crease <= 0.0  # (+-0.0 >= cos_crease)
    labels[zero] = u
    for a in range(u):
        theta = _angle(np.array(refs), refs[a])
        spread = np.array(radii) + radii[a]
        near, far = np.cos(np.minimum(theta + spread, np.pi)), np.cos(np.maximum(theta - spread, 0.0))
        yes, no = near >= cos_crease + _MARGIN, far < cos_crease - _MARGIN
        if not np.all(yes | no):
            return None
        ok[a, :u] = yes
    return labels, ok


def _group_sums(f: np.ndarray, w: np.ndarray, cos_crease: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each corner's weighted normal sum over the welded group with face normals ``f`` (k, 3)
    and angle weights ``w`` (k,), in ascending corner order (the bits of the neighbour-rank
    loop in :func:`crease_normals`). Corners whose normals fall in one cluster make the same
    crease decisions, so they share one sequential sum (``np.cumsum`` adds in order): time
    O(k x clusters). Clusters of normals within 1e-6 radians are tried first, then wider ones
    about their mean (up to ``_WIDE`` of the crease angle: the fan around a sphere's pole or a
    flat cone's apex, whose normals all lie within the crease angle of each other). A group that
    does not cluster so (a steep cone's apex: its normals around a circle wider than the crease
    angle, each corner's neighbours a window of its own) falls back to k passes of length k: a
    sum in floating point depends on where it starts, so windows that start at different
    corners share no partial sums, and the same bits need every corner's own sum."""
    k = f.shape[0]
    found = _clusters(f, cos_crease)
    if found is None and cos_crease < 1.0:  # (wider clusters, about their mean: a pole's or a flat apex's fan)
        found = _clusters(f, cos_crease, _WIDE * float(np.arccos(cos_crease)), centred=True)
    out = np.zeros((3, k))
    if found is None:
        for j in range(k):
            b = f[j]
            ok = (f[:, 0] * b[0] + f[:, 1] * b[1]) + f[:, 2] * b[2] >= cos_crease
            wq = np.where(ok, w[j], 0.0)
            out += wq * b[:, None]
        return out[0], out[1], out[2]
    labels, ok = found
    for a in np.unique(labels):
        wq = np.where(ok[a][labels], w, 0.0)
        total = np.cumsum(np.concatenate([np.zeros((1, 3)), wq[:, None] * f]), axis=0)[-1]
        out[:, labels == a] = total[:, None]
    return out[0], out[1], out[2]


def crease_normals(triangles: np.ndarray, part: np.ndarray | None = None,
                   crease_angle: float = DEFAULT_CREASE_ANGLE) -> np.ndarray:
    """Per-corner unit shading normals (n, 3, 3) of world-space ``triangles`` (n, 3, 3).

    part : (n,) part ids (corners of different parts are never welded); None = one part.
    crease_angle : degrees; faces meeting at a larger angle keep their own normal.

    A corner's sum runs over its welded neighbours in ascending corner order (itself
    included), one neighbour rank at a time over all corners at once; a group of more
    than ``_SMALL_GROUP`` corners by :func:`_group_sums`, with the same bits.
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
    # groups of more than _SMALL_GROUP corners (a prefix of the grouped list) one at a time,
    # in time linear in their size (a fan's first vertex is in every one of its triangles)
    large = int(np.sum(sizes[sizes > _SMALL_GROUP]))
    for g in np.flatnonzero(sizes > _SMALL_GROUP):
        lo, hi = int(new_starts[g]), int(new_starts[g] + sizes[g])
        ax[lo:hi], ay[lo:hi], az[lo:hi] = _group_sums(f[lo:hi], w[lo:hi], cos_crease)
    # the other groups: sum over each corner's welded neighbours in ascending corner order
    # (itself included), the j-th neighbour of every corner at once
    for j in range(1, min(active.shape[0], _SMALL_GROUP + 1)):
        m = int(active[j])
        q = head[large:m] + (j - 1)
        bx, by, bz = fx[q], fy[q], fz[q]
        ok = (fx[large:m] * bx + fy[large:m] * by) + fz[large:m] * bz >= cos_crease  # = np.sum(.., axis=1)
        wq = np.where(ok, w[q], 0.0)  # a skipped neighbour adds +-0.0: the sum stays the same bits
        ax[large:m] += wq * bx
        ay[large:m] += wq * by
        az[large:m] += wq * bz
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
