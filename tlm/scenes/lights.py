"""The scene's lights: a scene file's ``lights:`` list checked and built, the point, spot and
directional lights of its mesh files used when it gives no ``lights:``, and the ``mesh`` light
of its emitting triangles.

:func:`scene_lights` reads the ``lights:`` list (each item a ``point``, ``quad``, ``spot`` or
``directional`` light of :data:`LIGHT_KEYS`, each with an optional ``name``), or, without the
key, takes the lights the geometry's mesh files import (:attr:`~tlm.scenes.model.Geometry.imports`), with a line per
mesh file saying which. Every problem is an :class:`~tlm.errors.InputError` naming the
file, the key and the value. The scene loader (:mod:`tlm.scenes.loader`) calls it.
"""

from __future__ import annotations

import datetime
import math
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from tlm.config_words import listing, value_text
from tlm.errors import InputError, did_you_mean, quoted
from tlm.scenes.model import Geometry, Imported, Light, Material, Scene, directional_power, unit_vector
from tlm.scenes.validate import MAX_MAGNITUDE
from tlm.scenes.validate import keys as _keys
from tlm.scenes.validate import mapping as _mapping
from tlm.scenes.validate import num as _num
from tlm.scenes.validate import vec as _vec

LIGHT_KEYS = {"quad": ("type", "corner", "edge_u", "edge_v", "power"), "point": ("type", "position", "power"),
              "spot": ("type", "position", "direction", "power", "intensity", "inner_cone_angle", "outer_cone_angle"),
              "directional": ("type", "direction", "irradiance")}
_POWER = "[r, g, b] in W, each >= 0"
_POINT = "[x, y, z]"
_DIRECTION = "[x, y, z], not zero"
# the keys each light type cannot do without, and what they take (a spot's power may be given as intensity)
LIGHT_REQUIRED = {
    "point": (("position", _POINT), ("power", _POWER)),
    "quad": (("corner", _POINT), ("edge_u", "[x, y, z]"), ("edge_v", "[x, y, z]"), ("power", _POWER)),
    "spot": (("position", _POINT), ("direction", _DIRECTION + " (the way it shines)"),
             ("power", f"{_POWER} (4 pi x its intensity), or intensity: [r, g, b] in W/sr")),
    "directional": (("direction", _DIRECTION + " (the way its light travels)"),
                    ("irradiance", "[r, g, b] in W per unit area, each >= 0")),
}
# a key every type takes: the light's name (Light.name; optional), which says where it comes from (an exported glTF
# light's ``FILE KHR_lights_punctual.lights[i] 'NAME' at nodes[n]``: tlm.scenes.export) and its from shows
LIGHT_NAME = "name"
SPOT_ANGLES = (0.0, 45.0)  # a spot's default inner_cone_angle and outer_cone_angle (degrees; glTF's 0 and pi / 4)


def typed(raw: Any, src: str, key: str, allowed: dict[str, tuple[str, ...]]) -> tuple[dict, str]:
    """A mapping with a ``type`` among ``allowed``'s keys and only that type's keys (a light's:
    :data:`LIGHT_KEYS`; a material's: the loader's ``MATERIAL_KEYS``)."""
    raw = _mapping(raw, src, key)
    kind = raw.get("type")
    if kind is None:  # (absent, or "type:" with nothing after it)
        raise InputError(f"missing; give one of {', '.join(allowed)}", source=src, key=f"{key}.type")
    if not isinstance(kind, str) or kind not in allowed:
        said = repr(kind) if isinstance(kind, str) else value_text(kind)  # (not a string: as YAML writes it)
        hint = did_you_mean(kind, allowed) if isinstance(kind, str) else ""
        raise InputError(f"type {said} is not one of {', '.join(allowed)}{hint}", source=src, key=key)
    _keys(raw, allowed[kind], src, key)
    return raw, kind


