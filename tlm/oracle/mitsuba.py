"""Mitsuba 3 as an independent oracle: our scenes rendered by a production renderer.

:func:`scene_dict` maps a :class:`~tlm.scenes.model.Scene` onto a dictionary for
``mitsuba.load_dict``, :func:`render` renders it (variant ``scalar_rgb``: RGB, CPU,
single precision, no JIT, so it runs wherever Mitsuba's wheel installs; it uses every
core), :func:`ground_truth` caches converged images in ``oracle/<key>/`` of tlm's cache
folder (``$TLM_CACHE``, else ``$XDG_CACHE_HOME/tlm``, else ``~/.cache/tlm``:
:func:`tlm.caches.cache_home`; a cache that cannot be written loses no image, see
:func:`ground_truth`) and :func:`flip`, :func:`rel_mse_per_pixel` and :func:`mean_normalised_rel_rmse` measure an
image against one (the per-pixel relative MSE of many rendering papers: not the ``rel_mse`` of
tlm's runs, studies and reports, :func:`tlm.experiments.reference.image_error`'s summed ratio).
Mitsuba is optional: it is imported on first use (a missing package is a one-line
:class:`~tlm.errors.InputError`), and that use sets Mitsuba's process-wide variant to ``scalar_rgb``.

The mapping, and why:

* **Frame.** Mitsuba gets the scene moved so that the eye is at the origin and scaled
  so that its bounding box's diagonal is :data:`MITSUBA_DIAGONAL`, light power scaled by
  the square of the length scale: radiance, and so the image, does not change. Mitsuba
  works in float32 and offsets every ray it spawns by ~1e-4 (1 + |p|), an absolute floor;
  in this frame a scene scaled by 1e-6 or moved 1e6 away renders as the original does.
* **Geometry.** ``scene.triangles`` become one ``mi.Mesh`` per material, with unshared
  vertices (three per triangle, in the triangle's own order, so Mitsuba's geometric
  normal ``cross(V1 - V0, V2 - V0)`` is ours and a triangle's corner normals are its
  own). With per-corner shading ``normals`` (the argument, else ``scene.normals`` when
  the scene has them) the meshes carry them as vertex normals; without, they are flat
  (``face_normals``).
* **Materials.** ``lambertian`` -> ``diffuse`` with the RGB albedo, wrapped in
  ``twosided``: Mitsuba's diffuse BSDF is black seen from the back, ours shades
  whichever side a ray arrives from. ``mirror`` -> ``conductor`` with ``material:
  none`` (reflectance 1) scaled by the RGB ``specular_reflectance``, also wrapped in
  ``twosided``: Mitsuba's conductor is one-sided too (black from behind; checked by
  rendering), our mirror reflects on both sides. ``dielectric`` -> ``dielectric`` with
  ``int_ior`` = ior, ``ext_ior`` = 1 and the RGB ``specular_transmittance`` (two-sided
  by nature). Mitsuba's dielectric is the physical one: the exact Fresnel split into
  reflection and refraction (one of the two chosen at random per path), the
  transmittance applied at every crossing, and radiance scaled by ``1 / eta^2`` inside
  the denser medium (it cancels for a path that enters and leaves a closed object).
* **Lights.** A quad light -> a ``rectangle`` whose ``to_world`` maps the local square
  ``[-1, 1]^2`` (normal +z) onto ``corner + a edge_u + b edge_v``: the matrix's
  columns are ``edge_u / 2``, ``edge_v / 2``, the unit ``cross(edge_u, edge_v)`` and
  the quad's centre (a parallelogram is fine). Mitsuba's ``area`` emitter is one-sided
  along the shape's normal, which this map makes ours (checked by rendering: swapping
  the edges turns the Cornell box black). Its radiance is ours, ``power / (pi area)``,
  and it reflects nothing (a black ``diffuse``). Our lights are not geometry, while a
  Mitsuba emitter is attached to a shape, so the rectangle is moved
  :data:`LIGHT_OFFSET` of the scene's bounding-box diagonal along its emitting normal:
  a light lying on a surface (Cornell's, on its ceiling) then sits just in front of it
  instead of z-fighting with it. (The rectangle still blocks rays from behind, ours
  lets them through: no built-in scene has a light that anything sees from behind.) A
  point light -> ``point`` with intensity ``power / (4 pi)`` W/sr. A spot light -> ``spot``
  at its position looking along its direction, intensity ``power / (4 pi)`` W/sr,
  ``cutoff_angle`` its outer cone angle and ``beam_width`` its inner one. The two agree
  within the inner cone (the full intensity) and outside the outer one (nothing), **not
  between**: Mitsuba's falloff there is linear in the angle, ``(outer - angle) / (outer -
  inner)``, tlm's is the glTF spec's, ``((cos - cos outer) / (cos inner - cos outer))^2``
  (:func:`tlm.scenes.model.spot_falloff`), which falls faster; a comparison leaves out the
  pixels lit through the ring between the cones (``tests/test_spot_directional.py``). A
  directional light -> ``directional`` with its direction and irradiance (Mitsuba's
  ``irradiance`` is ours: W per unit area on a surface facing it; it does not scale with
  the frame's lengths).
* **Camera.** ``perspective`` with ``fov`` = ``vfov`` on the ``y`` axis and
  ``to_world`` = ``look_at(eye, target, up)``: Mitsuba's image is then ours, row 0 at
  the top, not mirrored (checked on the Cornell box: the red wall on the left). The
  film is an ``hdrfilm`` of the camera's size with a ``box`` reconstruction filter
  (Mitsuba's default Gaussian would blur across pixels), so a pixel is the mean
  radiance over its square. A renderer that samples a pixel at its centre, or at a few
  points, agrees with that except where the pixel holds an edge:
  :mod:`tlm.oracle.masks` finds the pixels where the comparison is fair. The clip
  planes follow the scene's size.
* **Sampler and integrators.** ``stratified`` when ``spp`` is a square number, else
  ``independent``, with the given seed. ``direct`` is Mitsuba's direct-illumination
  integrator (one emitter and one BSDF sample per camera sample, combined by MIS): on
  Lambertian surfaces it is what our ray-cast frame estimates; on a mirror or glass it
  shows only the lights seen in them. ``path`` is the unidirectional path tracer
  (``max_depth`` -1 = unlimited; Russian roulette from depth 5): the full solution of
  the rendering equation, which our composite approximates.

Units: images are linear radiance in the scene's units (W / (unit^2 sr)), float64,
``(height, width, 3)``, rows top to bottom: our frames reshaped to the image.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np

from tlm.caches import cache_root
from tlm.errors import EnvironmentFailure, InputError
from tlm.fingerprint import META_SEAL, read_sealed, sealed
from tlm.scenes.lights import own_points
from tlm.scenes.model import Scene
from tlm.storage import atomic_folder, warn

VARIANT = "scalar_rgb"
INTEGRATORS = ("direct", "path", "ptracer")
MITSUBA_DIAGONAL = 1000.0  # the scene's bounding-box diagonal in Mitsuba's units (see _normalised)
LIGHT_OFFSET = 1e-5  # quad lights move this fraction of the bounding-box diagonal along their normal
MAPPING_VERSION = 1  # part of the cache key: bump when the scene mapping changes what Mitsuba renders
# the optional packages of the 'oracle' extra (pyproject.toml's, which a test keeps them equal to), and how to
# install them: by name beside an installed copy (pip install . from a clone), or as the extra in a checkout
ORACLE_PACKAGES = ("mitsuba>=3.5", "flip-evaluator>=1.6")
INSTALL_HINT = ("pip install " + " ".join(f'"{p}"' for p in ORACLE_PACKAGES)
                + '; in a checkout: pip install -e ".[oracle]"')
REL_MSE_EPS = 1e-2  # rel_mse_per_pixel's floor on ref^2, as a fraction of mean(ref)^2 (see rel_mse_per_pixel)


def _mitsuba():
    """The ``mitsuba`` module with the :data:`VARIANT` set, or a one-line InputError."""
    try:
        import mitsuba as mi
    except ImportError:
        raise InputError(f"the Mitsuba oracle needs the optional package mitsuba ({INSTALL_HINT})",
                         key="oracle") from None
    if mi.variant() != VARIANT:
        mi.set_variant(VARIANT)
    return mi


def require() -> None:
    """Check that the oracle's optional packages (mitsuba, flip-evaluator) import; a
    one-line InputError naming the install command otherwise."""
    _mitsuba()
    try:
        import flip_evaluator  # noqa: F401
    except ImportError:
        raise InputError(f"FLIP needs the optional package flip-evaluator ({INSTALL_HINT})", key="oracle") from None


def mitsuba_version() -> str:
    return str(_mitsuba().__version__)


def _rgb(value) -> dict:
    return {"type": "rgb", "value": [float(x) for x in value]}


def _bsdf(material) -> dict:
    if material.kind == "lambertian":
        return {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": _rgb(material.albedo)}}
    if material.kind == "mirror":
        return {"type": "twosided", "bsdf": {"type": "conductor", "material": "none",
                                             "specular_reflectance": _rgb(material.reflectance)}}
    if material.kind == "dielectric":
        return {"type": "dielectric", "int_ior": float(material.ior), "ext_ior": 1.0,
                "specular_transmittance": _rgb(material.transmittance)}
    raise InputError(f"material kind {material.kind!r} has no Mitsuba mapping", key=f"materials.{material.name}")


def _scene_normals(scene: Scene, normals) -> np.ndarray | None:
    if normals is None:
        normals = getattr(scene, "normals", None)
    if normals is None:
        return None
    normals = np.asarray(normals, dtype=np.float64)
    if normals.shape != np.shape(scene.triangles):
        raise ValueError(f"normals must have the triangles' shape {np.shape(scene.triangles)}, got {normals.shape}")
    return normals


def _mesh(mi, name: str, triangles: np.ndarray, normals: np.ndarray | None, bsdf: dict,
          emission: tuple[float, float, float] | None = None):
    """A Mitsuba mesh of ``triangles`` (k, 3, 3) with unshared vertices; with
    ``emission`` (RGB radiance) an ``area`` emitter too (one-sided, along the winding's
    normal, as a mesh light of ours)."""
    k = triangles.shape[0]
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    if emission is not None and max(emission) > 0:
        props["emitter"] = mi.load_dict({"type": "area", "radiance": _rgb(np.asarray(emission, dtype=np.float64))})
    props["face_normals"] = normals is None
    mesh = mi.Mesh(name, 3 * k, k, props, has_vertex_normals=normals is not None)
    params = mi.traverse(mesh)
    array_f = type(params["vertex_positions"])
    array_u = type(params["faces"])
    params["vertex_positions"] = array_f(np.ascontiguousarray(triangles, dtype=np.float32).ravel())
    params["faces"] = array_u(np.arange(3 * k, dtype=np.uint32))
    if normals is not None:
        params["vertex_normals"] = array_f(np.ascontiguousarray(normals, dtype=np.float32).ravel())
    params.update()
    return mesh


def _extent(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box of the triangles, the lights and the eye."""
    pts = [np.asarray(scene.triangles, dtype=np.float64).reshape(-1, 3), np.asarray([scene.camera.eye])]
    for lt in scene.lights:
        if lt.kind == "mesh":  # its triangles are the scene's
            continue
        if lt.kind in ("point", "spot"):
            pts.append(np.asarray([lt.position]))
        elif lt.kind == "directional":  # (at infinity: no point of the scene)
            continue
        else:
            c = np.asarray(lt.corner)
            pts.append(np.asarray([c, c + lt.edge_u, c + lt.edge_v, c + np.add(lt.edge_u, lt.edge_v)]))
    allp = np.concatenate(pts)
    return allp.min(axis=0), allp.max(axis=0)


