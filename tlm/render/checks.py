"""Checks for mistakes that give no error: lights that reach nothing, a camera inside a
solid or facing nothing, a black image, a photon map that stores almost nothing.

Each check returns warnings, one line each naming the thing (``lights[1] (quad)``, ...);
:func:`tlm.experiments.run.results_dict` puts them in ``results.json`` ``warnings`` and
``tlm run`` prints them on stderr. Everything here is deterministic (fixed probe
patterns, no random numbers), so the warnings of a run repeat exactly.

* :func:`light_warnings`: every light with power is probed with :data:`PROBE_RAYS` rays
  spread over the side it emits on (a point light: the sphere; a quad light: the
  hemisphere of ``cross(edge_u, edge_v)`` from points spread over the quad; a mesh light:
  the front hemisphere of ``cross(V1 - V0, V2 - V0)`` of its triangles, picked in
  proportion to their area), and with as many aimed at the centres of triangles spread
  over the scene's list (those on that side), through the scene's BSP
  (:func:`tlm.kernels.traverse.closest_hit`). The aimed rays find what the spread ones
  miss: an object that fills a small part of the light's sphere (a lone model under a
  point light; a scene far from its light). A light none of whose rays hits a surface (a
  mesh light's own triangles do not count) reaches nothing; a light all of whose rays
  that hit, hit the back of an opaque (Lambertian or mirror) triangle lights only back
  faces: it sits inside a closed solid, outside a room whose walls face in, or the
  geometry around it is wound inside out. Glass does not count: a lamp in a glass globe
  is lit through it. The rays start :data:`PROBE_EPS` times the light's size from it (a
  point light: where its position's precision allows), so that a light close to a large
  surface still finds it.
* :func:`camera_warnings`: no eye ray hit anything, or more than
  :data:`BACK_FACE_LIMIT` of the eye rays' hits are on the back of an opaque triangle
  (the camera is inside a closed solid: a room's walls, wound to face in, are seen from
  the front).
* :func:`image_warnings`: every pixel of the composite is 0, or under
  :data:`BLACK_LIMIT` of the radiance the lights give at the scene's size
  (:func:`light_scale`: light that only grazes, as from a quad light facing away from a
  ceiling it lies in).
* :func:`file_warnings`: what the mesh files hold that tlm does not use (a glTF's spot and
  directional lights, its orthographic cameras, ...), and which of a glTF's point lights and
  camera the scene imported or left for the scene file's ``lights:`` and ``camera:``, a line each.
* :func:`material_warnings`: materials the image shows whose mesh file gives them what
  tlm does not render (texture and bump maps, alpha, unknown glTF extensions:
  :attr:`~tlm.scenes.model.Material.ignored`), in one line.
* :func:`photon_warnings`: fewer than :data:`STORED_LIMIT` of the emitted photons were
  stored.
"""

from __future__ import annotations

import math

import numpy as np

from tlm.kernels.traverse import TriangleAccel, closest_hit
from tlm.scenes.model import KIND, Light, Scene

PROBE_RAYS = 256  # rays per light
BACK_FACE_LIMIT = 0.5  # share of the eye rays' hits on back faces above which the camera is inside
STORED_LIMIT = 0.01  # share of the emitted photons below which the photon map is nearly empty
BLACK_LIMIT = 1e-12  # brightest pixel, relative to light_scale, below which the image is black
PROBE_EPS = 1e-5  # probe rays start this far (relative to the light's size) from the light
GRAZING = 1e-6  # cosine to a light's normal under which an aimed probe ray counts as in its plane
_PRECISION = 1e-12  # ... and at least this far relative to the largest coordinate they start from
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def light_name(i: int, light: Light) -> str:
    """``lights[i] (kind 'name')``: how a warning names a light."""
    name = getattr(light, "name", "") or ""
    return f"lights[{i}] ({light.kind}{f' {name!r}' if name else ''})"