def mesh_light(triangles: np.ndarray, material_index: np.ndarray, materials: tuple[Material, ...]) -> Light | None:
    """The scene's emitting triangles as one ``mesh`` light, or None when none emits.

    Triangles of zero area are left out (they emit nothing). The power is
    ``pi * sum(Le * area)``: a Lambertian emitter's radiant exitance is ``pi Le``.
    """
    emits = np.array([m.emits for m in materials], dtype=bool)
    ids = np.flatnonzero(emits[material_index])
    if ids.shape[0] == 0:
        return None
    tri = np.ascontiguousarray(triangles[ids], dtype=np.float64)
    areas = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    keep = areas > 0
    ids, tri, areas = ids[keep], tri[keep], areas[keep]
    if ids.shape[0] == 0:
        return None
    le = np.array([m.emission for m in materials], dtype=np.float64)[material_index[ids]]
    power = np.pi * (le * areas[:, None]).sum(axis=0)
    names = [materials[i].name for i in np.unique(material_index[ids])]
    return Light("mesh", tuple(float(x) for x in power), name=", ".join(names), materials=tuple(names),
                 ids=ids.astype(np.int64), triangles=tri, radiance=le)


def with_mesh_light(scene: Scene) -> Scene:
    """``scene`` with its mesh light (the emitting triangles) rebuilt from its geometry, and its
    directional lights' power set from its triangles' box (:func:`~tlm.scenes.model.directional_power`)."""
    lights = tuple(lt for lt in scene.lights if lt.kind != "mesh")
    if any(lt.kind == "directional" for lt in lights):
        lo, hi = scene.bounds()
        lights = tuple(replace(lt, power=directional_power(lt.irradiance, lo, hi)) if lt.kind == "directional"
                       else lt for lt in lights)
    light = mesh_light(scene.triangles, scene.material_index, scene.materials)
    return replace(scene, lights=lights if light is None else (*lights, light))


def own_points(lt: Light, pt: Callable[[Any], tuple], vec: Callable[[Any], tuple]) -> dict[str, tuple]:
    """A point, spot, quad or directional light's own points mapped by ``pt`` and its own lengths by ``vec``,
    as fields for :func:`dataclasses.replace`: a point's or spot's ``position``, a quad's ``corner`` (``pt``)
    and ``edge_u`` and ``edge_v`` (``vec``); none of a directional light's (its ``direction`` a way, not a
    length). A field its kind does not have is not among them (:func:`scaled_light`; the Mitsuba writer's
    frame, :func:`tlm.oracle.mitsuba.scene_dict`)."""
    if lt.kind == "quad":
        return {"corner": pt(lt.corner), "edge_u": vec(lt.edge_u), "edge_v": vec(lt.edge_v)}
    if lt.kind in ("point", "spot"):
        return {"position": pt(lt.position)}
    return {}


def scaled_light(lt: Light, scale: float, translate: np.ndarray) -> Light:
    """A point, spot, quad or directional light of a scene scaled about the origin by ``scale``, then
    moved by ``translate`` (:func:`tlm.scenes.loader.transform_scene`): its power times ``scale**2`` (its
    radiance, so the image, unchanged; a directional light's is set again from the scene's box,
    :func:`with_mesh_light`) and its kind's own points moved: a point's or spot's ``position``, a quad's
    ``corner`` (its edges scaled). A field its kind does not have is left as it is: moved, a quad's
    ``position`` (0, 0, 0) became the translation, a value no scene file gives, so that the scene
    exported (:func:`tlm.scenes.export.scene_yaml`) loaded back as another Light."""
    def pt(p) -> tuple[float, float, float]:
        return tuple(float(x) for x in np.asarray(p) * scale + translate)

    def vec(v) -> tuple[float, float, float]:
        return tuple(float(x) for x in np.asarray(v) * scale)

    return replace(lt, power=tuple(float(x) * scale**2 for x in lt.power), **own_points(lt, pt, vec))


def unit_direction(v: tuple[float, float, float], src: str, key: str) -> tuple[float, float, float]:
    """``v`` itself, or an InputError when it is no direction (zero: it has no length,
    :func:`~tlm.scenes.model.unit_vector`)."""
    if unit_vector(v) is None:
        raise InputError(f"{list(v)} is no direction (it has no length)", source=src, key=key)
    return tuple(float(x) for x in v)


