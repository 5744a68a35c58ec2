"""Geometry of the three built-in scenes: ``ring``, ``room`` and ``cornell``.

Each builder takes optional keyword parameters (the ``params`` of a scene file) and
returns a :class:`~tlm.scenes.model.Geometry` whose parts are named after material
roles, so that a scene file only maps part names to materials. At the default
parameters the triangle counts are exactly those of the test scenes in J. Ling's 2004
thesis: ring 646, room 7812, cornell 2604. Every count is a closed-form function of
the parameters, written out in each docstring.

A parameter that is not a number of the right kind, or out of its range, raises
:class:`BuilderParamError` (a ValueError) naming the keyword, which is also the scene
file's key under ``params:``; a geometry whose triangles could not fit in this machine's
memory is refused before any is made (:func:`shapes.check_triangle_count`), naming the
keywords that make it so.

Conventions: +y is up; surfaces that bound a room face into it; solids face out; a
solid resting on a surface touches it but never shares a coplanar face with it (its
bottom face is left out, or it stands a hair above); no two parts overlap.
"""

from __future__ import annotations

import inspect
import math
import sys
from collections.abc import Callable

import numpy as np

from tlm.config_words import listing
from tlm.scenes import shapes, validate
from tlm.scenes.model import Geometry

__all__ = ["BUILDERS", "BuilderParamError", "cornell", "ring", "room"]


class BuilderParamError(ValueError):
    """One parameter's refusal. ``key`` is the keyword, which is also the key a scene file
    writes under ``params:``; ``reason`` is what a scene file's error line says after that
    key (the value and what it must be). ``str()`` names the keyword, for Python callers."""

    def __init__(self, key: str, value, must: str):
        self.key = key
        shown = validate.shown(value)
        self.reason = f"{shown} {must}"
        super().__init__(f"{key} {must}, got {shown}")




