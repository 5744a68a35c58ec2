"""Checks for mistakes that give no error: lights that reach nothing, a camera inside a
solid or facing nothing, a black image, a photon map that stores almost nothing.

Each check returns warnings, one line each naming the thing (``lights[1] (quad)``, ...);
:func:`tlm.experiments.run.results_dict` puts them in ``results.json`` ``warnings`` and
``tlm run`` prints them on stderr. Everything here is deterministic (fixed probe
patterns, no random numbers), so the warnings of a run repeat exactly.

* :func:`light_warnings`: a scene with no light at all is said, with how to give one
  (:data:`NO_LIGHTS`); a light of zero power among lights with power is named (its shadow rays
  are cast and charged to the timing model, and add nothing: :func:`zero_power_warnings`); every
  light with power is probed with :data:`PROBE_RAYS` rays
  spread over the side it emits on (a point light: the sphere; a spot: its outer cone; a
  directional light: parallel rays along its direction from the disc covering the scene's
  bounding sphere; a quad light: the
  hemisphere of ``cross(edge_u, edge_v)`` from points spread over the quad; a mesh light:
  the front hemisphere of ``cross(V1 - V0, V2 - V0)`` of its triangles, picked in
  proportion to their area), and with as many aimed at the centres of triangles spread
  over the scene's list (those on that side; a spot's: those in its outer cone; a
  directional light's: along its direction, from outside the scene), through the scene's BSP
  (:func:`tlm.kernels.traverse.closest_hit`). The aimed rays find what the spread ones
  miss: an object that fills a small part of the light's sphere (a lone model under a
  point light; a scene far from its light). A light none of whose rays hits a surface (a
  mesh light's own triangles do not count) reaches nothing; a light all of whose rays
  that hit, hit the back of an opaque (Lambertian or mirror) triangle lights only back
  faces: it sits inside a closed solid, outside a room whose walls face in, or the
  geometry around it is wound inside out. Glass does not count: a lamp in a glass globe
  is lit through it. The rays start :data:`PROBE_EPS` times the light's size from it (a
  point light: a few ulps of its position), so that a light close to a large surface
  still finds it, and never more than :data:`PROBE_EPS` times the scene's diagonal from
  it (:func:`probe_eps`). A quad or mesh light with hits, not all on back faces, is probed once
  more (:func:`blocked_share`): over :data:`BLOCKED_LIMIT` of its power (its spread rays weighted
  by their cosine) stopping on an opaque surface within :func:`near_distance` of it (:data:`NEAR_LIMIT`
  of the scene's diagonal, and :data:`NEAR_SIZE` of the light's size) is a light wound to face the
  surface it lies against (a ceiling light facing the ceiling).
* :func:`camera_warnings`: no eye ray hit anything, or more than
  :data:`BACK_FACE_LIMIT` of the eye rays' hits are on the back of an opaque triangle
  (the camera is inside a closed solid: a room's walls, wound to face in, are seen from
  the front).
* :func:`image_warnings`: every pixel of the composite is 0, or under
  :data:`BLACK_LIMIT` of the radiance the lights give at the scene's size
  (:func:`light_scale`: light that only grazes, as from a quad light facing away from a
  ceiling it lies in).
* :func:`file_warnings`: what the mesh files hold that tlm does not use (a glTF's lights on
  no node of its scene, its orthographic cameras, ...), and which of a glTF's lights and
  camera the scene imported or left for the scene file's ``lights:`` and ``camera:``, a line each.
* :func:`material_warnings`: materials the image shows whose mesh file gives them what
  tlm does not render (texture and bump maps, alpha, unknown glTF extensions:
  :attr:`~tlm.scenes.model.Material.ignored`), in one line.
* :func:`photon_warnings`: fewer than :data:`STORED_LIMIT` of the emitted photons were
  stored.
* :func:`scene_warnings` (with :func:`file_warnings`): the scene lies so far from the
  origin for its size that float64 rounds its positions to over :data:`COARSE_LIMIT` of
  its extent; a material emits only on triangles of zero area; a closed glass body faces
  inwards, not a cavity (:func:`glass_warnings`; open glass, a water surface, is not judged).
* :func:`branching_warning`: ``render.min_weight`` 0 lets a mirror and glass walk spawn
  more than :data:`BRANCH_LIMIT` rays an eye ray (for the run to say before it renders).
* :func:`radius_warnings`: a search radius given in scene units over the scene's diagonal.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from tlm.config_words import listing
from tlm.errors import quoted
from tlm.kernels.shade import SPAWN_EPS
from tlm.kernels.traverse import TriangleAccel, closest_hit
from tlm.scenes.model import DISC_MARGIN, KIND, Light, Scene, bounding_sphere

PROBE_RAYS = 256  # rays per light
BACK_FACE_LIMIT = 0.5  # share of the eye rays' hits on back faces above which the camera is inside
STORED_LIMIT = 0.01  # share of the emitted photons below which the photon map is nearly empty
BLACK_LIMIT = 1e-12  # brightest pixel, relative to light_scale, below which the image is black
PROBE_EPS = 1e-5  # probe rays start this far (relative to the light's size) from the light
NEAR_LIMIT = 0.02  # share of the scene's diagonal within which a surface stops a light's power right away
NEAR_SIZE = 0.5  # ... and share of the light's size (a room's ceiling light over a wide ground: its floor is not near)
BLOCKED_LIMIT = 0.5  # share of a light's power stopped so (blocked_share) over which the run warns
GRAZING = 1e-6  # cosine to a light's normal under which an aimed probe ray counts as in its plane
COARSE_LIMIT = SPAWN_EPS / 10  # float64's spacing at the scene's coordinates, relative to its extent, above
# which its positions are rounded coarsely (moved by translate [t, t, t], 32x32, 16 samples a pixel, 4 a light:
# 10% of cornell-box's pixels change by over 1% at 1.1e-6 and 2% at 5.5e-7, its shadow rays stopping on its
# mesh light's own triangles at grazing angles; 2.5% of cornell's at 1.3e-4, 27% at 2.1e-3)
PROBE_ULPS = 16  # ... a point light's: this many float64 ulps of the largest coordinate they start from;
# either way never more than PROBE_EPS x the scene's diagonal (rays that start past a far scene skip it)
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
GLASS_VOLUME_LIMIT = 1e-6  # a glass body's signed volume / the sum of its tetrahedra's under minus which it faces in


def light_name(i: int, light: Light) -> str:
    """``lights[i] (kind 'name')``: how a warning names a light."""
    name = getattr(light, "name", "") or ""
    return f"lights[{i}] ({light.kind}{f' {quoted(name)}' if name else ''})"


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


def _cap(n: int, cos_max: float) -> np.ndarray:
    """(n, 3) unit directions spread evenly over the cap z >= ``cos_max`` of the sphere."""
    i = np.arange(n, dtype=np.float64) + 0.5
    z = 1.0 - i / n * (1.0 - cos_max)
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * math.pi * ((i * _GOLDEN) % 1.0)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _far(light: Light, box: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, float]:
    """A directional light's unit direction and how far back along it its probe rays start
    (past the sphere around ``box``)."""
    _, radius = bounding_sphere(*box)
    return light.axis, 2.0 * radius


def probe_rays(light: Light, n: int = PROBE_RAYS, box: tuple[np.ndarray, np.ndarray] | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Origins, unit directions (n, 3), the triangle each ray leaves (-1: none) and the unit
    normal of the side each origin emits on (None for a point, spot or directional light) of a
    light's spread probe. A spot's directions spread over its outer cone; a directional light's
    rays (``box``: the scene's triangles' box, which it needs) start on the disc that covers the
    box's bounding sphere (as its photons do) and travel along its direction."""
    none = np.full(n, -1, dtype=np.int64)
    empty = (np.zeros((0, 3)), np.zeros((0, 3)), none[:0], None)
    if light.kind in ("point", "spot"):
        o = np.broadcast_to(np.asarray(light.position, dtype=np.float64), (n, 3)).copy()
        if light.kind == "spot":
            return o, _around(np.broadcast_to(light.axis, (n, 3)), _cap(n, light.cone_cosines[1])), none, None
        return o, _fibonacci(n, hemisphere=False), none, None
    u, v = _spread(n)
    if light.kind == "directional":
        if box is None:
            return empty
        w = light.axis
        centre, radius = bounding_sphere(*box)
        a = np.where(abs(w[0]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        t = np.cross(a, w)
        t /= np.linalg.norm(t)
        b = np.cross(w, t)
        rr, phi = radius * np.sqrt(u), 2.0 * math.pi * v
        o = (centre - w * radius * (1.0 + DISC_MARGIN) + (rr * np.cos(phi))[:, None] * t
             + (rr * np.sin(phi))[:, None] * b)
        return o, np.broadcast_to(w, (n, 3)).copy(), none, None
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
    o, _, src, normal = probe_rays(light, n, scene.bounds()) if spread is None else spread
    tri = scene.triangles
    m = min(n, tri.shape[0])
    if o.shape[0] == 0 or m == 0:
        return np.zeros((0, 3)), np.zeros((0, 3)), src[:0]
    pick = np.unique(np.linspace(0.0, tri.shape[0] - 1, m).round().astype(np.int64))
    k = np.arange(pick.shape[0]) % o.shape[0]
    if light.kind == "directional":  # towards each centre along the light's direction, from outside the scene
        w, back = _far(light, scene.bounds())
        start = tri[pick].mean(axis=1) - back * w
        return start, np.broadcast_to(w, start.shape).copy(), src[k]
    d = tri[pick].mean(axis=1) - o[k]
    length = np.linalg.norm(d, axis=1)
    keep = length > 0.0
    if light.kind == "spot":  # (the centres in its outer cone)
        keep &= (d @ light.axis) > light.cone_cosines[1] * length
    if normal is not None:  # (in front, not grazing: a centre in the light's own plane is not lit)
        keep &= (d * normal[k]).sum(axis=1) > GRAZING * length
    own = getattr(light, "ids", None)
    if own is not None:
        keep &= ~np.isin(pick, np.asarray(own, dtype=np.int64))
    return o[k][keep], d[keep] / length[keep, None], src[k][keep]


def light_size(light: Light) -> float:
    """A light's length scale: the square root of its area (0 for a point light)."""
    if light.kind in ("point", "spot", "directional") or (light.kind == "mesh"
                                                          and getattr(light, "triangles", None) is None):
        return 0.0
    return float(np.sqrt(max(light.area, 0.0)))


def probe_eps(light: Light, accel: TriangleAccel, origins: np.ndarray) -> float:
    """How far from the light its probe rays (from ``origins``) start: :data:`PROBE_EPS` x
    the light's size (a point light: :data:`PROBE_ULPS` float64 ulps of the largest
    coordinate, so that a light on a surface skips it), and never more than
    :data:`PROBE_EPS` x the scene's diagonal (``accel.scale``), so that the rays of a scene
    far from the origin (a box 1 unit wide at x = 1e12, where an ulp is 1.2e-4) do not
    start past its walls."""
    size = light_size(light)
    if size > 0.0:
        eps = PROBE_EPS * size
    else:
        eps = PROBE_ULPS * float(np.finfo(float).eps) * float(np.abs(origins).max(initial=0.0))
    if accel.scale > 0.0:
        eps = min(eps, PROBE_EPS * accel.scale)
    return max(eps, float(np.finfo(float).tiny))


def probe_light(scene: Scene, accel: TriangleAccel, light: Light, n: int = PROBE_RAYS,
                kind: np.ndarray | None = None) -> dict:
    """``rays`` traced from the light (:func:`probe_rays` and :func:`aimed_rays`), how many
    ``hits`` found a surface (not the light's own triangles) and how many of those hit the
    ``back`` of an opaque triangle (``kind``: each triangle's material KIND, default the
    scene's)."""
    spread = probe_rays(light, n, scene.bounds())
    aimed = aimed_rays(scene, light, n, spread)
    o, d, src = (np.concatenate([spread[i], aimed[i]]) for i in range(3))
    if o.shape[0] == 0:
        return {"rays": 0, "hits": 0, "back": 0}
    h = closest_hit(accel, o, d, tmin=probe_eps(light, accel, o), ignore=src)
    tri = h.triangle
    hit = tri >= 0
    own = getattr(light, "ids", None)
    if light.kind == "mesh" and own is not None:
        hit &= ~np.isin(tri, np.asarray(own, dtype=np.int64))
    back = back_faces(scene, np.where(hit, tri, -1), d, kind)
    return {"rays": int(o.shape[0]), "hits": int(hit.sum()), "back": back}


def zero_power_warnings(scene: Scene) -> list[str]:
    """One line per light of zero power beside a light with power (every light off: the black
    image and the plan say so): it adds nothing to the picture, but its shadow rays are cast and
    charged to the timing model, as the hardware would cast them (the model keeps them)."""
    off = [i for i, lt in enumerate(scene.lights) if not any(p > 0.0 for p in lt.power)]
    if len(off) == len(scene.lights):
        return []
    return [f"{light_name(i, scene.lights[i])} has zero power: its shadow rays (one per Lambertian point facing it"
            f"{'' if scene.lights[i].kind in ('point', 'spot', 'directional') else ', per render.light_samples'}, "
            "each frame) are charged to the timing model and add nothing to the picture (leave the light out, or "
            "give it power)" for i in off]


NO_LIGHTS = ("the scene has no lights: nothing emits (no lights: in the scene file, no material with emission: an "
             "MTL's Ke, a glTF's emissive; no glTF light), so every frame is black: give it lights: (a quad light "
             "under the ceiling: docs/scenes.md, Lights) or a material emission: [r, g, b] under materials:")


def light_warnings(scene: Scene, accel: TriangleAccel, n: int = PROBE_RAYS) -> list[str]:
    """One line per light with power that reaches no surface or lights only back faces, and per
    light of zero power among lights with power (:func:`zero_power_warnings`); a scene with no
    light at all (a published mesh with no emitter, as McGuire's conference room) is
    :data:`NO_LIGHTS`, which says how to add one."""
    if not scene.lights:
        return [NO_LIGHTS]
    out = zero_power_warnings(scene)
    kind = scene.material_table()["kind"]
    for i, light in enumerate(scene.lights):
        if not any(p > 0.0 for p in light.power):
            continue  # a light switched off: zero_power_warnings, or (all off) the black image, says so
        p = probe_light(scene, accel, light, n, kind)
        if p["rays"] == 0:
            continue
        where = {"point": "in every direction", "quad": "over the side of cross(edge_u, edge_v)",
                 "mesh": "over the front of its triangles (cross(V1 - V0, V2 - V0))",
                 "spot": "over its outer cone", "directional": "along its direction over the scene's width"
                 }.get(light.kind, "")
        if p["hits"] == 0:
            hint = (" (does cross(edge_u, edge_v) face away from the scene?)" if light.kind == "quad" else
                    " (are its triangles wound to face away from the scene?)" if light.kind == "mesh" else
                    " (does its direction point away from the scene?)" if light.kind == "spot" else
                    " (is it outside the scene?)")
            out.append(f"{light_name(i, light)} reaches no surface: none of its {p['rays']} probe rays (spread "
                       f"{where}, and aimed at the scene's triangles on that side) hits the scene{hint}")
        elif p["back"] == p["hits"]:
            out.append(f"{light_name(i, light)} lights only back faces: all {p['hits']} of its {p['rays']} probe "
                       "rays that hit the scene hit the back of an opaque triangle (is it inside a closed mesh, "
                       "outside a room whose walls face in, or is the geometry wound inside out?)")
        else:
            out += blocked_warnings(i, light, *blocked_share(scene, accel, light, n, kind),
                                    near=near_distance(light, accel))
    return out


def blocked_share(scene: Scene, accel: TriangleAccel, light: Light, n: int = PROBE_RAYS,
                  kind: np.ndarray | None = None) -> tuple[float, float, int]:
    """``(share, distance, rays)``: the share of a quad or mesh light's power (its :func:`probe_rays`
    over the side it emits on, each weighted by its cosine to the light's normal, as the power it
    carries) that hits an opaque surface (not glass, not the light's own triangles) within
    :func:`near_distance` of it, the cosine-weighted mean distance of those hits, and the rays traced;
    ``(0, 0, 0)`` for a point, spot or directional light (no face). Near is the smaller of
    :data:`NEAR_LIMIT` of the scene's diagonal and :data:`NEAR_SIZE` of the light's size: a ceiling
    light 2 m over the floor of a room on a ground 1 km wide (0.02 of its diagonal: 28 m) does not stop
    its power on the floor."""
    o, d, src, normal = probe_rays(light, n, scene.bounds())
    near = near_distance(light, accel)
    if normal is None or o.shape[0] == 0 or not near > 0.0:
        return 0.0, 0.0, 0
    h = closest_hit(accel, o, d, tmin=probe_eps(light, accel, o), tmax=near, ignore=src)
    tri = h.triangle
    hit = tri >= 0
    own = getattr(light, "ids", None)
    if light.kind == "mesh" and own is not None:
        hit &= ~np.isin(tri, np.asarray(own, dtype=np.int64))
    kind = scene.material_table()["kind"] if kind is None else kind
    hit[hit] &= kind[tri[hit]] != KIND["dielectric"]
    cos = np.maximum((d * normal).sum(axis=1), 0.0)
    total = float(cos.sum())
    if not total > 0.0 or not hit.any():
        return 0.0, 0.0, int(o.shape[0])
    blocked = float(cos[hit].sum())
    return blocked / total, float((cos[hit] * h.t[hit]).sum() / blocked), int(o.shape[0])


def near_distance(light: Light, accel: TriangleAccel) -> float:
    """How far from a quad or mesh light a surface is one it lies against (:func:`blocked_share`): the
    smaller of :data:`NEAR_LIMIT` x the scene's diagonal (``accel.scale``) and :data:`NEAR_SIZE` x the
    light's size (:func:`light_size`); 0 where either is not positive."""
    if not accel.scale > 0.0:
        return 0.0
    return min(NEAR_LIMIT * accel.scale, NEAR_SIZE * light_size(light))


def blocked_warnings(i: int, light: Light, share: float, distance: float, rays: int, near: float) -> list[str]:
    """A line when over :data:`BLOCKED_LIMIT` of a light's power is stopped by a surface right in
    front of it (:func:`blocked_share`, within ``near``: :func:`near_distance`): a ceiling light whose face
    is wound to face the ceiling it hangs under (McGuire's ``CornellBox-Original`` with its light's face
    reversed, pmap at 32x32 and 5,000 photons: the composite's mean radiance 0.113 -> 0.021, its black
    pixels 2.4% -> 45%)."""
    if not share > BLOCKED_LIMIT:
        return []
    flip = ("swap edge_u and edge_v (cross(edge_u, edge_v) is the side it emits on)" if light.kind == "quad" else
            "reverse the order of its faces' corners (cross(V1 - V0, V2 - V0) is the side it emits on)")
    return [f"{light_name(i, light)} sends {100.0 * share:.0f}% of its power into a surface within {near:.3g} "
            f"of it (the smaller of {NEAR_LIMIT:g} of the scene's diagonal and {NEAR_SIZE:g} of its size; at "
            f"{distance:.3g} on average; {rays} probe rays over the side it emits on, weighted by their cosine): "
            f"it faces the surface it lies against (is its face wound the wrong way? {flip}; if it is aimed at that "
            "surface on purpose, as a lamp lighting a room off a wall, nothing is wrong: the scene is lit by the "
            "light that surface reflects, and this line can be ignored)"]


def file_warnings(scene: Scene) -> list[str]:
    """What the scene's mesh files hold that tlm does not use (``Geometry.notes``: a glTF's
    lights on no node of its scene, its orthographic cameras, ...) and what of a glTF's
    lights and camera the scene imported or did not use (:func:`tlm.scenes.loader.load_scene`),
    one line each naming the file, one mistake an MTL repeats over its materials folded into one line
    (:func:`~tlm.scenes.materials.fold_mtl_notes`: each stays in the scene's notes, which ``tlm scene
    show`` lists); then what the scene's files ask for that renders coarsely or not at all
    (:func:`scene_warnings`)."""
    return note_warnings(scene) + scene_warnings(scene)


def note_warnings(scene: Scene) -> list[str]:
    """The lines :func:`file_warnings` begins with: the scene's notes (``scene.extra["notes"]``),
    folded (:func:`~tlm.scenes.materials.fold_mtl_notes`)."""
    from tlm.scenes.materials import fold_mtl_notes

    return fold_mtl_notes([str(n) for n in scene.extra.get("notes") or []])


def scene_warnings(scene: Scene) -> list[str]:
    """One line each: the scene lies so far from the origin for its size that float64
    rounds its positions coarsely (:func:`coordinate_warnings`), a material whose
    emission lies only on triangles of zero area (:func:`emission_warnings`), and a closed
    glass part that faces inwards (:func:`glass_warnings`)."""
    return coordinate_warnings(scene) + emission_warnings(scene) + glass_warnings(scene)


def coordinate_spacing(scene: Scene) -> tuple[float, float, float]:
    """``(largest, spacing, extent)``: the largest coordinate magnitude of the triangles, the
    camera's eye and the quad, point and spot lights, float64's spacing there (``np.spacing``) and
    the diagonal of the triangles' box."""
    lo, hi = scene.bounds()
    pts = [lo, hi, np.asarray(scene.camera.eye, dtype=np.float64)]
    pts += [np.asarray(lt.corner if lt.kind == "quad" else lt.position, dtype=np.float64)
            for lt in scene.lights if lt.kind in ("point", "quad", "spot")]
    largest = float(np.abs(np.array(pts)).max())
    return largest, float(np.spacing(largest)), float(np.linalg.norm(hi - lo))


def coordinate_warnings(scene: Scene) -> list[str]:
    """A line when float64's spacing at the scene's largest coordinate is over
    :data:`COARSE_LIMIT` of its extent (:func:`coordinate_spacing`): its points are rounded
    to within a tenth of the distance rays skip from the surface they leave and stop short
    of a light (:data:`~tlm.kernels.shade.SPAWN_EPS` of the diagonal), so that a shadow
    ray may stop on the surface it leaves or the light it aims at, and edges move."""
    largest, spacing, extent = coordinate_spacing(scene)
    if not (extent > 0.0 and spacing > COARSE_LIMIT * extent):
        return []
    return [f"the scene lies far from the origin for its size: float64 positions at its largest coordinate "
            f"({largest:.3g}) are {spacing:.3g} apart, {spacing / extent:.2g} of its extent ({extent:.3g}, the "
            f"diagonal of its triangles' box), over {COARSE_LIMIT:g} (a tenth of the {SPAWN_EPS:g} of the "
            "diagonal that rays skip from the surface they leave and stop short of a light): shadows and edges "
            "may change, grazing light first (bring it nearer the origin: transform: {translate})"]


def emission_warnings(scene: Scene, shown: int = 3) -> list[str]:
    """One line per emitting material none of whose triangles has area (zero-area triangles
    emit nothing: :func:`tlm.scenes.loader.mesh_light` leaves them out), naming its parts
    (the first ``shown``) and its triangle count."""
    out = []
    tri = scene.triangles
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    for i, m in enumerate(scene.materials):
        on = scene.material_index == i
        if not m.emits or not on.any() or (area[on] > 0.0).any():
            continue
        parts = [scene.part_names[p] for p in np.unique(scene.part[on])]
        names = listing(map(quoted, parts), shown)
        k = int(on.sum())
        out.append(f"material {quoted(m.name)} emits (emission {list(m.emission)}) only on {k} triangle"
                   f"{'s' if k > 1 else ''} of zero area (part{'s' if len(parts) > 1 else ''} {names}): a triangle "
                   "without area emits nothing, so no light comes from it")
    return out


def corner_ids(tri: np.ndarray) -> tuple[np.ndarray, int]:
    """Triangles ``tri`` (k, 3, 3) as corner numbers (k, 3), matched by exact coordinates, and their count."""
    x = tri.reshape(-1, 3)
    order = np.lexsort(x.T[::-1])  # (np.unique(axis=0) is 4x slower)
    new = np.r_[True, (x[order[1:]] != x[order[:-1]]).any(axis=1)]  # (tri: not empty)
    corner = np.empty(order.shape[0], dtype=np.int64)
    corner[order] = np.cumsum(new) - 1
    return corner.reshape(-1, 3), int(new.sum())


def closed_surface(tri: np.ndarray) -> bool:
    """Whether triangles ``tri`` (k, 3, 3) close a surface wound one way: every edge shared by exactly two triangles
    that run along it in opposite directions; a triangle with two equal corners (a sphere's pole) left out."""
    f, n = corner_ids(tri)
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    a, b = f.T.ravel(), f[:, [1, 2, 0]].T.ravel()
    edge = np.sort(a * n + b)
    return f.shape[0] > 0 and bool((np.diff(edge) > 0).all() and np.array_equal(edge, np.sort(b * n + a)))


def winding(tri: np.ndarray, p: np.ndarray) -> float:
    """The winding number of triangles ``tri`` (k, 3, 3) about ``p``: 1 inside a closed surface facing out, -1 in."""
    a, b, c = (tri[:, i] - p for i in range(3))
    la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
    den = la * lb * lc + (a * b).sum(1) * lc + (a * c).sum(1) * lb + (b * c).sum(1) * la
    return float(np.arctan2((a * np.cross(b, c)).sum(1), den).sum() / (2.0 * np.pi))


def glass_warnings(scene: Scene, shown: int = 3) -> list[str]:
    """One line per set of parts whose dielectric triangles, joined by their corners into bodies (over parts too,
    h511), close a surface (:func:`closed_surface`) enclosing a negative volume (under minus :data:`GLASS_VOLUME_LIMIT`
    of its tetrahedra's sizes) in no other closed glass body (a cavity, :func:`winding`): glass is entered from the
    side cross(V1 - V0, V2 - V0) points to (h506: a ball so wound rendered its refract frame 0.02x-20x off)."""
    on = np.flatnonzero(np.array([m.kind == "dielectric" for m in scene.materials], dtype=bool)[scene.material_index])
    if on.shape[0] == 0:
        return []
    tri = scene.triangles[on]
    f, n = corner_ids(tri)
    label, u, v = np.arange(n), f.ravel(), f[:, [1, 2, 0]].ravel()  # (the bodies: each corner's least, union-find)
    while (label[u] != label[v]).any():
        np.minimum.at(label, label[u], label[v])
        np.minimum.at(label, label[v], label[u])
        while (label != label[label]).any():
            label = label[label]
    body = np.unique(label[f[:, 0]], return_inverse=True)[1]  # (0 .. k - 1, every one a body's: bincount's k)
    mean = np.stack([np.bincount(body, tri[:, :, c].sum(axis=1)) for c in range(3)], axis=1)
    t = tri - (mean / (3 * np.bincount(body)[:, None]))[body][:, None, :]  # (exact far from the origin)
    six = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2]))
    volume, total, each = np.bincount(body, six), np.bincount(body, np.abs(six)), np.split(
        np.argsort(body, kind="stable"), np.cumsum(np.bincount(body))[:-1])  # (each body's triangles)
    neg = [b for b in np.flatnonzero(volume < -GLASS_VOLUME_LIMIT * total) if closed_surface(tri[each[b]])]
    closed = {*neg, *(b for b in np.flatnonzero(volume > GLASS_VOLUME_LIMIT * total) if neg and closed_surface(
        tri[each[b]]))}  # (the bodies facing out: judged only where one faces in, whether it lies in one of them)
    said: dict[tuple, list] = {}  # (the bodies of each set of parts: one line)
    for b in neg:
        if closed - {b} and winding(tri[np.isin(body, list(closed - {b}))], tri[each[b][0]].mean(axis=0)) > 0.5:
            continue  # (a cavity of a glass body: its faces rightly point into it)
        said.setdefault(tuple(np.unique(scene.part[on[each[b]]])), []).append(b)
    out = []
    for parts, bodies in said.items():
        ids = np.concatenate([each[b] for b in bodies])
        mats, many, its = np.unique(scene.material_index[on[ids]]), len(parts) > 1, "their" if len(parts) > 1 else "its"
        out.append(f"part{'s' * many} {listing((quoted(scene.part_names[p]) for p in parts), shown)} (glass: material"
                   f"{'s' * (len(mats) > 1)} {listing((quoted(scene.materials[i].name) for i in mats), shown)}) "
                   f"{'are' if many else 'is'} a closed surface that faces inwards: "
                   + (f"{its} {ids.shape[0]}" if ids.shape[0] == np.isin(scene.part[on], parts).sum() else
                      f"{ids.shape[0]} of {its}") + f" triangles enclose a volume of {volume[bodies].sum() / 6.0:.3g}, "
                   "negative (cross(V1 - V0, V2 - V0) points into it), so light refracts out of it where it should "
                   "enter and the refract and photon-map frames are wrong (reverse the order of its faces' corners in "
                   "its mesh file, an OBJ's 'f 1 2 3' as 'f 1 3 2': glass is a closed surface with its front outward, "
                   "docs/scenes.md; the scene file has no key that turns a part's faces, and a mirroring transform "
                   "keeps them outward or inward as they are)")
    return out