def _spot(raw: dict, key: str, src: str) -> Light:
    position = _vec(raw.get("position"), src, f"{key}.position")
    direction = unit_direction(_vec(raw.get("direction"), src, f"{key}.direction"), src, f"{key}.direction")
    if "power" in raw and "intensity" in raw:
        raise InputError("give power or intensity, not both (power = 4 pi x intensity)", source=src, key=key)
    if "intensity" in raw:
        power = tuple(4.0 * math.pi * x for x in _vec(raw["intensity"], src, f"{key}.intensity", lo=0.0))
    else:
        power = _vec(raw.get("power"), src, f"{key}.power", lo=0.0)
    inner = _num(raw.get("inner_cone_angle", SPOT_ANGLES[0]), src, f"{key}.inner_cone_angle", lo=0.0, hi=90.0)
    outer = _num(raw.get("outer_cone_angle", SPOT_ANGLES[1]), src, f"{key}.outer_cone_angle", lo=0.0, hi=90.0,
                 lo_exclusive=True)
    if not inner < outer:
        raise InputError(f"{inner:g} must be less than outer_cone_angle ({outer:g} degrees"
                         f"{'' if 'outer_cone_angle' in raw else ', the default'})", source=src,
                         key=f"{key}.inner_cone_angle")
    light = Light("spot", power, position=position, direction=direction, inner_angle=inner, outer_angle=outer)
    ci, co = light.cone_cosines
    if not ci > co:
        raise InputError(f"inner_cone_angle {inner:g} and outer_cone_angle {outer:g} are too close: their cosines "
                         "are equal in float64", source=src, key=key)
    return light


def _light(i: int, raw: Any, src: str) -> Light:
    """The scene file's ``lights[i]``, named by its ``name:`` where it gives one."""
    key = f"lights[{i}]"
    raw, kind = typed(raw, src, key, {k: (*v, LIGHT_NAME) for k, v in LIGHT_KEYS.items()})
    name = raw.get(LIGHT_NAME, "")
    if not isinstance(name, str):  # (a date as written, 2020-01-01: not '2020-01-01', a string)
        said = name.isoformat() if isinstance(name, datetime.date) else value_text(name)
        raise InputError(f"{said} is not text (the light's name: quote it, name: \"...\")", source=src,
                         key=f"{key}.name")
    return replace(_unnamed(i, raw, src, kind), name=name)


def _unnamed(i: int, raw: dict, src: str, kind: str) -> Light:
    key = f"lights[{i}]"
    for need, what in LIGHT_REQUIRED[kind]:
        if need not in raw and not (kind == "spot" and need == "power" and "intensity" in raw):
            raise InputError(f"required for type {kind}: {what}", source=src, key=f"{key}.{need}")
    if kind == "spot":
        return _spot(raw, key, src)
    if kind == "directional":
        direction = unit_direction(_vec(raw.get("direction"), src, f"{key}.direction"), src, f"{key}.direction")
        irradiance = _vec(raw.get("irradiance"), src, f"{key}.irradiance", lo=0.0)
        return Light("directional", (0.0, 0.0, 0.0), direction=direction, irradiance=irradiance)
    power = _vec(raw.get("power"), src, f"{key}.power", lo=0.0)
    if kind == "point":
        return Light(kind, power, position=_vec(raw.get("position"), src, f"{key}.position"))
    light = Light(
        kind, power,
        corner=_vec(raw.get("corner"), src, f"{key}.corner"),
        edge_u=_vec(raw.get("edge_u"), src, f"{key}.edge_u"),
        edge_v=_vec(raw.get("edge_v"), src, f"{key}.edge_v"),
    )
    size = np.linalg.norm(light.edge_u) * np.linalg.norm(light.edge_v)
    if not light.area > 1e-12 * size or size == 0.0:
        raise InputError("edge_u and edge_v span no area", source=src, key=key)
    return light


def _grouped(geom: Geometry) -> dict[str, list[Imported]]:
    """The geometry's imports by mesh file (two items of one file: two entries)."""
    out: dict[str, list[Imported]] = {}
    for imp in geom.imports:
        out.setdefault(imp.source, []).append(imp)
    return out


_KIND_ORDER = ("point", "spot", "directional")


def _kinds(imps: list[Imported]) -> list[str]:
    """The kinds of a file's imported lights, in order."""
    return [lt.kind for i in imps for lt in i.lights]


def _imported_lights(imps: list[Imported]) -> str:
    """``N point light(s) (KHR_lights_punctual.lights[0] 'lamp' at nodes[2], ...)`` of a file's imports
    (``N lights (1 point and 1 spot: ...)`` of several kinds)."""
    names = list(dict.fromkeys(lt.name.removeprefix(f"{Path(imps[0].source).name} ") for i in imps
                               for lt in i.lights))
    kinds = _kinds(imps)
    n = len(kinds)
    shown = listing(names, 4)
    items = f", in each of its {len(imps)} geometry items" if len(imps) > 1 else ""
    counts = [(k, kinds.count(k)) for k in _KIND_ORDER if k in kinds]
    if len(counts) == 1:
        return f"{f'{n} {kinds[0]} lights' if n > 1 else f'{kinds[0]} light'} ({shown}{items})"
    return f"{n} lights ({listing(f'{c} {k}' for k, c in counts)}: {shown}{items})"


