"""Small pure-numpy mesh primitives for the built-in scene builders.

Every function returns a ``(n, 3, 3)`` float64 array of triangles (``n`` triangles,
three vertices, xyz) and never emits a zero-area triangle. The winding is
counter-clockwise seen from outside: ``cross(v1 - v0, v2 - v0)`` points out of a
closed solid, and along ``cross(edge_u, edge_v)`` for a flat patch. Triangle counts are
exact functions of the tessellation arguments (given in each docstring), so that the
builders can hit a prescribed total. A tessellation too large for the machine is refused
before it is made (:func:`check_triangle_count`); the primitives a scene file's ``shape:``
items use (:func:`quad`, :func:`box` and :func:`aabox`, :func:`uv_sphere`,
:func:`cylinder`) name its size by the scene file's keys (``divisions``, ``segments``,
``rings``), the others by their own parameters.

Most round shapes are made by `lathe`, a surface of revolution of a 2-D profile; the
sphere, cylinder, torus and thick ring band are thin wrappers around it.
"""

from __future__ import annotations

import math
import os

import numpy as np

from tlm.scenes.validate import digit_count

__all__ = [
    "TRIANGLE_BYTES",
    "aabox",
    "box",
    "check_triangle_count",
    "cylinder",
    "grid",
    "lathe",
    "machine_memory",
    "oriented_box",
    "patch",
    "quad",
    "rotate",
    "torus",
    "translate",
    "triangle_areas",
    "triangle_normals",
    "tube",
    "uv_sphere",
]

_BOX_FACES = ("bottom", "top", "side0", "side1", "side2", "side3")


def _vec3(x, name: str = "vector") -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.shape != (3,):
        raise ValueError(f"{name} must have shape (3,), got {a.shape}")
    return a


def _unit(x, name: str = "axis") -> np.ndarray:
    a = _vec3(x, name)
    n = np.linalg.norm(a)
    if not n > 0:
        raise ValueError(f"{name} must be non-zero")
    return a / n


def _frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ``e1, e2`` with ``(e1, e2, axis)`` right-handed orthonormal.

    For ``axis = +y`` this gives ``e1 = +x`` and ``e2 = -z``.
    """
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    e1 = helper - axis * (helper @ axis)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    return e1, e2


def triangle_normals(triangles: np.ndarray) -> np.ndarray:
    """Unnormalised normals ``cross(v1 - v0, v2 - v0)``.

    Parameters
    ----------
    triangles : (n, 3, 3) float array

    Returns
    -------
    (n, 3) float64 array; its norm is twice the triangle area.
    """
    t = np.asarray(triangles, dtype=np.float64)
    return np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])


def triangle_areas(triangles: np.ndarray) -> np.ndarray:
    """Triangle areas.

    Parameters
    ----------
    triangles : (n, 3, 3) float array

    Returns
    -------
    (n,) float64 array.
    """
    return 0.5 * np.linalg.norm(triangle_normals(triangles), axis=1)


def grid(points: np.ndarray) -> np.ndarray:
    """Triangulate a structured grid of points, two triangles per cell.

    Cell ``(i, j)`` with corners ``p00 = points[i, j]``, ``p10 = points[i + 1, j]``,
    ``p11 = points[i + 1, j + 1]``, ``p01 = points[i, j + 1]`` becomes
    ``(p00, p10, p11)`` and ``(p00, p11, p01)``; cells are emitted in row-major
    ``(i, j)`` order, the two triangles of a cell next to each other. The normal
    follows ``cross(d/di, d/dj)``.

    Parameters
    ----------
    points : (nu + 1, nv + 1, 3) float array, nu, nv >= 1

    Returns
    -------
    (2 * nu * nv, 3, 3) float64 array.
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 3 or p.shape[2] != 3 or p.shape[0] < 2 or p.shape[1] < 2:
        raise ValueError(f"grid points must have shape (nu+1, nv+1, 3), got {p.shape}")
    p00, p10 = p[:-1, :-1], p[1:, :-1]
    p11, p01 = p[1:, 1:], p[:-1, 1:]
    a = np.stack([p00, p10, p11], axis=-2)
    b = np.stack([p00, p11, p01], axis=-2)
    return np.stack([a, b], axis=2).reshape(-1, 3, 3)


# a run's memory per triangle at the least: its float64 vertices (72 bytes), the BSP's slots
# and the kernels' padded float32 and float64 rows, the shading and material tables
TRIANGLE_BYTES = 512