def material_warnings(scene: Scene, shown: int = 3) -> list[str]:
    """One line naming the materials on the scene's triangles whose mesh file gives them
    what tlm does not render (:attr:`~tlm.scenes.model.Material.ignored`: the first
    ``shown`` by name) and what that is."""
    used = [scene.materials[i] for i in np.unique(scene.material_index)]
    hit = [m for m in used if m.ignored]
    if not hit:
        return []
    what = ", ".join(dict.fromkeys(k for m in hit for k in m.ignored))
    names = listing((quoted(m.name) for m in hit), shown)
    many = len(hit) > 1
    # (the files that define them, by name: an MTL library, a glTF; one OBJ may name two libraries, two OBJs share one)
    files = list(dict.fromkeys(quoted(Path(_material_file(m.origin)).name) for m in hit))
    of = listing(files, shown, "more files")
    # (a Lambertian's constant colour is its albedo; the others say what they become: a glTF material
    # whose metallicFactor defaults to 1 is a mirror, not its diffuse colour)
    other = [m for m in hit if m.kind != "lambertian"]
    became = ("" if not other else f", as {rendered_as(other[0])}" if not many else
              " (" + "; ".join(f"{quoted(m.name)} as {rendered_as(m)}" for m in other[:shown]) + ")")
    return [f"{len(hit)} material{'s' if many else ''} of {of} ({names}) "
            f"{'use' if many else 'uses'} what tlm does not render: {what}; "
            f"{'each renders' if many else 'it renders'} with its constant colour{became} (a scene file's "
            "materials: entry of the same name replaces it)"]