def _fibonacci(n: int, hemisphere: bool) -> np.ndarray:
    """(n, 3) unit directions spread evenly over the sphere, or the hemisphere z > 0."""
    i = np.arange(n, dtype=np.float64) + 0.5
    z = 1.0 - i / n if hemisphere else 1.0 - 2.0 * i / n
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * math.pi * ((i * _GOLDEN) % 1.0)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _around(normals: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Local directions (z up) turned about unit ``normals`` (k, 3)."""
    n = normals
    a = np.where((np.abs(n[:, 0]) < 0.9)[:, None], [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = np.cross(a, n)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(n, t)
    return local[:, :1] * t + local[:, 1:2] * b + local[:, 2:3] * n


def _spread(n: int) -> tuple[np.ndarray, np.ndarray]:
    """(n,) x 2 points of the unit square, a rank-1 lattice (even, and not aligned with the
    directions' own pattern)."""
    i = np.arange(n, dtype=np.float64)
    return (i + 0.5) / n, (i * 0.7548776662466927 + 0.5) % 1.0


def probe_rays(light: Light, n: int = PROBE_RAYS
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Origins, unit directions (n, 3), the triangle each ray leaves (-1: none) and the unit
    normal of the side each origin emits on (None for a point light) of a light's spread
    probe."""
    none = np.full(n, -1, dtype=np.int64)
    empty = (np.zeros((0, 3)), np.zeros((0, 3)), none[:0], None)
    if light.kind == "point":
        o = np.broadcast_to(np.asarray(light.position, dtype=np.float64), (n, 3)).copy()
        return o, _fibonacci(n, hemisphere=False), none, None
    u, v = _spread(n)
    if light.kind == "quad":
        o = (np.asarray(light.corner, dtype=np.float64) + u[:, None] * np.asarray(light.edge_u, dtype=np.float64)
             + v[:, None] * np.asarray(light.edge_v, dtype=np.float64))
        normal = np.broadcast_to(light.normal, (n, 3))
        return o, _around(normal, _fibonacci(n, hemisphere=True)), none, normal
    if light.kind == "mesh" and getattr(light, "triangles", None) is not None and len(light.triangles):
        tri = np.asarray(light.triangles, dtype=np.float64)
        e = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area = np.linalg.norm(e, axis=1)
        keep = np.flatnonzero(area > 0)
        if keep.shape[0] == 0:
            return empty
        cum = np.cumsum(area[keep])
        j = keep[np.minimum(np.searchsorted(cum, (np.arange(n) + 0.5) / n * cum[-1]), keep.shape[0] - 1)]
        su = np.sqrt(u)
        b0, b1 = 1.0 - su, v * su
        t = tri[j]
        o = b0[:, None] * t[:, 0] + b1[:, None] * t[:, 1] + (1.0 - b0 - b1)[:, None] * t[:, 2]
        normal = e[j] / area[j, None]
        ids = getattr(light, "ids", None)
        src = np.asarray(ids, dtype=np.int64)[j] if ids is not None else none
        return o, _around(normal, _fibonacci(n, hemisphere=True)), src, normal
    return empty


def aimed_rays(scene: Scene, light: Light, n: int = PROBE_RAYS, spread=None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Origins, unit directions and left triangles (as :func:`probe_rays`) of rays from the
    light's probe origins to the centres of up to ``n`` triangles spread evenly over the
    scene's list: those in front of the side the origin emits on (a cosine above
    :data:`GRAZING`), and not the light's own. ``spread``: the light's :func:`probe_rays`,
    when the caller has them."""
    o, _, src, normal = probe_rays(light, n) if spread is None else spread
    tri = scene.triangles
    m = min(n, tri.shape[0])
    if o.shape[0] == 0 or m == 0:
        return np.zeros((0, 3)), np.zeros((0, 3)), src[:0]
    pick = np.unique(np.linspace(0.0, tri.shape[0] - 1, m).round().astype(np.int64))
    k = np.arange(pick.shape[0]) % o.shape[0]
    d = tri[pick].mean(axis=1) - o[k]
    length = np.linalg.norm(d, axis=1)
    keep = length > 0.0
    if normal is not None:  # (in front, not grazing: a centre in the light's own plane is not lit)
        keep &= (d * normal[k]).sum(axis=1) > GRAZING * length
    own = getattr(light, "ids", None)
    if own is not None:
        keep &= ~np.isin(pick, np.asarray(own, dtype=np.int64))
    return o[k][keep], d[keep] / length[keep, None], src[k][keep]


def light_size(light: Light) -> float:
    """A light's length scale: the square root of its area (0 for a point light)."""
    if light.kind == "point" or (light.kind == "mesh" and getattr(light, "triangles", None) is None):
        return 0.0
    return float(np.sqrt(max(light.area, 0.0)))


def probe_light(scene: Scene, accel: TriangleAccel, light: Light, n: int = PROBE_RAYS,
                kind: np.ndarray | None = None) -> dict:
    """``rays`` traced from the light (:func:`probe_rays` and :func:`aimed_rays`), how many
    ``hits`` found a surface (not the light's own triangles) and how many of those hit the
    ``back`` of an opaque triangle (``kind``: each triangle's material KIND, default the
    scene's)."""
    spread = probe_rays(light, n)
    aimed = aimed_rays(scene, light, n, spread)
    o, d, src = (np.concatenate([spread[i], aimed[i]]) for i in range(3))
    if o.shape[0] == 0:
        return {"rays": 0, "hits": 0, "back": 0}
    eps = max(PROBE_EPS * light_size(light), _PRECISION * float(np.abs(o).max()), np.finfo(float).tiny)
    h = closest_hit(accel, o, d, tmin=eps, ignore=src)
    tri = h.triangle
    hit = tri >= 0
    own = getattr(light, "ids", None)
    if light.kind == "mesh" and own is not None:
        hit &= ~np.isin(tri, np.asarray(own, dtype=np.int64))
    back = back_faces(scene, np.where(hit, tri, -1), d, kind)
    return {"rays": int(o.shape[0]), "hits": int(hit.sum()), "back": back}


def light_warnings(scene: Scene, accel: TriangleAccel, n: int = PROBE_RAYS) -> list[str]:
    """One line per light with power that reaches no surface or lights only back faces."""
    out = []
    kind = scene.material_table()["kind"] if scene.lights else None
    for i, light in enumerate(scene.lights):
        if not any(p > 0.0 for p in light.power):
            continue  # a light switched off: the black image says so
        p = probe_light(scene, accel, light, n, kind)
        if p["rays"] == 0:
            continue
        where = {"point": "in every direction", "quad": "over the side of cross(edge_u, edge_v)",
                 "mesh": "over the front of its triangles (cross(V1 - V0, V2 - V0))"}.get(light.kind, "")
        if p["hits"] == 0:
            hint = (" (does cross(edge_u, edge_v) face away from the scene?)" if light.kind == "quad" else
                    " (are its triangles wound to face away from the scene?)" if light.kind == "mesh" else
                    " (is it outside the scene?)")
            out.append(f"{light_name(i, light)} reaches no surface: none of its {p['rays']} probe rays (spread "
                       f"{where}, and aimed at the scene's triangles on that side) hits the scene{hint}")
        elif p["back"] == p["hits"]:
            out.append(f"{light_name(i, light)} lights only back faces: all {p['hits']} of its {p['rays']} probe "
                       "rays that hit the scene hit the back of an opaque triangle (is it inside a closed mesh, "
                       "outside a room whose walls face in, or is the geometry wound inside out?)")
    return out


def file_warnings(scene: Scene) -> list[str]:
    """What the scene's mesh files hold that tlm does not use (``Geometry.notes``: a glTF's
    spot and directional lights, its orthographic cameras, ...) and what of a glTF's point
    lights and camera the scene imported or did not use (:func:`tlm.scenes.loader.load_scene`),
    one line each naming the file."""
    return [str(n) for n in scene.extra.get("notes") or []]


def material_warnings(scene: Scene, shown: int = 3) -> list[str]:
    """One line naming the materials on the scene's triangles whose mesh file gives them
    what tlm does not render (:attr:`~tlm.scenes.model.Material.ignored`: the first
    ``shown`` by name) and what that is."""
    used = [scene.materials[i] for i in np.unique(scene.material_index)]
    hit = [m for m in used if m.ignored]
    if not hit:
        return []
    what = ", ".join(dict.fromkeys(k for m in hit for k in m.ignored))
    names = ", ".join(repr(m.name) for m in hit[:shown]) + (f" and {len(hit) - shown} more" if len(hit) > shown else "")
    many = len(hit) > 1
    return [f"{len(hit)} material{'s' if many else ''} of the mesh file{'s' if many else ''} ({names}) "
            f"{'use' if many else 'uses'} what tlm does not render: {what}; "
            f"{'each renders' if many else 'it renders'} with its constant colour (a scene file's "
            "materials: entry of the same name replaces it)"]


def back_faces(scene: Scene, triangle: np.ndarray, direction: np.ndarray, kind: np.ndarray | None = None) -> int:
    """How many of the rays of ``direction`` (k, 3) that hit ``triangle`` (k,; -1 on a miss)
    hit the back (the side away from ``cross(V1 - V0, V2 - V0)``) of an opaque triangle
    (not glass; ``kind``: each triangle's material KIND, default the scene's)."""
    kind = scene.material_table()["kind"] if kind is None else kind
    hit = np.flatnonzero(triangle >= 0)
    hit = hit[kind[triangle[hit]] != KIND["dielectric"]]
    t = scene.triangles[triangle[hit]]
    normal = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    return int(((normal * direction[hit]).sum(axis=1) > 0.0).sum())


def camera_warnings(rays: int, hits: int, back: int) -> list[str]:
    """The camera faces nothing (no eye ray hit) or sits inside a closed solid (most hits on back faces)."""
    if rays > 0 and hits == 0:
        return [f"the camera faces nothing: none of its {rays} eye rays hits the scene"]
    if hits > 0 and back > BACK_FACE_LIMIT * hits:
        return [f"the camera may be inside a closed mesh: {back} of the {hits} eye-ray hits "
                f"({100.0 * back / hits:.0f}%) are on the back of an opaque triangle"]
    return []


def light_scale(scene: Scene, diagonal: float) -> float:
    """A radiance the scene's lights give: the brightest light's power (its largest channel)
    over ``pi diagonal**2`` (W/m^2/sr; about the radiance of a white wall at the scene's size,
    in the scene's units whatever they are)."""
    power = max((max(lt.power) for lt in scene.lights), default=0.0)
    return power / (math.pi * diagonal * diagonal) if diagonal > 0 else 0.0


def image_warnings(radiance: dict[str, np.ndarray], scale: float = 0.0) -> list[str]:
    """The composite (the sum of the passes) is black: every pixel 0, or its brightest pixel
    under :data:`BLACK_LIMIT` of ``scale`` (:func:`light_scale`; light that only grazes)."""
    if not radiance:
        return []
    top = float(np.max(sum(radiance.values()), initial=0.0))
    if top == 0.0:
        return ["the image is black: every pixel of the composite is 0 (no light reaches what the camera sees)"]
    if top < BLACK_LIMIT * scale:
        return [f"the image is black: its brightest pixel ({top:.3g}) is under {BLACK_LIMIT:g} of the lights' "
                f"radiance scale ({scale:.3g}: the brightest light's power / (pi diagonal^2))"]
    return []


def photon_warnings(emitted: int, stored: int) -> list[str]:
    """Fewer than :data:`STORED_LIMIT` of the emitted photons were stored."""
    if emitted > 0 and stored < STORED_LIMIT * emitted:
        return [f"the photon map stored {stored} of {emitted} emitted photons ({100.0 * stored / emitted:.2g}%, "
                f"under {100 * STORED_LIMIT:g}%): its lights reach few surfaces after a bounce"]
    return []