def machine_memory() -> int:
    """This machine's physical memory in bytes (64 GiB where it cannot be read)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 1 << 36


def check_triangle_count(n: int, what: str) -> None:
    """A ValueError when ``n`` triangles (of ``what``, named in it) cannot fit in this
    machine's memory at :data:`TRIANGLE_BYTES` each: said before a tessellation is
    allocated, so an impossible size is an error, not an out-of-memory kill. A count too
    large for its GiB to be a float (a whole number of hundreds of digits) is said in digits."""
    n, total = int(n), machine_memory()
    if n * TRIANGLE_BYTES <= total:
        return
    if n.bit_length() > 900:  # (its GiB beyond a float: counted in digits, as tlm.scenes.builders does)
        raise ValueError(f"{what} makes {digit_count(n)} of triangles, more than this machine's "
                         f"{total / 2**30:.0f} GiB can hold")
    raise ValueError(f"{what} makes {n:,} triangles, about {n * TRIANGLE_BYTES / 2**30:,.0f} GiB to render, "
                     f"more than this machine's {total / 2**30:.0f} GiB")


def _say(n) -> str:
    """A whole number as an error line names it: its digits, or, past the 900 bits whose
    triangle count :func:`check_triangle_count` says in digits, how many digits it has."""
    n = int(n)
    return str(n) if n.bit_length() <= 900 else digit_count(n)


def _whole(n, lo: int) -> bool:
    """Whether ``n`` is a whole number >= ``lo`` (an int, or a finite float of a whole value)."""
    if isinstance(n, (float, np.floating)) and not math.isfinite(n):
        return False
    return int(n) == n and n >= lo


def _check_div(**divs: int) -> None:
    for name, n in divs.items():
        if not _whole(n, 1):
            raise ValueError(f"{name} must be a positive integer, got {n!r}")


def quad(corner, edge_u, edge_v, nu: int = 1, nv: int = 1) -> np.ndarray:
    """Parallelogram ``corner + a * edge_u + b * edge_v`` (a, b in [0, 1]) as a grid.

    Parameters
    ----------
    corner, edge_u, edge_v : (3,) float arrays
    nu, nv : int
        Number of cells along ``edge_u`` and ``edge_v``.

    Returns
    -------
    (2 * nu * nv, 3, 3) float64 array, normals along ``cross(edge_u, edge_v)``.
    """
    _check_div(nu=nu, nv=nv)
    check_triangle_count(2 * int(nu) * int(nv), f"divisions = [{_say(nu)}, {_say(nv)}]")
    c, u, v = _vec3(corner, "corner"), _vec3(edge_u, "edge_u"), _vec3(edge_v, "edge_v")
    a = np.linspace(0.0, 1.0, nu + 1)[:, None, None]
    b = np.linspace(0.0, 1.0, nv + 1)[None, :, None]
    return grid(c + a * u + b * v)


def patch(p00, p10, p11, p01, nu: int = 1, nv: int = 1) -> np.ndarray:
    """Bilinear patch through four corners (need not be planar nor a parallelogram).

    The corners are given in cyclic order; the normal points along
    ``cross(p10 - p00, p01 - p00)``. Two patches sharing an edge with the same number
    of cells along it share the vertices on it (no T-junctions).

    Parameters
    ----------
    p00, p10, p11, p01 : (3,) float arrays
    nu, nv : int
        Cells along ``p00 -> p10`` and along ``p00 -> p01``.

    Returns
    -------
    (2 * nu * nv, 3, 3) float64 array.
    """
    _check_div(nu=nu, nv=nv)
    check_triangle_count(2 * int(nu) * int(nv), f"nu = {_say(nu)} x nv = {_say(nv)}")
    c = [_vec3(p, "corner") for p in (p00, p10, p11, p01)]
    a = np.linspace(0.0, 1.0, nu + 1)[:, None, None]
    b = np.linspace(0.0, 1.0, nv + 1)[None, :, None]
    pts = (1 - a) * (1 - b) * c[0] + a * (1 - b) * c[1] + a * b * c[2] + (1 - a) * b * c[3]
    return grid(pts)


def box(corners, n: int = 1, omit: tuple[str, ...] = ()) -> np.ndarray:
    """Hexahedron from 8 corners (a box that may be rotated or sheared).

    ``corners[0:4]`` is the bottom ring and ``corners[4:8]`` the top ring, with
    ``corners[4 + i]`` above ``corners[i]``; either ring direction is accepted, the
    winding is made outward from the signed volume. Faces are emitted in the order
    bottom, top, side0 .. side3 (side ``i`` joins bottom corners ``i`` and ``i + 1``),
    each as an ``n`` x ``n`` bilinear patch.

    Parameters
    ----------
    corners : (8, 3) float array
    n : int
        Cells per face edge.
    omit : tuple of str
        Faces to leave out, from 'bottom', 'top', 'side0' .. 'side3' (e.g. the
        bottom of a block resting on the floor).

    Returns
    -------
    (2 * n * n * (6 - len(omit)), 3, 3) float64 array.
    """
    _check_div(n=n)
    c = np.asarray(corners, dtype=np.float64)
    if c.shape != (8, 3):
        raise ValueError(f"box corners must have shape (8, 3), got {c.shape}")
    bad = set(omit) - set(_BOX_FACES)
    if bad:
        raise ValueError(f"unknown box faces {sorted(bad)}; expected some of {_BOX_FACES}")
    faces = len(set(_BOX_FACES) - set(omit))
    check_triangle_count(2 * int(n) * int(n) * faces, f"divisions = {_say(n)} (a side, on each of {faces} faces)")
    # Signed volume (divergence theorem) with the ring taken as given: if negative,
    # the ring runs the other way and every face must be flipped.
    quads = {
        "bottom": (0, 3, 2, 1),
        "top": (4, 5, 6, 7),
        "side0": (0, 1, 5, 4),
        "side1": (1, 2, 6, 5),
        "side2": (2, 3, 7, 6),
        "side3": (3, 0, 4, 7),
    }
    full = np.concatenate([patch(*c[list(q)]) for q in quads.values()])
    volume = np.einsum("ij,ij->i", full[:, 0], triangle_normals(full)).sum() / 6.0
    if not abs(volume) > 0:
        raise ValueError("box corners enclose zero volume")
    parts = []
    for name in _BOX_FACES:
        if name in omit:
            continue
        q = quads[name]
        if volume < 0:
            q = (q[0], q[3], q[2], q[1])
        parts.append(patch(*c[list(q)], nu=n, nv=n))
    if not parts:
        return np.zeros((0, 3, 3))
    return np.concatenate(parts)


def oriented_box(
    center_bottom, size, yaw_deg: float = 0.0, n: int = 1, omit: tuple[str, ...] = ()
) -> np.ndarray:
    """Box standing on the plane ``y = center_bottom[1]``, turned about +y.

    Parameters
    ----------
    center_bottom : (3,) float array
        Centre of the bottom face.
    size : (3,) float array
        Extent along x, y, z before the rotation.
    yaw_deg : float
        Rotation about +y in degrees (right-handed: +x turns towards -z).
    n, omit
        As in `box`.

    Returns
    -------
    (2 * n * n * (6 - len(omit)), 3, 3) float64 array.
    """
    cb = _vec3(center_bottom, "center_bottom")
    sx, sy, sz = _vec3(size, "size")
    ring = np.array([[-sx, 0, -sz], [sx, 0, -sz], [sx, 0, sz], [-sx, 0, sz]]) / 2.0
    t = np.radians(yaw_deg)
    rot = np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
    ring = ring @ rot.T
    corners = np.concatenate([ring, ring + [0.0, sy, 0.0]]) + cb
    return box(corners, n=n, omit=omit)


def aabox(lo, hi, n: int = 1, omit: tuple[str, ...] = ()) -> np.ndarray:
    """Axis-aligned box between the corners ``lo`` and ``hi`` ('bottom' is ``y = lo[1]``).

    Sides: side0 is ``z = lo[2]``, side1 ``x = hi[0]``, side2 ``z = hi[2]``, side3
    ``x = lo[0]``.

    Parameters
    ----------
    lo, hi : (3,) float arrays, ``lo < hi`` componentwise
    n, omit
        As in `box`.

    Returns
    -------
    (2 * n * n * (6 - len(omit)), 3, 3) float64 array.
    """
    lo, hi = _vec3(lo, "lo"), _vec3(hi, "hi")
    if not np.all(hi > lo):
        raise ValueError(f"aabox needs lo < hi, got lo={lo.tolist()} hi={hi.tolist()}")
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    ring = np.array([[x0, 0, z0], [x1, 0, z0], [x1, 0, z1], [x0, 0, z1]])
    corners = np.concatenate([ring + [0, y0, 0], ring + [0, y1, 0]])
    return box(corners, n=n, omit=omit)


def lathe(
    radii,
    heights,
    n_seg: int,
    center=(0.0, 0.0, 0.0),
    axis=(0.0, 1.0, 0.0),
    closed: bool = False,
    phase: float = 0.0,
) -> np.ndarray:
    """Surface of revolution of the profile ``(radii[j], heights[j])`` about ``axis``.

    Vertex ``(i, j)`` is ``center + radii[j] * (cos t e1 + sin t e2) + heights[j] *
    axis`` with ``t = phase + 2 pi i / n_seg``. Each profile segment whose two radii
    are positive gives ``2 * n_seg`` triangles; a segment with one zero radius (a
    pole) gives a fan of ``n_seg`` triangles. The surface faces the side of
    ``cross(d/dt, d/dprofile)``: a profile that runs up the outside of a solid (or
    around its cross-section counter-clockwise in the (r, h) half-plane) faces out.

    Parameters
    ----------
    radii, heights : (m,) float arrays
        Profile; radii >= 0, zero radii only at the ends of an open profile.
    n_seg : int
        Segments around the axis, >= 3.
    center : (3,) float array
    axis : (3,) float array
    closed : bool
        Also join the last profile point back to the first (a ring-like solid).
    phase : float
        Angle of the first meridian in radians.

    Returns
    -------
    (k, 3, 3) float64 array, ``k = sum over profile segments`` as above.
    """
    r = np.asarray(radii, dtype=np.float64)
    h = np.asarray(heights, dtype=np.float64)
    if r.ndim != 1 or r.shape != h.shape or r.size < 2:
        raise ValueError("radii and heights must be 1-D of the same length >= 2")
    if not _whole(n_seg, 3):
        raise ValueError(f"n_seg must be an integer >= 3, got {n_seg!r}")
    if np.any(r < 0) or not np.all(np.isfinite(r)) or not np.all(np.isfinite(h)):
        raise ValueError("profile radii must be finite and >= 0")
    pole = r == 0
    if np.any(pole[1:-1]) or (closed and np.any(pole)):
        raise ValueError("zero radius is allowed only at the ends of an open profile")
    ring_r = np.append(r, r[0]) if closed else r
    sides = int(np.count_nonzero(ring_r[:-1] > 0)) + int(np.count_nonzero(ring_r[1:] > 0))  # (a pole: a fan)
    check_triangle_count(sides * int(n_seg), f"n_seg = {_say(n_seg)} around a profile of {r.size} points")
    c, ax = _vec3(center, "center"), _unit(axis)
    e1, e2 = _frame(ax)
    t = phase + 2.0 * np.pi * np.arange(n_seg) / n_seg
    ring = np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2  # (n_seg, 3)
    pts = c + r[:, None, None] * ring[None] + h[:, None, None] * ax  # (m, n_seg, 3)
    j0 = np.arange(r.size if closed else r.size - 1)
    j1 = (j0 + 1) % r.size
    i0 = np.arange(n_seg)
    i1 = (i0 + 1) % n_seg
    v0, v1 = pts[j0][:, i0], pts[j0][:, i1]
    v2, v3 = pts[j1][:, i1], pts[j1][:, i0]
    a = np.stack([v0, v1, v2], axis=-2)  # (segments, n_seg, 3, 3)
    b = np.stack([v0, v2, v3], axis=-2)
    keep_a = np.broadcast_to(~pole[j0][:, None], (j0.size, n_seg))
    keep_b = np.broadcast_to(~pole[j1][:, None], (j0.size, n_seg))
    if np.any(pole[j0] & pole[j1]):
        raise ValueError("two consecutive zero radii in the profile")
    tris = np.stack([a, b], axis=2).reshape(-1, 3, 3)
    keep = np.stack([keep_a, keep_b], axis=2).reshape(-1)
    return tris[keep]


def uv_sphere(center, radius: float, n_seg: int, n_rings: int, axis=(0.0, 1.0, 0.0)):
    """Latitude-longitude sphere with triangle fans at the two poles.

    Parameters
    ----------
    center : (3,) float array
    radius : float
    n_seg : int
        Meridian segments, >= 3.
    n_rings : int
        Latitude bands from pole to pole, >= 2.
    axis : (3,) float array
        Pole direction.

    Returns
    -------
    (2 * n_seg * (n_rings - 1), 3, 3) float64 array, outward winding.
    """
    if not _whole(n_rings, 2):
        raise ValueError(f"n_rings must be an integer >= 2, got {n_rings!r}")
    if not _whole(n_seg, 3):  # (said before the rings are made, as lathe would say it)
        raise ValueError(f"n_seg must be an integer >= 3, got {n_seg!r}")
    check_triangle_count(2 * int(n_seg) * (int(n_rings) - 1),
                         f"a sphere of segments = {_say(n_seg)} and rings = {_say(n_rings)}")
    phi = np.pi * np.arange(n_rings + 1) / n_rings
    r = radius * np.sin(phi)
    r[0] = r[-1] = 0.0
    return lathe(r, -radius * np.cos(phi), n_seg, center=center, axis=axis)


def cylinder(
    base_center,
    radius: float,
    height: float,
    n_seg: int,
    axis=(0.0, 1.0, 0.0),
    bottom: bool = True,
    top: bool = True,
) -> np.ndarray:
    """Cylinder from ``base_center`` along ``axis``, with optional fan caps.

    Parameters
    ----------
    base_center : (3,) float array
    radius, height : float
    n_seg : int
        Segments around the axis, >= 3.
    axis : (3,) float array
    bottom, top : bool
        Whether to close the bottom / top with a cap.

    Returns
    -------
    ((2 + bottom + top) * n_seg, 3, 3) float64 array, outward winding.
    """
    sides = 2 + bool(bottom) + bool(top)  # (triangles a segment: the wall's two, a cap's one)
    if _whole(n_seg, 3) and radius > 0:  # (the count lathe makes; it checks n_seg itself)
        check_triangle_count(sides * int(n_seg),
                             f"a cylinder of segments = {_say(n_seg)} ({sides} triangles a segment)")
    r = [radius, radius]
    h = [0.0, height]
    if bottom:
        r, h = [0.0, *r], [0.0, *h]
    if top:
        r, h = [*r, 0.0], [*h, height]
    return lathe(r, h, n_seg, center=base_center, axis=axis)


def tube(
    base_center,
    r_inner: float,
    r_outer: float,
    height: float,
    n_seg: int,
    axis=(0.0, 1.0, 0.0),
) -> np.ndarray:
    """Thick ring band (a short pipe): outer and inner walls and the two annular rims.

    Parameters
    ----------
    base_center : (3,) float array
        Centre of the bottom rim.
    r_inner, r_outer : float
        ``0 < r_inner < r_outer``.
    height : float
    n_seg : int
        Segments around the axis, >= 3.
    axis : (3,) float array

    Returns
    -------
    (8 * n_seg, 3, 3) float64 array, outward winding; emitted as outer wall, top rim,
    inner wall, bottom rim.
    """
    if not 0 < r_inner < r_outer:
        raise ValueError(f"tube needs 0 < r_inner < r_outer, got {r_inner}, {r_outer}")
    r = [r_outer, r_outer, r_inner, r_inner]
    h = [0.0, height, height, 0.0]
    return lathe(r, h, n_seg, center=base_center, axis=axis, closed=True)


def torus(
    center, R: float, r: float, n_major: int, n_minor: int, axis=(0.0, 1.0, 0.0)
) -> np.ndarray:
    """Torus around ``axis`` through ``center``.

    Parameters
    ----------
    center : (3,) float array
    R : float
        Distance from the axis to the tube centre.
    r : float
        Tube radius, ``0 < r < R``.
    n_major : int
        Segments around the axis, >= 3.
    n_minor : int
        Segments around the tube, >= 3.
    axis : (3,) float array

    Returns
    -------
    (2 * n_major * n_minor, 3, 3) float64 array, outward winding.
    """
    if not 0 < r < R:
        raise ValueError(f"torus needs 0 < r < R, got R={R}, r={r}")
    if not _whole(n_minor, 3):
        raise ValueError(f"n_minor must be an integer >= 3, got {n_minor!r}")
    if not _whole(n_major, 3):  # (said before the profile is made)
        raise ValueError(f"n_major must be an integer >= 3, got {n_major!r}")
    check_triangle_count(2 * int(n_major) * int(n_minor), f"n_major = {_say(n_major)} x n_minor = {_say(n_minor)}")
    phi = 2.0 * np.pi * np.arange(n_minor) / n_minor
    return lathe(R + r * np.cos(phi), r * np.sin(phi), n_major, center, axis, closed=True)


def rotate(triangles, angle_deg: float, axis=(0.0, 1.0, 0.0), origin=(0.0, 0.0, 0.0)):
    """Rotate triangles about the line through ``origin`` along ``axis`` (right-handed).

    Parameters
    ----------
    triangles : (n, 3, 3) float array
    angle_deg : float
    axis, origin : (3,) float arrays

    Returns
    -------
    (n, 3, 3) float64 array.
    """
    k = _unit(axis)
    o = _vec3(origin, "origin")
    t = np.radians(angle_deg)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    rot = np.eye(3) + np.sin(t) * kx + (1 - np.cos(t)) * (kx @ kx)
    return (np.asarray(triangles, dtype=np.float64) - o) @ rot.T + o


def translate(triangles, offset) -> np.ndarray:
    """Shift triangles by ``offset``.

    Parameters
    ----------
    triangles : (n, 3, 3) float array
    offset : (3,) float array

    Returns
    -------
    (n, 3, 3) float64 array.
    """
    return np.asarray(triangles, dtype=np.float64) + _vec3(offset, "offset")