def _material_file(origin: str) -> str:
    """The file a mesh file's material comes from, by its :attr:`~tlm.scenes.model.Material.origin`: a
    glTF's ``FILE materials[i]``, an MTL's ``FILE:LINE`` (the OBJ's library, which :func:`material_warnings`
    names: an OBJ may name two libraries, two OBJs may share one)."""
    found = re.fullmatch(r"(.*)(?: materials\[[0-9]+\]|:[0-9]+)", origin, re.S)
    return found.group(1) if found else origin


def rendered_as(m) -> str:
    """What a material renders as, in words: ``a mirror of reflectance [1, 1, 1]``."""
    def rgb(c) -> str:
        return "[" + ", ".join(f"{x:.3g}" for x in c) + "]"

    what = {"lambertian": f"a Lambertian surface of albedo {rgb(m.albedo)}",
            "mirror": f"a mirror of reflectance {rgb(m.reflectance)}",
            "dielectric": f"glass of ior {m.ior:.4g} and transmittance {rgb(m.transmittance)}"}.get(m.kind, m.kind)
    return what + (f" emitting {rgb(m.emission)}" if m.emits else "")


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


BRANCH_LIMIT = 2**12  # rays one eye ray's mirror and glass walk may spawn, over which min_weight 0 is warned of