def _imported_as(imps: list[Imported]) -> str:
    """``a tlm point light (power 4 pi x intensity x color W)``: what a file's imported lights become."""
    kinds = _kinds(imps)
    present = [k for k in _KIND_ORDER if k in kinds]
    if len(present) == 1:
        what = f"tlm {present[0]} lights" if len(kinds) > 1 else f"a tlm {present[0]} light"
    else:
        what = "tlm lights of their kinds"
    units = []
    if "point" in present or "spot" in present:
        units.append("power 4 pi x intensity x color W")
    if "directional" in present:
        units.append("irradiance intensity x color W per unit area")
    return f"{what} ({'; '.join(units)})"


def _placed(lt: Light, where: str, file: str) -> Light:
    """An imported light, checked (its position and direction as the geometry item's transform
    left them: :mod:`tlm.scenes.compose`)."""
    p = np.asarray(lt.position)
    if not (np.isfinite(p).all() and np.abs(p).max() <= MAX_MAGNITUDE):
        raise InputError(f"{where}: its position {list(lt.position)} (with the geometry item's transform) "
                         f"is not finite or is beyond +-{MAX_MAGNITUDE:g}", source=file)
    if not max(lt.power) <= MAX_MAGNITUDE:
        raise InputError(f"{where}: its power {list(lt.power)} W is beyond {MAX_MAGNITUDE:g}", source=file)
    if not max(lt.irradiance) <= MAX_MAGNITUDE:
        raise InputError(f"{where}: its irradiance {list(lt.irradiance)} is beyond {MAX_MAGNITUDE:g}", source=file)
    if lt.kind in ("spot", "directional") and unit_vector(lt.direction) is None:
        raise InputError(f"{where}: the geometry item's transform leaves it no direction", source=file)
    return lt


def _entry(lt: Light, where: str) -> Light:
    """A scene file's light with its origin: its entry, ``FILE: lights[i]``, and its name where it has one
    (``FILE: lights[i] 'NAME'``, as a glTF's ``KHR_lights_punctual.lights[i] 'NAME'``)."""
    return replace(lt, origin=f"{where} {quoted(lt.name)}" if lt.name else where)


def scene_lights(raw: dict, geom: Geometry, src: str, given_by: str = "") -> tuple[tuple[Light, ...], list[str]]:
    """The scene's lights: the scene file's ``lights:`` when it gives the key (itself or through
    ``extends``: ``given_by``, the file of the chain that gave it, default ``src``), else the mesh files'
    point, spot and directional lights (:attr:`Geometry.imports`); and a line per mesh file with such
    lights saying which it is. Each light's :attr:`~tlm.scenes.model.Light.origin` names its entry:
    ``FILE: lights[i]``, or the mesh file (its path, as a glTF material's ``from`` has it) and its
    light's name (``KHR_lights_punctual.lights[i] 'NAME' at nodes[n]``)."""
    notes = []
    if "lights" in raw:
        lights_raw = raw.get("lights") or []
        if not isinstance(lights_raw, list):
            raise InputError(f"must be a list, got {lights_raw!r}", source=src, key="lights")
        for file, imps in _grouped(geom).items():
            if any(i.lights for i in imps):
                k = len(_kinds(imps))
                notes.append(f"{file}: its {_imported_lights(imps)} {'are' if k > 1 else 'is'} not used: the scene "
                             f"file gives lights: (leave lights: out to import {'them' if k > 1 else 'it'})")
        return tuple(_entry(_light(i, v, src), f"{given_by or src}: lights[{i}]")
                     for i, v in enumerate(lights_raw)), notes
    lights = []
    for file, imps in _grouped(geom).items():
        if not any(i.lights for i in imps):
            continue
        for lt in (lt for i in imps for lt in i.lights):
            label = lt.name.removeprefix(f"{Path(file).name} ")
            lights.append(replace(_placed(lt, label, file), origin=f"{file} {label}"))
        k = len(_kinds(imps))
        notes.append(f"{file}: its {_imported_lights(imps)} {'are' if k > 1 else 'is'} imported as "
                     f"{_imported_as(imps)}: the scene file gives no lights:")
    return tuple(lights), notes
