"""The scene model: triangles, materials, lights and a pinhole camera.

A scene is what the thesis's Vertex PM receives as raw data: a flat list of world-space
triangles (the order of that list is the triangle id used everywhere: AOVs, BSP
leaves, exports), a material per triangle, the lights and the camera. Geometry comes
either from a built-in builder (`ring`, `room`, `cornell`) or from a mesh that trimesh
loads; in both cases it arrives as named *parts*, and the scene file maps parts to
materials.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import NamedTuple

import numpy as np

from tlm.errors import quoted

MATERIAL_KINDS = ("lambertian", "mirror", "dielectric")
KIND = {k: i for i, k in enumerate(MATERIAL_KINDS)}  # a material kind's small-integer code
LIGHT_KINDS = ("quad", "point", "mesh", "spot", "directional")
# the kinds that are a point or a direction, not an area: one shadow ray a shaded point, never seen
DELTA_KINDS = ("point", "spot", "directional")
# a directional light's photons start on a disc this much (relative to the bounding sphere's
# radius) beyond the sphere, so that they start outside the scene
DISC_MARGIN = 0.01


def spot_falloff(cos_angle, cos_inner: float, cos_outer: float):
    """The glTF spec's recommended spot-light falloff (KHR_lights_punctual, "Inner and Outer Cone
    Angles"): 1 within the inner cone, 0 outside the outer one, between them the square of the
    cosine's linear interpolation, ``((cos - cos_outer) / (cos_inner - cos_outer))**2``. Numbers or
    arrays of cosines."""
    x = (np.asarray(cos_angle, dtype=np.float64) - cos_outer) / (cos_inner - cos_outer)
    x = np.clip(x, 0.0, 1.0)
    return x * x


def unit_vector(v) -> np.ndarray | None:
    """``v`` (3,) scaled to unit length (by its largest component first, so that a vector of
    tiny or huge components keeps its direction), or None when it has none (zero, not finite)."""
    a = np.asarray(v, dtype=np.float64)
    with np.errstate(over="ignore", under="ignore", invalid="ignore", divide="ignore"):
        big = float(np.abs(a).max())
        if not (big > 0.0 and np.isfinite(big)):
            return None
        u = a / big
        u = u / np.linalg.norm(u)
    return u if np.isfinite(u).all() else None


def bounding_sphere(lo, hi) -> tuple[np.ndarray, float]:
    """The centre and radius of the sphere around the box [lo, hi]: the box's centre and half its
    diagonal (a directional light's photons cover it)."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    return 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))


@dataclass(frozen=True)
class Material:
    """A surface description.

    kind : 'lambertian' (RGB ``albedo``), 'mirror' (RGB ``reflectance``) or
    'dielectric' (``ior`` and RGB ``transmittance``).
    emission : RGB radiance ``Le`` leaving the front side (``cross(V1 - V0, V2 - V0)``)
    of every triangle of the material; non-zero makes those triangles a light (a
    ``mesh`` :class:`Light` that the loader builds, MTL ``Ke``, glTF ``emissiveFactor``).
    """

    name: str
    kind: str
    albedo: tuple[float, float, float] = (0.0, 0.0, 0.0)
    reflectance: tuple[float, float, float] = (0.0, 0.0, 0.0)
    ior: float = 1.0
    transmittance: tuple[float, float, float] = (0.0, 0.0, 0.0)
    emission: tuple[float, float, float] = (0.0, 0.0, 0.0)
    # what the mesh file gives the material that tlm does not render (MTL ``map_Kd``, ``bump``;
    # glTF ``baseColorTexture``, ``alpha``), for the run's warning (tlm.render.checks); not part
    # of the material's equality nor of its record() (references, Mitsuba), but its repr is, and so
    # the scene fingerprint of the frame cache
    ignored: tuple[str, ...] = field(default=(), compare=False)
    # a mesh file's material renamed where two files name one (tlm.scenes.compose.merge): the
    # name its file gives it, by which a scene file's materials: entry still replaces it
    alias: str = field(default="", compare=False)
    # a material a mesh file's faces name (OBJ usemtl) that its libraries do not define, or a PLY's
    # face material (tlm.scenes.plyfile: a PLY holds no material's values): why
    # (the line), for the error when the scene file gives it neither a materials: entry nor a
    # default_material (tlm.scenes.loader); its values are a placeholder
    undefined: str = field(default="", compare=False)
    # where its values come from, for results.json (:meth:`info`): ``FILE:LINE`` of an MTL's newmtl, ``FILE
    # materials[i]`` of a glTF's, ``FILE: materials.NAME`` of a scene file's entry; "" where not known (a
    # builder's); not part of the material's value (equality, hashes, repr)
    origin: str = field(default="", compare=False, repr=False)

    @property
    def emits(self) -> bool:
        return max(self.emission) > 0.0

    def with_origin(self, origin: str) -> Material:
        """The material with :attr:`origin` ``origin`` (its value the same)."""
        return replace(self, origin=origin)

    def info(self) -> dict:
        """The values the renderer uses, as plain data (``results.json``'s ``scene.materials``): ``kind``,
        its kind's own (a Lambertian's ``albedo``, a mirror's ``reflectance``, a dielectric's ``ior`` and
        ``transmittance``), ``emission`` where it emits, ``ignored`` where its file gives what tlm does not
        render (:attr:`ignored`) and ``from`` (:attr:`origin`) where known."""
        out: dict = {"kind": self.kind}
        if self.kind == "lambertian":
            out["albedo"] = [float(x) for x in self.albedo]
        elif self.kind == "mirror":
            out["reflectance"] = [float(x) for x in self.reflectance]
        elif self.kind == "dielectric":
            out.update(ior=float(self.ior), transmittance=[float(x) for x in self.transmittance])
        if self.emits:
            out["emission"] = [float(x) for x in self.emission]
        if self.ignored:
            out["ignored"] = [str(x) for x in self.ignored]
        return {**out, "from": self.origin} if self.origin else out

    def record(self) -> dict:
        """The material as plain data (for hashes): its fields, ``emission`` only when it emits
        (so a material's record is what it was before emission existed)."""
        out = {"name": self.name, "kind": self.kind, "albedo": self.albedo, "reflectance": self.reflectance,
               "ior": self.ior, "transmittance": self.transmittance}
        return {**out, "emission": self.emission} if self.emits else out


@dataclass(frozen=True)
class Light:
    """A quad area light, a point light, a mesh light, a spot light or a directional light,
    with RGB power in watts.

    A quad light is the parallelogram ``corner + a*edge_u + b*edge_v`` (a, b in
    [0, 1]); it emits on the side of ``cross(edge_u, edge_v)`` only, with constant
    radiance ``power / (pi * area)``. A point light emits ``power / (4 pi)`` watts per
    steradian in every direction. A mesh light is the scene's emitting triangles
    (``ids`` into the scene's triangle list, ``triangles`` their (m, 3, 3) vertices,
    ``radiance`` (m, 3) each one's ``Le``, on its front side only); unlike the other
    two it is geometry: eye rays see it where they hit it, and it casts shadows.
    ``power = pi * sum(Le * area)``. ``name`` says where the light comes from (the
    emitting materials' names for a mesh light).

    A spot light at ``position`` shines along ``direction`` (any length; :attr:`axis` is it
    made unit): ``power / (4 pi)`` W/sr
    (the intensity of a point light of that power) within ``inner_angle`` degrees of the
    axis, nothing beyond ``outer_angle``, and between them :func:`spot_falloff` (glTF's). It
    emits :attr:`flux` watts, less than ``power``. A directional light sends ``irradiance``
    (W per unit area, on a surface facing it) along ``direction`` from infinitely
    far; its ``power`` is that irradiance times the area of the disc that covers the
    triangles' bounding sphere (:func:`directional_power`, which the scene loader sets), the
    power its photons carry into the scene.
    """

    kind: str
    power: tuple[float, float, float]
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    corner: tuple[float, float, float] = (0.0, 0.0, 0.0)
    edge_u: tuple[float, float, float] = (0.0, 0.0, 0.0)
    edge_v: tuple[float, float, float] = (0.0, 0.0, 0.0)
    name: str = ""
    direction: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inner_angle: float = 0.0
    outer_angle: float = 0.0
    irradiance: tuple[float, float, float] = (0.0, 0.0, 0.0)
    ids: np.ndarray | None = field(default=None, compare=False, repr=False)
    triangles: np.ndarray | None = field(default=None, compare=False, repr=False)
    radiance: np.ndarray | None = field(default=None, compare=False, repr=False)
    # a mesh light's emitting materials' names, in the scene's order (its ``name`` joins them with ", ")
    materials: tuple[str, ...] = field(default=(), compare=False)
    # where it comes from, for results.json and ``tlm scene show`` (:meth:`info`'s ``from``): ``FILE: lights[i]``
    # of a scene file's entry, ``FILE KHR_lights_punctual.lights[i] 'NAME' at nodes[n]`` of a glTF's light
    origin: str = field(default="", compare=False, repr=False)

    def record(self) -> dict:
        """The light as plain data (for hashes and results.json): a quad or point light's
        fields as before mesh lights existed; a mesh light's kind, power, name and
        triangle count (its triangles and radiance are the scene's geometry and materials);
        a spot's kind, power, position, direction and cone angles; a directional light's
        kind, power, irradiance and direction."""
        if self.kind == "mesh":
            return {"kind": self.kind, "power": list(self.power), "name": self.name,
                    "triangles": int(self.ids.shape[0])}
        if self.kind == "spot":
            return {"kind": self.kind, "power": self.power, "position": self.position, "direction": self.direction,
                    "inner_angle": self.inner_angle, "outer_angle": self.outer_angle}
        if self.kind == "directional":
            return {"kind": self.kind, "power": self.power, "irradiance": self.irradiance,
                    "direction": self.direction}
        return {"kind": self.kind, "power": self.power, "position": self.position, "corner": self.corner,
                "edge_u": self.edge_u, "edge_v": self.edge_v}

    def info(self) -> dict:
        """The light as ``tlm scene show`` lists it (and a run's ``results.json``): its type,
        power (W) and its kind's own fields (a spot's cone angles in degrees, as a scene file
        gives them; a directional light's power is its irradiance over the disc covering the scene;
        a mesh light's ``materials`` a list of names), and ``from`` (:attr:`origin`) where known."""
        own: dict
        if self.kind == "point":
            own = {"position": list(self.position)}
        elif self.kind == "spot":
            own = {"position": list(self.position), "direction": list(self.direction),
                   "inner_cone_angle": self.inner_angle, "outer_cone_angle": self.outer_angle}
        elif self.kind == "directional":
            own = {"direction": list(self.direction), "irradiance": list(self.irradiance)}
        elif self.kind == "mesh":
            own = {"materials": list(self.materials) or [self.name], "triangles": int(self.ids.shape[0]),
                   "area": self.area}
        else:
            own = {"corner": list(self.corner), "edge_u": list(self.edge_u), "edge_v": list(self.edge_v),
                   "area": self.area}
        return {"type": self.kind, "power": list(self.power), **own, **({"from": self.origin} if self.origin else {})}

    @cached_property
    def axis(self) -> np.ndarray:
        """A spot's or directional light's ``direction`` made unit (:func:`unit_vector`; made once,
        read-only)."""
        u = unit_vector(self.direction)
        if u is None:
            raise ValueError(f"{self.kind} light {quoted(self.name)}: direction {list(self.direction)} has no length")
        return _frozen(u)

    @property
    def cone_cosines(self) -> tuple[float, float]:
        """A spot's ``(cos inner_angle, cos outer_angle)``."""
        return math.cos(math.radians(self.inner_angle)), math.cos(math.radians(self.outer_angle))

    @property
    def flux(self) -> tuple[float, float, float]:
        """The RGB watts the light emits: its ``power``, but for a spot ``power / (4 pi)``
        times the solid angle its falloff weighs, ``2 pi (1 - cos_i + (cos_i - cos_o) / 3)``."""
        if self.kind != "spot":
            return self.power
        ci, co = self.cone_cosines
        share = 0.5 * ((1.0 - ci) + (ci - co) / 3.0)
        return tuple(float(p) * share for p in self.power)

    # The derived values below are made on first use and kept on the light (functools.cached_property:
    # the shading reads them every batch of every pass). A light is frozen, and a mesh light's
    # arrays are never changed after it is made; the arrays given out are read-only.

    @cached_property
    def area(self) -> float:
        """A quad light's area ``|cross(edge_u, edge_v)|``; a mesh light's, the sum of :attr:`areas`."""
        if self.kind == "mesh":
            return float(self.areas.sum())
        return float(np.linalg.norm(np.cross(self.edge_u, self.edge_v)))

    @cached_property
    def areas(self) -> np.ndarray:
        """(m,) areas of a mesh light's triangles."""
        t = self.triangles
        return _frozen(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1))

    @cached_property
    def normal(self) -> np.ndarray:
        """A quad light's unit normal, ``cross(edge_u, edge_v)`` made unit (the side it emits on)."""
        n = np.cross(self.edge_u, self.edge_v)
        return _frozen(n / np.linalg.norm(n))

    @cached_property
    def quad(self) -> QuadFrame:
        """A quad light's corner and edges as arrays, the Gram matrix of its edges and its
        radiance (:class:`QuadFrame`)."""
        c, eu, ev = (np.array(x) for x in (self.corner, self.edge_u, self.edge_v))
        gram = np.array([[eu @ eu, eu @ ev], [eu @ ev, ev @ ev]])
        with np.errstate(divide="ignore", invalid="ignore"):  # (a quad of no area: never seen, emits nothing)
            le = np.array(self.power) / (np.pi * self.area)
        return QuadFrame(*(_frozen(x) for x in (c, eu, ev, gram, le)))