def walk_rays(depth: int) -> int:
    """The most rays one eye ray's specular walk of ``depth`` bounces traces when every
    glass hit splits a path in two (its Fresnel reflection and refraction, both traced)
    and no branch is pruned: ``2 + 4 + ... + 2**depth``."""
    return 2 ** (depth + 1) - 2


def branching_warning(cfg, scene: Scene | None = None) -> list[str]:
    """A line when ``render.min_weight`` is 0 (no branch is pruned) and a specular walk the
    run's mode traces (the reflect pass's from ``reflect`` on, ``render.reflect_depth``;
    the refract pass's from ``refract`` on, ``render.refract_depth``; the photon-map pass
    gathers at the ends of both) may spawn more than :data:`BRANCH_LIMIT` rays per eye ray
    (:func:`walk_rays`). Nothing with ``render.fresnel: false`` (one ray a path) or, given
    ``scene``, without glass (a mirror does not split a path; the reflect walk counts only
    with mirrors). ``cfg``: the run's :class:`~tlm.config.RunConfig`; its resolution, else
    the scene's, sizes the frame's total."""
    from tlm.config import MODES, RenderConfig

    r = cfg.render
    if r.min_weight > 0.0 or not r.fresnel:
        return []
    kinds = scene.kinds_present() if scene is not None else None
    if kinds is not None and "dielectric" not in kinds:
        return []
    level = MODES.index(cfg.mode)
    walks = [(key, depth) for key, depth, need, lowest in (
        ("render.reflect_depth", r.reflect_depth, "mirror", 1),
        ("render.refract_depth", r.refract_depth, "dielectric", 2))
        if level >= lowest and (kinds is None or need in kinds)]
    if not walks:
        return []
    key, depth = max(walks, key=lambda w: w[1])
    rays = walk_rays(depth)
    if rays <= BRANCH_LIMIT:
        return []
    res = cfg.resolution or ([scene.camera.width, scene.camera.height] if scene is not None else None)
    frame = (f", {rays * res[0] * res[1] * r.spp:.2g} for this {res[0]}x{res[1]} frame at render.spp = {r.spp}"
             if res else "")
    return [f"render.min_weight = 0 with {key} = {depth}: every glass hit splits a path in two (its Fresnel "
            f"reflection and refraction) and no branch is pruned, so one eye ray may spawn up to {rays:,} rays "
            f"(2^(depth + 1) - 2){frame}: the render may not finish, its memory growing; a render.min_weight above "
            f"0 prunes the branches whose weight falls under it (six glass slabs, 16x16 pixels: min_weight 0 traced "
            f"16 million rays in 32 s at refract_depth 18, 1.9 times more a level; the default "
            f"{RenderConfig().min_weight:g}, 76,012 rays in 3 s at depth 64)"]


