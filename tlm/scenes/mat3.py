"""3x3 matrix helpers for placing meshes, written out with numpy (no LAPACK call): the
determinant, the inverse and the adjugate of a node's linear part, and whether a singular one
keeps a flat mesh's triangles (:func:`keeps_triangles`). :mod:`tlm.scenes.meshes` and
:mod:`tlm.scenes.compose` use them."""

from __future__ import annotations

import numpy as np


def det3(m: np.ndarray) -> np.ndarray | float:
    """The determinant of a 3x3 matrix (or of each of a stack, ``(..., 3, 3)``) by the rule of
    Sarrus, written out: no LAPACK call, hence none of OpenBLAS's, whose first call takes a
    buffer of its own and, where a limit on the address space (``ulimit -v``) leaves too little
    for it, ends the process with its own line (``OpenBLAS error: Memory allocation still
    failed ...``, exit 1) instead of a MemoryError. Equal to ``np.linalg.det`` up to rounding."""
    m = np.asarray(m, dtype=np.float64)
    a, b, c = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    d, e, f = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    g, h, i = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    return (a * e * i + b * f * g + c * d * h) - (c * e * g + a * f * h + b * d * i)


def inverse3(m: np.ndarray) -> np.ndarray:
    """The inverse of a 3x3 matrix (or of each of a stack, ``(..., 3, 3)``): its adjugate (the
    transposed cofactors) over its determinant, written out (no LAPACK call: :func:`det3`).
    Equal to ``np.linalg.inv`` up to rounding; a singular matrix gives non-finite entries (no
    LinAlgError)."""
    m = np.asarray(m, dtype=np.float64)
    r0 = m[..., 0, :]
    adj = adjugate3(m)
    det = np.sum(r0 * adj[..., :, 0], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return adj / np.asarray(det)[..., None, None]


def adjugate3(m: np.ndarray) -> np.ndarray:
    """The adjugate of a 3x3 matrix (or of each of a stack): ``M @ adj = det(M) * I``, its
    columns the cross products of the rows. ``n @ adj`` turns a normal (a row) as the inverse
    transpose does, scaled by the determinant, and is defined for a singular ``M`` too (a flat
    mesh under a zero scale along its normal: every normal onto the plane's)."""
    m = np.asarray(m, dtype=np.float64)
    r0, r1, r2 = m[..., 0, :], m[..., 1, :], m[..., 2, :]
    return np.stack([_cross(r1, r2), _cross(r2, r0), _cross(r0, r1)], axis=-1)


def keeps_triangles(tri: np.ndarray, m: np.ndarray) -> bool:
    """Whether the singular 3x3 transform ``m`` keeps the triangles ``tri`` (n, 3, 3):
    they lie in one plane (to 1e-6 of their extent) and ``m`` maps that plane onto a plane (a
    zero scale along its normal, or across it at a slant), not onto a line or a point."""
    edge1, edge2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    cross = _cross(edge1, edge2)
    size = np.sqrt(np.sum(cross * cross, axis=1))
    if not (size.size and np.isfinite(size).all() and size.max() > 0.0):
        return False
    t = int(np.argmax(size))
    normal = cross[t] / size[t]
    corners = tri.reshape(-1, 3)
    extent = float(np.sqrt(np.sum((corners.max(axis=0) - corners.min(axis=0)) ** 2)))
    if np.abs(np.sum((corners - tri[t, 0]) * normal, axis=1)).max() > 1e-6 * extent:
        return False  # (not flat: any singular transform collapses it)
    u = edge1[t] / np.sqrt(np.sum(edge1[t] * edge1[t]))
    images = [np.sum(m * d, axis=1) for d in (u, _cross(normal, u))]  # (the plane's two axes, transformed)
    for i, v in enumerate(images):
        big = np.abs(v).max()
        if not big > 0.0:
            return False
        v = v / big
        images[i] = v / np.sqrt(np.sum(v * v))
    turn = _cross(images[0], images[1])
    return bool(np.sqrt(np.sum(turn * turn)) > 1e-12)


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``u x v`` along the last axis, written out (as ``np.cross``, which calls no BLAS either)."""
    return np.stack([u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1],
                     u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2],
                     u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]], axis=-1)