class QuadFrame(NamedTuple):
    """A quad light's constants as arrays (:attr:`Light.quad`, read-only): ``corner``, ``edge_u``
    and ``edge_v`` (3,); ``gram`` (2, 2), ``[[eu.eu, eu.ev], [eu.ev, ev.ev]]``, whose system gives
    a point's coordinates ``(a, b)`` in the quad's frame; ``radiance`` (3,), ``Le = power / (pi
    area)`` on the emitting side."""

    corner: np.ndarray
    edge_u: np.ndarray
    edge_v: np.ndarray
    gram: np.ndarray
    radiance: np.ndarray


def _frozen(a: np.ndarray) -> np.ndarray:
    """``a`` made read-only (a value kept on a light, shared by every caller)."""
    a.flags.writeable = False
    return a


def directional_power(irradiance, lo, hi) -> tuple[float, float, float]:
    """A directional light's power in a scene whose triangles' box is [lo, hi]: ``irradiance``
    times ``pi R^2``, the area of the disc covering the box's bounding sphere (of radius R)."""
    _, r = bounding_sphere(lo, hi)
    return tuple(float(e) * math.pi * r * r for e in irradiance)


@dataclass(frozen=True)
class Camera:
    """Pinhole look-at camera; ``vfov`` is the vertical field of view in degrees."""

    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    up: tuple[float, float, float]
    vfov: float
    width: int
    height: int