def _normalised(scene: Scene) -> Scene:
    """The scene moved so that the eye is at the origin and scaled so that its bounding
    box's diagonal is :data:`MITSUBA_DIAGONAL`, in float64 before Mitsuba's float32.

    Radiance does not change: light power scales with the square of the lengths. Mitsuba
    offsets the rays it spawns by ``~1e-4 (1 + |p|)``, an absolute floor that would
    swallow a scene a millimetre wide, and its float32 coordinates would blur a scene far
    from the origin; at the eye and at this size both are ~1e-7 of the scene.
    """
    eye = np.asarray(scene.camera.eye, dtype=np.float64)
    lo, hi = _extent(scene)
    size = float(np.linalg.norm(hi - lo))
    k = MITSUBA_DIAGONAL / size if size > 0 and np.isfinite(size) else 1.0

    def pt(p):
        return tuple(float(x) for x in (np.asarray(p, dtype=np.float64) - eye) * k)

    def vec(v):
        return tuple(float(x) for x in np.asarray(v, dtype=np.float64) * k)

    # (each light's own points and lengths, as the scene loader's transform moves them, lights.scaled_light: a
    # field its kind does not have stays as it is; a directional light's irradiance does not change, its power,
    # irradiance x the area of a disc, does)
    lights = tuple(replace(lt, power=tuple(float(x) * k * k for x in lt.power), **own_points(lt, pt, vec))
                   for lt in scene.lights if lt.kind != "mesh")  # a mesh light goes with its material
    camera = replace(scene.camera, eye=(0.0, 0.0, 0.0), target=pt(scene.camera.target))
    triangles = (np.asarray(scene.triangles, dtype=np.float64) - eye) * k
    return replace(scene, triangles=triangles, lights=lights, camera=camera)