class _Parts:
    """Collects triangle arrays under part names, in order of first use."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self.chunks: list[tuple[int, np.ndarray]] = []

    def add(self, name: str, *arrays: np.ndarray) -> None:
        if name not in self.names:
            self.names.append(name)
        idx = self.names.index(name)
        for a in arrays:
            self.chunks.append((idx, np.asarray(a, dtype=np.float64).reshape(-1, 3, 3)))

    def geometry(self) -> Geometry:
        tris = np.concatenate([c for _, c in self.chunks])
        part = np.concatenate([np.full(len(c), i, dtype=np.int32) for i, c in self.chunks])
        return Geometry(triangles=tris, part=part, part_names=tuple(self.names))


def _is_number(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def _is_finite(value) -> bool:
    """A finite number (a Python int of any size is one; np.isfinite refuses those beyond int64)."""
    return _is_number(value) and (isinstance(value, (int, np.integer)) or math.isfinite(value))


def _positive_int(name: str, value, minimum: int = 1) -> int:
    if not _is_finite(value) or int(value) != value or value < minimum:
        raise BuilderParamError(name, value, f"must be a whole number >= {minimum}")
    return int(value)


def _real(name: str, value) -> float:
    """A finite number as a float (a whole number beyond 1.8e308 cannot be one)."""
    if abs(value) > sys.float_info.max:
        raise BuilderParamError(name, value, f"is too large (at most {sys.float_info.max:.3g})")
    return float(value)


def _positive(name: str, value) -> float:
    if not _is_finite(value) or not value > 0:
        raise BuilderParamError(name, value, "must be a positive number")
    return _real(name, value)


def _finite(name: str, value) -> float:
    if not _is_finite(value):
        raise BuilderParamError(name, value, "must be a finite number")
    return _real(name, value)


def _check_size(builder: Callable[..., Geometry], terms: list[tuple[int, dict[str, float]]]) -> None:
    """Refuse, before anything is made, a tessellation that cannot fit in this machine's memory
    (:func:`shapes.check_triangle_count`), naming the parameters that make it too large as a
    scene file writes them (its keys under ``params:`` are the keywords). ``terms``: the
    closed-form count's terms, each with the keywords and values it depends on (none for a
    constant). Named are as few terms as leave the rest small enough to fit: first those with
    a value away from its default, then the others, each the largest first."""
    total = sum(n for n, _ in terms)
    fits = shapes.machine_memory() // shapes.TRIANGLE_BYTES
    if total <= fits:
        return
    defaults = {k: p.default for k, p in inspect.signature(builder).parameters.items()}
    named: dict[str, float] = {}
    rest = total
    for n, keys in sorted((t for t in terms if t[1]),
                          key=lambda t: (all(v == defaults[k] for k, v in t[1].items()), -t[0])):
        if rest <= fits:
            break
        named.update(keys)
        rest -= n
    given = [f"{k} = {validate.shown(v)}" for k, v in named.items()]
    what = f"{builder.__name__} with {listing(given)}"
    shapes.check_triangle_count(total, what)  # (a count past 900 bits named by its digits)


# --------------------------------------------------------------------------- cornell

# Cornell University's measured Cornell box (millimetres), vertex order as published.
CORNELL_FLOOR = ((552.8, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 559.2), (549.6, 0.0, 559.2))
CORNELL_CEILING = (
    (556.0, 548.8, 0.0), (556.0, 548.8, 559.2), (0.0, 548.8, 559.2), (0.0, 548.8, 0.0),
)
CORNELL_BACK = (
    (549.6, 0.0, 559.2), (0.0, 0.0, 559.2), (0.0, 548.8, 559.2), (556.0, 548.8, 559.2),
)
CORNELL_RIGHT = ((0.0, 0.0, 559.2), (0.0, 0.0, 0.0), (0.0, 548.8, 0.0), (0.0, 548.8, 559.2))
CORNELL_LEFT = (
    (552.8, 0.0, 0.0), (549.6, 0.0, 559.2), (556.0, 548.8, 559.2), (556.0, 548.8, 0.0),
)
CORNELL_SHORT_TOP = ((130.0, 165.0, 65.0), (82.0, 165.0, 225.0), (240.0, 165.0, 272.0),
                     (290.0, 165.0, 114.0))
CORNELL_TALL_TOP = ((423.0, 330.0, 247.0), (265.0, 330.0, 296.0), (314.0, 330.0, 456.0),
                    (472.0, 330.0, 406.0))
# The light (not geometry): 130 x 105 at the ceiling, x 213..343, z 227..332.
CORNELL_LIGHT = ((343.0, 548.8, 227.0), (343.0, 548.8, 332.0), (213.0, 548.8, 332.0),
                 (213.0, 548.8, 227.0))


def _block(top: tuple, n: int) -> np.ndarray:
    top = np.asarray(top, dtype=np.float64)
    bottom = top * [1.0, 0.0, 1.0]
    return shapes.box(np.concatenate([bottom, top]), n=n, omit=("bottom",))


def cornell(
    wall_div: int = 6,
    block_div: int = 3,
    mirror_radius: float = 80.0,
    mirror_seg: int = 30,
    mirror_rings: int = 15,
    glass_radius: float = 90.0,
    glass_seg: int = 36,
    glass_rings: int = 18,
) -> Geometry:
    """The measured Cornell box with a mirror sphere and a glass sphere (millimetres).

    Walls and blocks use Cornell University's published vertices: floor ``y = 0``,
    ceiling ``y = 548.8``, back wall ``z = 559.2``, red left wall at ``x`` 552.8..556,
    green right wall at ``x = 0``, open front at ``z = 0``. The camera of the published
    set-up is at (278, 273, -800) looking along +z. The 130 x 105 ceiling light is a
    light of the scene file, not geometry. The blocks have no bottom face (they stand
    on the floor). A mirror sphere rests on the centre of the short block's top and a
    glass sphere on the floor in the front left (large-x) part of the box.

    Parameters
    ----------
    wall_div : int
        Each of the five walls is a ``wall_div`` x ``wall_div`` bilinear grid.
    block_div : int
        Each of the five faces of each block is a ``block_div`` x ``block_div`` grid.
    mirror_radius, glass_radius : float
        Sphere radii in mm; at most 140 and 110, which keeps them clear of the blocks
        and walls.
    mirror_seg, mirror_rings, glass_seg, glass_rings : int
        `shapes.uv_sphere` tessellation: ``seg`` meridians, ``rings`` latitude bands.

    Returns
    -------
    Geometry
        Parts ``floor, ceiling, back_wall, left_wall, right_wall, short_block,
        tall_block, mirror_object, glass_object``; ``10 * wall_div**2 + 20 *
        block_div**2 + 2 * mirror_seg * (mirror_rings - 1) + 2 * glass_seg *
        (glass_rings - 1)`` triangles (2604 at the defaults: 360 + 180 + 840 + 1224).
    """
    n = _positive_int("wall_div", wall_div)
    m = _positive_int("block_div", block_div)
    r_mirror = _positive("mirror_radius", mirror_radius)
    r_glass = _positive("glass_radius", glass_radius)
    if r_mirror > 140.0:
        raise BuilderParamError("mirror_radius", mirror_radius,
                                "must be at most 140 mm (it would reach the tall block)")
    if r_glass > 110.0:
        raise BuilderParamError("glass_radius", glass_radius, "must be at most 110 mm (it would reach a block)")
    ms = _positive_int("mirror_seg", mirror_seg, 3)
    gs = _positive_int("glass_seg", glass_seg, 3)
    mr = _positive_int("mirror_rings", mirror_rings, 2)
    gr = _positive_int("glass_rings", glass_rings, 2)
    _check_size(cornell, [
        (10 * n * n, {"wall_div": n}),
        (20 * m * m, {"block_div": m}),
        (2 * ms * (mr - 1), {"mirror_seg": ms, "mirror_rings": mr}),
        (2 * gs * (gr - 1), {"glass_seg": gs, "glass_rings": gr}),
    ])
    p = _Parts()
    for name, q in (
        ("floor", CORNELL_FLOOR),
        ("ceiling", CORNELL_CEILING),
        ("back_wall", CORNELL_BACK),
        ("left_wall", CORNELL_LEFT),
        ("right_wall", CORNELL_RIGHT),
    ):
        p.add(name, shapes.patch(*q, nu=n, nv=n))
    p.add("short_block", _block(CORNELL_SHORT_TOP, m))
    p.add("tall_block", _block(CORNELL_TALL_TOP, m))
    top = np.mean(CORNELL_SHORT_TOP, axis=0)
    mirror_center = top + [0.0, r_mirror, 0.0]
    p.add("mirror_object", shapes.uv_sphere(mirror_center, r_mirror, ms, mr))
    glass_center = np.array([400.0, r_glass, 130.0])
    p.add("glass_object", shapes.uv_sphere(glass_center, r_glass, gs, gr))
    return p.geometry()


# --------------------------------------------------------------------------- ring


def ring(
    n_seg: int = 72,
    radius: float = 5.0,
    thickness: float = 0.3,
    height: float = 3.5,
    floor_nx: int = 7,
    floor_nz: int = 5,
    floor_cell: float = 10.0,
    floor_back: float = 0.4,
    glass_radius: float = 0.0,
    glass_seg: int = 16,
    glass_rings: int = 9,
    glass_x: float = -10.0,
    glass_z: float = -3.0,
) -> Geometry:
    """A polished metal ring standing on a diffuse floor (centimetres).

    The ring is a thick band (a short pipe: outer wall, top rim, inner wall, bottom
    rim) around the +y axis through the origin, standing on its rim on the floor
    ``y = 0``. Its bottom rim faces the floor, so it touches the floor without a
    coplanar face pointing the same way. The floor is a ``floor_nx`` x ``floor_nz``
    grid of square cells, centred on the ring in x and reaching further towards the
    camera side (-z) than behind. A point light low at the side (+x, a little behind)
    reflects off the inside of the far wall into the classic cardioid caustic on the
    floor inside the ring, while the ring's shadow falls towards -x. The walls are flat
    facets, so the caustic is made of ``n_seg`` overlapping streaks.

    Parameters
    ----------
    n_seg : int
        Segments around the ring.
    radius : float
        Outer radius in cm.
    thickness : float
        Wall thickness in cm (inner radius ``radius - thickness``).
    height : float
        Ring height in cm.
    floor_nx, floor_nz : int
        Floor cells along x and z.
    floor_cell : float
        Floor cell size in cm.
    floor_back : float
        Fraction of the floor's depth that lies behind the ring (+z), in (0, 1).
    glass_radius : float
        Radius in cm of a glass sphere resting on the floor at ``(glass_x, glass_z)``
        (part ``glass``); 0 (the default) leaves it out.
    glass_seg, glass_rings : int
        The glass sphere's `shapes.uv_sphere` tessellation (checked also when the
        sphere is left out).
    glass_x, glass_z : float
        Where the glass sphere stands; it must lie on the floor and clear the ring.

    Returns
    -------
    Geometry
        Parts ``floor, ring`` and, with ``glass_radius > 0``, ``glass``;
        ``2 * floor_nx * floor_nz + 8 * n_seg`` triangles (646 at the defaults: 70 +
        576), plus ``2 * glass_seg * (glass_rings - 1)`` with the glass sphere.
    """
    n = _positive_int("n_seg", n_seg, 3)
    nx = _positive_int("floor_nx", floor_nx)
    nz = _positive_int("floor_nz", floor_nz)
    r_out = _positive("radius", radius)
    t = _positive("thickness", thickness)
    h = _positive("height", height)
    cell = _positive("floor_cell", floor_cell)
    if not _is_finite(floor_back) or not 0.0 < floor_back < 1.0:
        raise BuilderParamError("floor_back", floor_back, "must lie in (0, 1)")
    # (the glass sphere's parameters are checked even when glass_radius = 0 leaves it out)
    rg = 0.0 if _is_number(glass_radius) and glass_radius == 0 else _positive("glass_radius", glass_radius)
    gs = _positive_int("glass_seg", glass_seg, 3)
    gr = _positive_int("glass_rings", glass_rings, 2)
    gx, gz = _finite("glass_x", glass_x), _finite("glass_z", glass_z)
    if not t < r_out:
        raise ValueError(f"thickness = {t} must be smaller than radius = {r_out}")
    _check_size(ring, [
        (2 * nx * nz, {"floor_nx": nx, "floor_nz": nz}),
        (8 * n, {"n_seg": n}),
        (2 * gs * (gr - 1) if rg else 0, {"glass_radius": glass_radius, "glass_seg": gs, "glass_rings": gr}),
    ])
    sx, sz = nx * cell, nz * cell
    # Floor: centred in x; in z, floor_back (default 40 %) of the depth lies behind the ring (+z).
    z_back = floor_back * sz
    if sx / 2.0 < r_out or z_back < r_out:
        raise ValueError(
            f"the floor (floor_nx * floor_cell = {sx} cm wide, floor_back * floor_nz * floor_cell = {z_back} cm "
            f"behind the ring) does not hold a ring of radius = {r_out} cm"
        )
    corner = (-sx / 2.0, 0.0, z_back)
    p = _Parts()
    p.add("floor", shapes.quad(corner, (sx, 0.0, 0.0), (0.0, 0.0, -sz), nu=nx, nv=nz))
    p.add("ring", shapes.tube((0.0, 0.0, 0.0), r_out - t, r_out, h, n))
    if rg:
        sphere = f"the glass sphere of glass_radius = {rg} at glass_x = {gx}, glass_z = {gz}"
        if np.hypot(gx, gz) < r_out + rg:
            raise ValueError(f"{sphere} would touch the ring of radius = {r_out}")
        if not (-sx / 2.0 + rg <= gx <= sx / 2.0 - rg and z_back - sz + rg <= gz <= z_back - rg):
            raise ValueError(f"{sphere} does not stand on the floor (x {-sx / 2.0} to {sx / 2.0}, "
                             f"z {z_back - sz} to {z_back})")
        p.add("glass", shapes.uv_sphere((gx, rg, gz), rg, gs, gr))
    return p.geometry()


# --------------------------------------------------------------------------- room


def _chair(seat_center: np.ndarray, yaw: float, div: int) -> list[np.ndarray]:
    """A wooden chair facing -z before the ``yaw`` turn about +y (metres)."""
    seat_h, seat_t, w, leg = 0.44, 0.04, 0.44, 0.04
    x0 = seat_center[0]
    z0 = seat_center[2]
    parts = [
        shapes.aabox((x0 - w / 2, seat_h, z0 - w / 2), (x0 + w / 2, seat_h + seat_t, z0 + w / 2),
                     n=div),
    ]
    for sx in (-1, 1):
        for sz in (-1, 1):
            cx = x0 + sx * (w / 2 - leg / 2)
            cz = z0 + sz * (w / 2 - leg / 2)
            parts.append(shapes.aabox((cx - leg / 2, 0.0, cz - leg / 2),
                                      (cx + leg / 2, seat_h, cz + leg / 2), omit=("bottom", "top")))
    # Back: two posts on the +z edge rising from the seat, and a rail between them.
    zb = z0 + w / 2 - leg / 2
    for sx in (-1, 1):
        cx = x0 + sx * (w / 2 - leg / 2)
        parts.append(shapes.aabox((cx - leg / 2, seat_h + seat_t, zb - leg / 2),
                                  (cx + leg / 2, 0.95, zb + leg / 2), omit=("bottom",)))
    parts.append(shapes.aabox((x0 - w / 2 + leg, 0.68, zb - 0.015),
                              (x0 + w / 2 - leg, 0.90, zb + 0.015), n=div))
    tris = np.concatenate(parts)
    return [shapes.rotate(tris, yaw, origin=seat_center)]


def _books(x0: float, x1: float, y0: float, z0: float, z1: float, seed: int, max_h: float):
    """A row of upright books standing on the shelf board ``y = y0``, 4 mm apart.

    Widths, heights and depths follow a fixed low-discrepancy sequence (no random
    generator, so the count never changes between numpy versions).
    """
    out = []
    x = x0 + 0.01
    k = 0
    while True:
        a, b, c = ((seed * 7 + k) * np.array([0.6180339887, 0.7548776662, 0.5698402910])) % 1.0
        w = 0.02 + 0.03 * a
        if x + w > x1 - 0.01:
            break
        h = (0.6 + 0.4 * b) * max_h
        d = (0.75 + 0.25 * c) * (z1 - z0)
        out.append(shapes.aabox((x, y0, z1 - d), (x + w, y0 + h, z1), omit=("bottom",)))
        x += w + 0.004
        k += 1
    return out


def room(
    grid_x: int = 20,
    grid_y: int = 10,
    grid_z: int = 23,
    glass_seg: int = 34,
    glass_rings: int = 17,
    vase_seg: int = 40,
    leg_seg: int = 16,
    sofa_div: int = 3,
    furniture_div: int = 2,
) -> Geometry:
    """A furnished living room, 5 m wide (x), 6 m deep (z), 2.6 m high (metres).

    The room is closed: floor ``y = 0``, ceiling ``y = 2.6``, walls at ``x = 0, 5`` and
    ``z = 0, 6``, all facing in. Against the back wall (``z = 6``) stand a bookshelf with
    books (left part of the view, small x) and, on the wall, a framed mirror; a sofa
    stands against the right-hand wall ``x = 0``; a dining table with two chairs and
    a rug stand in the middle of the room; on the table are a glass sphere and a glass
    vase (a closed solid with a cavity). A camera near the front wall ``z = 0`` looking
    along +z sees all of it. Large furniture faces are subdivided so that photon
    density can be resolved on them.

    Parameters
    ----------
    grid_x, grid_y, grid_z : int
        Cells of the floor, ceiling and walls along x, y and z (25-26 cm at the
        defaults).
    glass_seg, glass_rings : int
        Glass sphere tessellation (`shapes.uv_sphere`).
    vase_seg : int
        Segments around the glass vase (a 14-point profile with a pole at each end).
    leg_seg : int
        Segments around each (open) table leg.
    sofa_div : int
        Grid per face of the sofa's six boxes.
    furniture_div : int
        Grid per face of the table top, chair seats, chair back rails and rug.

    Returns
    -------
    Geometry
        Parts ``floor, ceiling, walls, rug, wood, fabric, books, frame, mirror, glass``;
        ``4 * (grid_x * grid_z + grid_x * grid_y + grid_z * grid_y) + 2 * glass_seg *
        (glass_rings - 1) + 24 * vase_seg + 8 * leg_seg + 60 * sofa_div**2 + 70 *
        furniture_div**2 + 1256`` triangles, the constant being chair legs and posts
        (104), shelf (90), books (1020), frame (40) and mirror (2). At the defaults:
        3560 + 1088 + 960 + 128 + 540 + 280 + 1256 = 7812.
    """
    gx = _positive_int("grid_x", grid_x)
    gy = _positive_int("grid_y", grid_y)
    gz = _positive_int("grid_z", grid_z)
    leg_seg = _positive_int("leg_seg", leg_seg, 3)
    vase_seg = _positive_int("vase_seg", vase_seg, 3)
    sd = _positive_int("sofa_div", sofa_div)
    fd = _positive_int("furniture_div", furniture_div)
    gs = _positive_int("glass_seg", glass_seg, 3)
    gr = _positive_int("glass_rings", glass_rings, 2)
    _check_size(room, [
        (4 * (gx * gz + gx * gy + gz * gy), {"grid_x": gx, "grid_y": gy, "grid_z": gz}),
        (2 * gs * (gr - 1), {"glass_seg": gs, "glass_rings": gr}),
        (24 * vase_seg, {"vase_seg": vase_seg}),
        (8 * leg_seg, {"leg_seg": leg_seg}),
        (60 * sd * sd, {"sofa_div": sd}),
        (70 * fd * fd, {"furniture_div": fd}),
        (1256, {}),
    ])
    W, H, D = 5.0, 2.6, 6.0
    p = _Parts()

    # Shell, every surface facing into the room.
    p.add("floor", shapes.quad((0, 0, 0), (0, 0, D), (W, 0, 0), nu=gz, nv=gx))
    p.add("ceiling", shapes.quad((0, H, 0), (W, 0, 0), (0, 0, D), nu=gx, nv=gz))
    p.add(
        "walls",
        shapes.quad((0, 0, D), (0, H, 0), (W, 0, 0), nu=gy, nv=gx),  # back, z = D
        shapes.quad((0, 0, 0), (W, 0, 0), (0, H, 0), nu=gx, nv=gy),  # front, z = 0
        shapes.quad((0, 0, 0), (0, H, 0), (0, 0, D), nu=gy, nv=gz),  # right, x = 0
        shapes.quad((W, 0, 0), (0, 0, D), (0, H, 0), nu=gz, nv=gy),  # left, x = W
    )

    # Rug under the table: a 1 cm slab without a bottom face.
    p.add("rug", shapes.aabox((1.6, 0.0, 2.9), (4.2, 0.01, 5.1), n=fd, omit=("bottom",)))

    # Dining table: top 1.4 x 0.8 at 0.72..0.76 m, four round legs standing on the rug.
    tx0, tx1, tz0, tz1 = 2.2, 3.6, 3.5, 4.3
    top_y0, top_y1 = 0.72, 0.76
    wood = [shapes.aabox((tx0, top_y0, tz0), (tx1, top_y1, tz1), n=fd)]
    for lx in (tx0 + 0.07, tx1 - 0.07):
        for lz in (tz0 + 0.07, tz1 - 0.07):
            wood.append(shapes.cylinder((lx, 0.01, lz), 0.03, top_y0 - 0.01, leg_seg,
                                        bottom=False, top=False))
    # Two chairs: one at the left end of the table facing it, one behind it.
    wood += _chair(np.array([3.95, 0.0, 3.9]), 90.0, fd)
    wood += _chair(np.array([2.9, 0.0, 4.75]), 0.0, fd)

    # Bookshelf against the back wall, 2 cm off it: two sides, five boards, a back.
    bx0, bx1, bz0, bz1, bh, th = 0.9, 2.3, 5.63, 5.98, 1.9, 0.025
    wood.append(shapes.aabox((bx0, 0.0, bz0), (bx0 + th, bh, bz1), omit=("bottom",)))
    wood.append(shapes.aabox((bx1 - th, 0.0, bz0), (bx1, bh, bz1), omit=("bottom",)))
    boards = (0.0, 0.45, 0.9, 1.35, bh - th)
    for y in boards:
        omit = ("bottom",) if y == 0.0 else ()
        wood.append(shapes.aabox((bx0 + th, y, bz0), (bx1 - th, y + th, bz1 - 0.01), omit=omit))
    wood.append(shapes.aabox((bx0 + th, th, bz1 - 0.01), (bx1 - th, bh - th, bz1)))
    p.add("wood", *wood)

    # Sofa against the right wall x = 0 (2 cm off it): base, back, two arms, two cushions.
    fabric = [
        shapes.aabox((0.02, 0.0, 2.4), (0.92, 0.40, 4.6), n=sd, omit=("bottom",)),
        shapes.aabox((0.02, 0.40, 2.4), (0.25, 0.85, 4.6), n=sd, omit=("bottom",)),
        shapes.aabox((0.25, 0.40, 2.4), (0.92, 0.62, 2.58), n=sd, omit=("bottom",)),
        shapes.aabox((0.25, 0.40, 4.42), (0.92, 0.62, 4.6), n=sd, omit=("bottom",)),
        shapes.aabox((0.26, 0.40, 2.59), (0.90, 0.52, 3.49), n=sd, omit=("bottom",)),
        shapes.aabox((0.26, 0.40, 3.51), (0.90, 0.52, 4.41), n=sd, omit=("bottom",)),
    ]
    p.add("fabric", *fabric)

    # Books on the three middle boards of the shelf (a fixed pseudo-random row each).
    books = []
    for k, y in enumerate(boards[:3]):
        books += _books(bx0 + th, bx1 - th, y + th, bz0 + 0.02, bz1 - 0.02, seed=k, max_h=0.38)
    p.add("books", *books)

    # Framed mirror on the back wall, behind the table: a 1.3 x 0.9 m panel 1.5 cm in
    # front of the wall, and a 6 cm frame 4 cm deep (no face against the wall).
    mx0, mx1, my0, my1, f = 2.6, 3.9, 1.1, 2.0, 0.06
    zw, zf = D - 0.04, D
    keep_wall = ("side2",)  # the z = hi face lies on the wall
    p.add(
        "frame",
        shapes.aabox((mx0 - f, my0 - f, zw), (mx1 + f, my0, zf), omit=keep_wall),
        shapes.aabox((mx0 - f, my1, zw), (mx1 + f, my1 + f, zf), omit=keep_wall),
        shapes.aabox((mx0 - f, my0, zw), (mx0, my1, zf), omit=keep_wall),
        shapes.aabox((mx1, my0, zw), (mx1 + f, my1, zf), omit=keep_wall),
    )
    p.add("mirror", shapes.quad((mx0, my0, D - 0.015), (0, my1 - my0, 0), (mx1 - mx0, 0, 0)))

    # Glass on the table: a sphere resting on it and a vase 1 mm above it (so that its
    # bottom is not coplanar with the table top).
    r = 0.11
    glass = [shapes.uv_sphere((2.6, top_y1 + r, 3.85), r, gs, gr)]
    prof_r = [0.0, 0.05, 0.062, 0.075, 0.066, 0.042, 0.034, 0.04, 0.034, 0.028, 0.036,
              0.06, 0.045, 0.0]
    prof_h = [0.0, 0.0, 0.03, 0.10, 0.17, 0.22, 0.26, 0.29, 0.295, 0.26, 0.22, 0.10,
              0.02, 0.015]
    glass.append(shapes.lathe(prof_r, prof_h, vase_seg, center=(3.2, top_y1 + 0.001, 4.0)))
    p.add("glass", *glass)
    return p.geometry()


BUILDERS: dict[str, Callable[..., Geometry]] = {"ring": ring, "room": room, "cornell": cornell}