@dataclass(frozen=True)
class Imported:
    """What a mesh file gives besides its triangles that a scene can take: a glTF's point, spot
    and directional lights (``KHR_lights_punctual``) and its first perspective camera, in the geometry's
    space (an item's ``transform`` moves them with its triangles). The scene takes the
    lights when its file gives no ``lights:``, the camera when it gives no ``camera:``
    (:func:`tlm.scenes.loader.load_scene`).

    source : the mesh file's path.
    lights : ``point``, ``spot`` and ``directional`` lights, each named ``FILE
        KHR_lights_punctual.lights[i] 'NAME' at nodes[n]`` (a spot's or directional light's
        ``direction`` unit length; an item's transform turns it); a directional light's power
        is 0 until the scene's loader knows the scene's bounds.
    camera : ``eye``, ``target`` (one unit in front of the eye), ``up``, ``vfov``; its
        ``width`` and ``height`` are 0 (the scene's resolution gives them). None: none.
    camera_name : ``cameras[i] 'NAME' at nodes[n]``.
    aspect : the camera's ``aspectRatio``, when the file gives one.
    """

    source: str
    lights: tuple[Light, ...] = ()
    camera: Camera | None = None
    camera_name: str = ""
    aspect: float | None = None


@dataclass(frozen=True)
class Geometry:
    """Triangles as named parts, as a builder or a mesh loader returns them.

    triangles : (n, 3, 3) float64, world space, vertex order defines the normal.
    part : (n,) int32 index into ``part_names``.
    """

    triangles: np.ndarray
    part: np.ndarray
    part_names: tuple[str, ...]
    normals: np.ndarray | None = None  # (n, 3, 3) per-corner shading normals from the file, if it has them
    # the materials the file defines (OBJ's MTL, glTF's materials), mapped to tlm's kinds
    # (tlm.scenes.materials), and each triangle's index into them; -1 where the file
    # gives a triangle none. A scene file's `parts:` and `materials:` override them.
    materials: tuple[Material, ...] = ()
    face_material: np.ndarray | None = None  # (n,) int32
    # what the file holds that tlm does not use, one line each naming the file (a glTF's
    # lights on no node, its orthographic cameras): the run warns of them
    # (tlm.render.checks.file_warnings)
    notes: tuple[str, ...] = ()
    # the lights and camera of the files (a glTF's punctual lights and first perspective camera),
    # one entry per item of the geometry that has any (tlm.scenes.loader decides whether they are used)
    imports: tuple[Imported, ...] = ()