def _quad_light(mi, light, offset: float) -> dict | None:
    area = light.area
    if not area > 0:
        return None
    eu, ev = np.asarray(light.edge_u, dtype=np.float64), np.asarray(light.edge_v, dtype=np.float64)
    n = light.normal
    centre = np.asarray(light.corner, dtype=np.float64) + 0.5 * (eu + ev) + offset * n
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = 0.5 * eu, 0.5 * ev, n, centre
    radiance = np.asarray(light.power, dtype=np.float64) / (math.pi * area)
    return {
        "type": "rectangle",
        "to_world": mi.ScalarTransform4f(m.tolist()),
        "emitter": {"type": "area", "radiance": _rgb(radiance)},
        "bsdf": {"type": "diffuse", "reflectance": _rgb((0.0, 0.0, 0.0))},
    }


def _spot_light(mi, light) -> dict:
    """Mitsuba's ``spot`` for a spot light: at its position, looking along its axis, intensity
    ``power / (4 pi)``, ``cutoff_angle`` its outer cone angle and ``beam_width`` its inner one
    (Mitsuba's falloff between them is linear in the angle, not tlm's: see the module's docstring)."""
    axis = light.axis
    up = np.array([0.0, 1.0, 0.0]) if abs(axis[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    pos = np.asarray(light.position, dtype=np.float64)
    return {"type": "spot",
            "to_world": mi.ScalarTransform4f().look_at(origin=[float(x) for x in pos],
                                                      target=[float(x) for x in pos + axis],
                                                      up=[float(x) for x in up]),
            "intensity": _rgb(np.asarray(light.power, dtype=np.float64) / (4.0 * math.pi)),
            "cutoff_angle": float(light.outer_angle), "beam_width": float(light.inner_angle)}


def _check_settings(integrator: str, spp: int, max_depth: int, seed: int) -> None:
    if integrator not in INTEGRATORS:
        raise InputError(f"{integrator!r} is not one of {', '.join(INTEGRATORS)}", key="integrator")
    for key, value, lo in (("spp", spp, 1), ("max_depth", max_depth, -1), ("seed", seed, 0)):
        if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < lo:
            raise InputError(f"{value!r} must be a whole number >= {lo}", key=key)


def scene_dict(scene: Scene, *, integrator: str, spp: int, max_depth: int = -1, seed: int = 0,
               normals=None) -> dict[str, Any]:
    """The Mitsuba scene of ``scene`` (a dict for ``mi.load_dict``; sets the variant).

    integrator : 'direct', 'path' or 'ptracer' (Mitsuba's particle tracer: light paths
    connected to the camera; it renders caustics of point lights seen on diffuse surfaces,
    which no eye path can reach, and leaves black what the eye sees in a mirror or
    glass). spp : samples per pixel. max_depth : the path
    tracer's longest path (-1 = unlimited). seed : the sampler's seed. normals :
    optional (n, 3, 3) unit per-corner shading normals (default ``scene.normals`` if
    the scene has them, else flat triangles).
    """
    mi = _mitsuba()
    _check_settings(integrator, spp, max_depth, seed)
    nrm = _scene_normals(scene, normals)
    scene = _normalised(scene)
    tri = np.asarray(scene.triangles, dtype=np.float64)
    lo, hi = _extent(scene)
    diag = float(np.linalg.norm(hi - lo)) or 1.0
    cam = scene.camera
    far = 2.0 * diag  # the box holds the eye: nothing is farther than its diagonal
    root = math.isqrt(spp)
    sampler = "stratified" if root * root == spp else "independent"
    doc: dict[str, Any] = {
        "type": "scene",
        "integrator": ({"type": "direct"} if integrator == "direct"
                       else {"type": integrator, "max_depth": int(max_depth)}),
        "sensor": {
            "type": "perspective",
            "fov": float(cam.vfov),
            "fov_axis": "y",
            "near_clip": far * 1e-7,
            "far_clip": far,
            "to_world": mi.ScalarTransform4f().look_at(origin=[float(x) for x in cam.eye],
                                                      target=[float(x) for x in cam.target],
                                                      up=[float(x) for x in cam.up]),
            "film": {"type": "hdrfilm", "width": int(cam.width), "height": int(cam.height),
                     "rfilter": {"type": "box"}, "pixel_format": "rgb", "component_format": "float32"},
            "sampler": {"type": sampler, "sample_count": int(spp), "seed": int(seed)},
        },
    }
    material_index = np.asarray(scene.material_index)
    for m in np.unique(material_index):
        sel = material_index == m
        material = scene.materials[int(m)]
        doc[f"mesh_{int(m)}"] = _mesh(mi, material.name, tri[sel], None if nrm is None else nrm[sel],
                                      _bsdf(material), material.emission)
    for i, light in enumerate(scene.lights):
        if light.kind == "point":
            doc[f"light_{i}"] = {"type": "point", "position": [float(x) for x in light.position],
                                 "intensity": _rgb(np.asarray(light.power, dtype=np.float64) / (4.0 * math.pi))}
        elif light.kind == "quad":
            quad = _quad_light(mi, light, LIGHT_OFFSET * diag)
            if quad is not None:
                doc[f"light_{i}"] = quad
        elif light.kind == "spot":
            doc[f"light_{i}"] = _spot_light(mi, light)
        elif light.kind == "directional":
            doc[f"light_{i}"] = {"type": "directional", "direction": [float(x) for x in light.axis],
                                 "irradiance": _rgb(np.asarray(light.irradiance, dtype=np.float64))}
        else:
            raise InputError(f"light kind {light.kind!r} has no Mitsuba mapping", key=f"lights[{i}]")
    return doc


def render(scene: Scene, *, integrator: str, spp: int, max_depth: int = -1, seed: int = 0,
           normals=None) -> np.ndarray:
    """Mitsuba's image of ``scene``: (height, width, 3) float64 linear radiance, row 0 at the top."""
    mi = _mitsuba()
    ms = mi.load_dict(scene_dict(scene, integrator=integrator, spp=spp, max_depth=max_depth, seed=seed,
                                 normals=normals))
    image = mi.render(ms, spp=int(spp), seed=int(seed))
    return np.array(image, dtype=np.float64).reshape(scene.camera.height, scene.camera.width, 3)


# --------------------------------------------------------------------------- cache


def cache_dir() -> Path:
    """``oracle`` in tlm's cache folder (:func:`tlm.caches.cache_home`)."""
    return cache_root("oracle")


def oracle_key(scene: Scene, *, integrator: str, spp: int, max_depth: int = -1, seed: int = 0,
               normals=None) -> str:
    """A hash of everything Mitsuba's image depends on: the scene's content (triangles,
    shading normals, materials, lights, camera and resolution) and the render settings.
    The scene's name, source and photon count are not part of it."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(scene.triangles, dtype=np.float64).tobytes())
    nrm = _scene_normals(scene, normals)
    if nrm is not None:
        h.update(b"normals")
        h.update(np.ascontiguousarray(nrm, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(scene.material_index, dtype=np.int64).tobytes())
    doc = {
        "materials": [m.record() for m in scene.materials],
        "lights": [lt.record() for lt in scene.lights],
        "camera": asdict(scene.camera),
        "settings": {"integrator": integrator, "spp": int(spp), "max_depth": int(max_depth), "seed": int(seed)},
        "mapping": MAPPING_VERSION,
    }
    h.update(json.dumps(doc, sort_keys=True, default=float).encode())
    return h.hexdigest()[:20]


META_FORMAT = "ground-truth-meta/2"  # /2: sealed with its own digest (tlm.fingerprint.META_SEAL)


def save_ground_truth(key: str, image: np.ndarray, meta: dict) -> Path:
    """Write ``image.npy`` (float32) and ``meta.json`` (with the image's size and checksum, :data:`META_FORMAT`
    and, last, its own digest: :func:`~tlm.fingerprint.sealed`) atomically into the cache."""
    from tlm.caches import file_digest

    final = cache_dir() / key
    with atomic_folder(final, "meta.json") as tmp:
        np.save(tmp / "image.npy", np.asarray(image, dtype=np.float32))
        body = {"key": key, **meta, "npy": file_digest(tmp / "image.npy"), "format": META_FORMAT}
        (tmp / "meta.json").write_text(json.dumps(sealed(body, META_SEAL), indent=2) + "\n", encoding="utf-8")
    return final


def load_ground_truth(key: str) -> tuple[np.ndarray, dict] | None:
    """The cached image (float64) and its metadata, or None when there is none.

    A damaged entry (``meta.json`` missing, unreadable or of another key; ``image.npy``
    missing, unreadable, cut short, not the bytes its size and checksum in ``meta.json``
    say, or not the (height, width, 3) floats ``meta.json`` describes) is reported once as
    a warning naming the file and removed: it is rendered again as if it had never been
    cached (as the references' and the scenes' caches do). So is one whose ``meta.json`` is not as
    its own digest says (:func:`~tlm.fingerprint.read_sealed`: a value changed in it); one written
    before the seals (no digest, no format) is used, said once in a warning.
    """
    folder = cache_dir() / key
    found = read_sealed(folder, "image.npy", key, "Mitsuba ground-truth", "it is rendered again when next needed",
                        META_FORMAT, f"removing {folder} renders it again, sealed")
    return None if found is None else (found[0].astype(np.float64), found[1])


def ground_truth(scene: Scene, integrator: str = "path", spp: int = 4096, max_depth: int = -1, seed: int = 0,
                 compute: bool = True, normals=None) -> tuple[np.ndarray, dict] | None:
    """Mitsuba's image of ``scene`` and its metadata, from the cache or rendered and cached.

    With ``compute=False`` a missing image is not rendered: the result is None.
    ``meta.json`` holds the key, the settings, the Mitsuba version, the variant, the
    image size and the render's wall seconds.

    The Mitsuba version is checked as the image is read, not in the key (which needs no Mitsuba, so that a
    cached image is used where Mitsuba is not installed, :class:`tlm.experiments.error_cost_truth.Truth`, and
    entries cached before this check are found): one rendered by another version than the one installed
    (``pip install -U mitsuba``) is not used (None with ``compute=False``) but rendered again and
    replaced, said once per image in this process; without Mitsuba the cached one is used as it is.

    A cache that cannot be written (read-only, full, a file in the way) loses no image: the
    one rendered is returned all the same (as float32, as a cached one is), for this run
    only, and :mod:`tlm.caches` says once on stderr which cache could not be written and
    what that costs (every run renders it again); no traceback.
    """
    _check_settings(integrator, spp, max_depth, seed)
    key = oracle_key(scene, integrator=integrator, spp=spp, max_depth=max_depth, seed=seed, normals=normals)
    cached = load_ground_truth(key)
    if cached is not None and _other_version(cached[1]):
        cached = None
    if cached is not None or not compute:
        return cached
    t0 = time.perf_counter()
    image = render(scene, integrator=integrator, spp=spp, max_depth=max_depth, seed=seed, normals=normals)
    meta = {
        "scene": scene.name,
        "integrator": integrator,
        "spp": int(spp),
        "max_depth": int(max_depth),
        "seed": int(seed),
        "width": int(scene.camera.width),
        "height": int(scene.camera.height),
        "mitsuba_version": mitsuba_version(),
        "variant": VARIANT,
        "mapping": MAPPING_VERSION,
        "seconds": round(time.perf_counter() - t0, 3),
    }
    try:
        save_ground_truth(key, image, meta)
    except (EnvironmentFailure, OSError, InputError):  # (a read-only or full cache, or something in the way of
        # the entry's folder: storage.check_destination; said once by caches.cache_failed)
        return np.asarray(image, dtype=np.float32).astype(np.float64), {"key": key, **meta}
    return load_ground_truth(key)


_OTHER_SAID: set[str] = set()  # the ground truths of another Mitsuba said in this process (_other_version)


def _other_version(meta: dict) -> bool:
    """Whether the cached ground truth of ``meta`` was rendered by another Mitsuba than the one installed (said
    once per key in this process); False where Mitsuba is not installed (nothing can render it again)."""
    try:
        now = mitsuba_version()
    except InputError:
        return False
    was = meta.get("mitsuba_version")
    if was == now:
        return False
    if meta.get("key") not in _OTHER_SAID:
        _OTHER_SAID.add(meta.get("key"))
        warn(f"the Mitsuba ground truth {meta.get('key')} cached in {cache_dir()} was rendered by Mitsuba "
             f"{was}, not by the Mitsuba installed ({now}): not used; rendered again by this one where it is "
             "computed")
    return True


def away_from_lights(sees_light: np.ndarray) -> np.ndarray:
    """(height, width) bool: the pixels to compare, given which pixels see a light, directly
    or as a highlight in a mirror or glass (any of their eye rays; the renderer's
    :func:`tlm.render.passes.sees_a_light`): those and their 8 neighbours are left out. A
    light's radiance is hundreds of times a lit wall's, so its edge pixels (Mitsuba's
    emitter sits a hair in front of the ceiling, its film box-filters the edge, our four
    samples per pixel see it in steps of a quarter) would dominate a sum of squared errors
    (on Cornell, 20 highlight pixels on the mirror sphere held 95% of the error of the
    pixels that see the spheres) and, in a relative MSE's denominator, dilute every other
    error."""
    from scipy import ndimage

    return ~ndimage.binary_dilation(np.asarray(sees_light, dtype=bool), structure=np.ones((3, 3), dtype=bool))


def truth_mask(frame, sees_light: np.ndarray, supersample: int = 4) -> np.ndarray:
    """:func:`away_from_lights` of the pixels our eye rays see a light at (``sees_light``) and of
    those whose whole square shows one (:func:`tlm.oracle.masks.light_footprint`): what Mitsuba's
    box filter sees of a highlight our few samples miss is left out too (h472)."""
    from tlm.oracle.masks import light_footprint

    seen = np.asarray(sees_light, dtype=bool) | light_footprint(frame, supersample)
    return away_from_lights(seen)


DOMINANT_SHARE = 0.5  # one pixel carrying more than this share of the squared error is named


def dominant_pixel(test, reference, keep) -> str | None:
    """A warning line where one pixel of ``keep`` carries more than :data:`DOMINANT_SHARE` of the
    summed squared error of ``test`` against ``reference`` (the relative MSE is then that pixel's,
    not the image's), naming it (x, y) with both values; else None."""
    t, r = _pair(test, reference)
    keep = np.asarray(keep, dtype=bool)
    err = np.where(keep, ((t - r) ** 2).sum(axis=-1), 0.0)
    total = float(err.sum())
    if not total > 0:
        return None
    y, x = np.unravel_index(int(np.argmax(err)), err.shape)
    share = float(err[y, x]) / total
    if share <= DOMINANT_SHARE:
        return None
    return (f"one pixel, (x {x}, y {y}), carries {share:.0%} of the squared error against the truth (truth "
            f"{float(r[y, x].mean()):.4g}, ours {float(t[y, x].mean()):.4g}): the relative MSE is mostly that pixel's")


PTRACER_FACTOR = 4  # light paths per pixel of the particle tracer, per sample of the path tracer


def needs_light_tracing(scene: Scene) -> bool:
    """Whether the path tracer misses light the scene has: caustics of a point, spot or
    directional light.

    A path traced from the eye reaches such a light (a delta light) only by a shadow ray from
    a diffuse point; a path that meets a mirror or glass after the diffuse point can never hit
    a delta light, so the caustics a point light casts through mirrors and glass (the
    ring's cardioid, the room's) are missing from Mitsuba's ``path`` image.
    """
    point = any(light.kind in ("point", "spot", "directional") for light in scene.lights)
    return point and any(m.kind != "lambertian" for m in scene.materials)


def composite_truth(scene: Scene, diffuse: np.ndarray, spp: int = 4096, seed: int = 0,
                    compute: bool = True, light_tracing: bool | None = None) -> tuple[np.ndarray, dict] | None:
    """The ground truth of ``scene``: Mitsuba's path tracer, and where the path tracer
    misses light (:func:`needs_light_tracing`), its particle tracer at the pixels whose
    eye rays all meet a diffuse surface (``diffuse``, (height, width) bool), which it
    renders completely (every light path ending on a diffuse surface seen by the camera,
    caustics of point lights included) and ``PTRACER_FACTOR x spp`` light paths per pixel.
    ``light_tracing``: None = when :func:`needs_light_tracing`; False = the path tracer
    alone (the particle tracer converges slowly in a closed room: on the room scene at
    320x240, 16384 light paths per pixel were 2.3 hours away on this machine), which
    ``meta["missing"]`` then says. None when ``compute`` is False and an image is missing.
    """
    path = ground_truth(scene, "path", spp=spp, seed=seed, compute=compute)
    needed = needs_light_tracing(scene)
    if path is None or not needed or light_tracing is False:
        if path is not None and needed:
            path = (path[0], {**path[1], "missing": "caustics of point lights through mirrors and glass (no "
                              "eye path reaches them; the particle tracer was not asked for)"})
        return path
    light = ground_truth(scene, "ptracer", spp=PTRACER_FACTOR * spp, seed=seed, compute=compute)
    if light is None:
        return None
    mask = np.asarray(diffuse, dtype=bool)[..., None]
    image = np.where(mask, light[0], path[0])
    meta = {**path[1], "integrator": "path + ptracer", "ptracer": light[1],
            "ptracer_pixels": float(mask.mean())}
    return image, meta


# --------------------------------------------------------------------------- error metrics


def _pair(test, reference) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(test, dtype=np.float64)
    r = np.asarray(reference, dtype=np.float64)
    if t.shape != r.shape:
        raise ValueError(f"test {t.shape} and reference {r.shape} differ in shape")
    return t, r


def rel_mse_per_pixel(test, reference) -> float:
    """Per-pixel relative MSE: the mean over pixels and channels of ``(test - ref)^2 / (ref^2 + eps)``,
    the relMSE of many rendering papers. Not the ``rel_mse`` of tlm's runs, studies and reports
    (:func:`tlm.experiments.reference.image_error`: ``sum (test - ref)^2 / sum ref^2``, which weighs a
    pixel by its brightness). ``rel_mse`` is its old name, kept.

    ``eps = REL_MSE_EPS * mean(ref)^2`` with :data:`REL_MSE_EPS` = 1e-2: a pixel darker
    than a tenth of the image's mean is measured against that tenth instead of against
    its own (near-zero) value, so black and nearly black pixels (shadows, the sky) do not
    dominate the mean with huge ratios, while every lit pixel counts relatively.
    """
    t, r = _pair(test, reference)
    eps = REL_MSE_EPS * float(np.mean(r)) ** 2
    if not eps > 0:
        raise ValueError("rel_mse_per_pixel needs a reference with a positive mean")
    return float(np.mean((t - r) ** 2 / (r**2 + eps)))


rel_mse = rel_mse_per_pixel  # (its old name: the per-pixel relMSE, not the rel_mse of tlm's runs and reports)


def mean_normalised_rel_rmse(test, reference, mask=None) -> float:
    """``sqrt(mean((test - ref)^2)) / mean(ref)`` over the pixels of ``mask`` (all channels).

    mask : optional (height, width) bool, the pixels to compare (e.g. not the lights).
    """
    t, r = _pair(test, reference)
    if mask is not None:
        m = np.asarray(mask, dtype=bool)
        if m.shape != t.shape[:-1]:
            raise ValueError(f"mask {m.shape} does not match the images {t.shape[:-1]}")
        t, r = t[m], r[m]
    return float(np.sqrt(np.mean((t - r) ** 2)) / np.mean(r))


def flip(test, reference, exposure: float | None = None) -> float:
    """Mean FLIP error (0 = identical, 1 = maximal) of two linear (height, width, 3) images.

    ``exposure=None``: HDR-FLIP (``flip_evaluator``) on the linear radiance, with FLIP's
    own exposure range (start and stop exposures computed from the reference: the result
    does not change when both images are scaled, except where more than half the reference
    is so dark that the stop exposure is pinned by its floor, 2**-23 of luminance, below
    which, at the peak, flip_evaluator aborts the process) and its defaults (ACES tone
    mapper, 67 pixels per degree). It takes about 0.5 s at 320x320 on one core.
    ``exposure`` given: LDR-FLIP of the pictures we write, both images tone-mapped by
    :func:`tlm.render.image.to_srgb8` at that one exposure (e.g.
    ``auto_exposure(reference)``), so errors above the clipped white do not count.
    """
    t, r = _pair(test, reference)
    if t.ndim != 3 or t.shape[-1] != 3:
        raise ValueError(f"flip needs (height, width, 3) images, got {t.shape}")
    if not (np.isfinite(t).all() and np.isfinite(r).all()):
        raise ValueError("flip needs finite images")
    try:
        import flip_evaluator
    except ImportError:
        raise InputError(f"FLIP needs the optional package flip-evaluator ({INSTALL_HINT})", key="oracle") from None
    if exposure is None:
        pair = (np.maximum(r, 0.0).astype(np.float32), np.maximum(t, 0.0).astype(np.float32))
        _, mean, _ = flip_evaluator.evaluate(*pair, "HDR", applyMagma=False)
    else:
        from tlm.render.image import to_srgb8

        pair = (to_srgb8(r, exposure).astype(np.float32) / 255.0, to_srgb8(t, exposure).astype(np.float32) / 255.0)
        _, mean, _ = flip_evaluator.evaluate(*pair, "LDR", applyMagma=False)
    return float(mean)