def radius_warnings(cfg, diagonal: float) -> list[str]:
    """A line per search radius the config gives in scene units (``estimate.radius``,
    ``estimate.caustic_radius``) that is larger than the scene's ``diagonal``: every gather
    then takes every photon it reaches, the whole map, and divides their power by
    ``pi r**2``; past ``sqrt(max / pi)`` (about 7.6e153) that area is infinite and the
    estimate 0 (:func:`tlm.kernels.estimate.check_radius` refuses it). Nothing with the
    k-nearest filter (``knn``: no fixed radius) or before the photon-map pass
    (``mode: pmap``)."""
    est = cfg.estimate
    if cfg.mode != "pmap" or est.filter == "knn" or not diagonal > 0.0:
        return []
    out = []
    for key, r in (("estimate.radius", est.radius), ("estimate.caustic_radius", est.caustic_radius)):
        if r is None or not r > diagonal:
            continue
        area = math.pi * r * r
        what = (f"pi r^2 = {area:.3g}, so the estimate is the map's power over that area" if math.isfinite(area)
                else "pi r^2 overflows float64 to infinity, so the estimate is 0")
        out.append(f"{key} = {r:g} is {r / diagonal:.3g} times the scene's diagonal ({diagonal:.3g}): every gather "
                   f"takes every photon of the map within reach and {what} (a radius of a few hundredths of the "
                   "diagonal, or radius_fraction, is the usual choice)")
    return out