@dataclass(frozen=True)
class Scene:
    """Everything the renderer needs; triangle ids are indices into ``triangles``."""

    name: str
    triangles: np.ndarray  # (n, 3, 3) float64
    material_index: np.ndarray  # (n,) int32 into materials
    materials: tuple[Material, ...]
    part: np.ndarray  # (n,) int32 into part_names
    part_names: tuple[str, ...]
    lights: tuple[Light, ...]
    camera: Camera
    photons: int
    source: str = ""
    extra: dict = field(default_factory=dict)
    # (n, 3, 3) unit shading normal of each triangle corner (tlm.scenes.normals); None:
    # the renderer computes them with the default crease angle
    normals: np.ndarray | None = None

    def __repr__(self) -> str:
        """One line (a notebook shows it for ``tlm.load_scene(...)``), not the arrays' values: the name, the
        triangles, parts, materials and lights, the camera's width x height, the photons and the file; each field as
        it is: ``.triangles``, ``.materials``, ``.lights``, ``.camera``, ``.extra``."""
        name = self.name if len(self.name) <= 40 else self.name[:37] + "..."
        kinds = sorted({light.kind for light in self.lights})
        n_lights = len(self.lights)
        return (f"Scene({name!r}: {self.n_triangles:,} triangles, {len(self.part_names)} "
                f"part{'s' if len(self.part_names) != 1 else ''}, {len(self.materials)} "
                f"material{'s' if len(self.materials) != 1 else ''}, {n_lights} light{'s' if n_lights != 1 else ''}"
                + (f" ({', '.join(kinds)})" if kinds else "")
                + f", camera {self.camera.width}x{self.camera.height}, {self.photons:,} photons"
                + (f", from {self.source}" if self.source else "") + ")")

    @property
    def n_triangles(self) -> int:
        return int(self.triangles.shape[0])

    def material_table(self) -> dict[str, np.ndarray]:
        """Per-triangle material arrays: ``kind`` (n,) int8 (:data:`KIND` codes),
        ``albedo``, ``reflectance``, ``transmittance``, ``emission`` (n, 3) and ``ior`` (n,)."""
        mats = self.materials
        table = {
            "kind": np.array([KIND[m.kind] for m in mats], dtype=np.int8),
            "albedo": np.array([m.albedo for m in mats], dtype=np.float64).reshape(-1, 3),
            "reflectance": np.array([m.reflectance for m in mats], dtype=np.float64).reshape(-1, 3),
            "transmittance": np.array([m.transmittance for m in mats], dtype=np.float64).reshape(-1, 3),
            "ior": np.array([m.ior for m in mats], dtype=np.float64),
            "emission": np.array([m.emission for m in mats], dtype=np.float64).reshape(-1, 3),
        }
        return {k: v[self.material_index] for k, v in table.items()}

    def kinds_present(self) -> set[str]:
        used = np.unique(self.material_index)
        return {self.materials[i].kind for i in used}

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        flat = self.triangles.reshape(-1, 3)
        return flat.min(axis=0), flat.max(axis=0)
