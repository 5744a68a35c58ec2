"""tlm's Python API, its scenes: the built-in scenes listed and described (``tlm scene list``), a
scene loaded by name or file (:func:`load_scene`), shown (``tlm scene show``) and exported
(``tlm scene export``).

Read them from :mod:`tlm.api` (or ``tlm``), which re-exports them: ``tlm.load_scene is
tlm.api.load_scene``. Bad input raises :class:`~tlm.errors.InputError`, and a layer is imported when
a function first needs it, whole (:func:`tlm.whole_imports.imports_whole`), as in :mod:`tlm.api`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from tlm.api_common import argument_names, checked, existing_folder, flags_are_kept
from tlm.api_common import shown as _shown
from tlm.api_studies import expanded
from tlm.config import plain, read_yaml
from tlm.errors import InputError, did_you_mean
from tlm.whole_imports import imports_whole

if TYPE_CHECKING:
    from tlm.scenes.model import Scene


@argument_names
def list_scenes(*, bad: bool = False) -> list[str]:
    """The built-in scene names (what a config's ``scene:`` may name), as ``tlm scene list`` lists them:
    not the scenes of bad input on purpose (tests of tlm's error messages, ``extreme/bad_scale_zero``,
    which fail to load), which ``bad=True`` lists too (``tlm scene list --all``)."""
    from tlm.scenes.loader import list_scenes as names
    from tlm.scenes.loader import listed_scenes

    # (the command line's tlm scene list leaves those out itself, and lists them with --all)
    return names() if checked(bad, "bad", bool) or flags_are_kept() else listed_scenes()


@argument_names
def scene_description(name: str) -> str:
    """A built-in scene's ``description:``, else the first sentence of its leading comment
    lines, which may run over several ("" when it has neither; cheap: reads no geometry)."""
    from tlm.builtin import comment_description
    from tlm.scenes.loader import list_scenes as every
    from tlm.scenes.loader import scenes_dir

    names = every()
    if not isinstance(name, str) or name not in names:
        from tlm.config_paths import scene_file_named

        found = scene_file_named(name, [Path.cwd()])  # (a scene file of that name here: what reads it, h455)
        hint = "" if found is None else (f"; a scene file of that name lies at {found[0]}, which scene_description "
                                         f"does not describe (the built-in scenes alone): load_scene({found[1]!r}) "
                                         "reads it")
        raise InputError(f"{_shown(name)} is not a built-in scene ({', '.join(names)}){did_you_mean(str(name), names)}"
                         f"{hint}", key="scene")
    path = scenes_dir() / f"{name}.yaml"
    try:
        raw = read_yaml(path)
        if isinstance(raw, dict) and isinstance(raw.get("description"), str):
            return raw["description"]
        return comment_description(path.read_text(encoding="utf-8"))
    except (InputError, OSError, UnicodeDecodeError):
        return ""


@argument_names
@imports_whole
def load_scene(scene: str | Path, *, base: str | Path | None = None, resolution: list[int] | None = None) -> Scene:
    """A built-in scene by name (``cornell``) or a scene file by path (relative to ``base``,
    default the working folder), at its own resolution or ``[width, height]``."""
    from tlm.scenes.loader import load_scene as load
    from tlm.scenes.loader import resolve_scene_path

    if not isinstance(scene, (str, os.PathLike)):  # (named by its type, not taken for a scene's name: str(5))
        raise InputError(f"{_shown(scene)} is not a scene's name or path: give a built-in scene's name "
                         "(tlm.list_scenes()) or a scene file's path", key="scene")
    if base is not None and not isinstance(base, (str, os.PathLike)):
        raise InputError(f"{_shown(base)} is not a folder's path (None: the working folder)", key="base")
    scene, base = expanded(scene, "scene"), expanded(base, "base")  # (~: the home folder, as every path argument's)
    existing_folder(base, "base")  # (as load_config: a relative scene path looked for nowhere is not "not found")
    folder = Path(base) if base is not None else Path.cwd()
    # a scene not found is named as given (as 'tlm run NAME' names its NAME), a bad resolution as this call's;
    # (a numpy array or a tuple reads as the list it holds, as in load_config)
    path = resolve_scene_path(str(scene), folder, config_source=str(scene))
    if path.is_symlink() and path.resolve().is_file():  # (/dev/stdin < my.yaml: its meshes from my.yaml's folder,
        path = path.resolve()  # as tlm run reads a scene file it is given, not /dev's)
    return load(path, folder, None if resolution is None else plain(resolution), config_source="(load_scene)")


def _scene(scene: Scene | str | Path) -> Scene:
    """The scene named, loaded; or the Scene given, checked as a loaded one is (one made or changed
    in Python: NaN or infinite vertices are an InputError naming it, :func:`tlm.scenes.export.check_scene`)."""
    from tlm.scenes.export import check_scene
    from tlm.scenes.model import Scene

    if isinstance(scene, (str, os.PathLike)):
        return load_scene(scene)
    if not isinstance(scene, Scene):
        raise InputError(f"{_shown(scene)} is not a scene: give a Scene, a built-in scene's name or a scene "
                         "file's path", key="scene")
    check_scene(scene)
    return scene


@argument_names
@imports_whole
def scene_info(scene: Scene | str | Path) -> dict:
    """What ``tlm scene show`` prints: triangles, bounds, resolution, photons, materials,
    parts, lights and camera of a scene (or of the scene named), and ``notes``: the lines
    on what its mesh files gave that was imported or left out, which a run warns of. Each
    material gives ``from`` where its values' source is known (:attr:`Material.origin`, as in
    ``results.json``). Each
    light is its ``type``, ``power`` and its kind's own fields: a point light's ``position``;
    a spot's ``position``, ``direction``, ``inner_cone_angle`` and ``outer_cone_angle``
    (degrees); a directional light's ``direction`` and ``irradiance``; a quad's ``corner``,
    ``edge_u``, ``edge_v`` and ``area``; a mesh light's ``materials``, ``triangles`` and
    ``area``."""
    from tlm.experiments.run import scene_head

    scene = _scene(scene)
    head, used = scene_head(scene, lambda lo, hi: {"min": lo.tolist(), "max": hi.tolist()})
    return {
        **head,
        "materials": [
            {"name": m.name, "type": m.kind, "triangles": int(used[i]),
             **({"albedo": list(m.albedo)} if m.kind == "lambertian" else {}),
             **({"reflectance": list(m.reflectance)} if m.kind == "mirror" else {}),
             **({"ior": m.ior, "transmittance": list(m.transmittance)} if m.kind == "dielectric" else {}),
             **({"emission": list(m.emission)} if m.emits else {}),
             **({"ignored": list(m.ignored)} if m.ignored else {}),  # (not rendered: checks.material_warnings)
             **({"from": m.origin} if m.origin else {})}  # (where its values come from: Material.origin)
            for i, m in enumerate(scene.materials)
        ],
        "parts": {p: int((scene.part == i).sum()) for i, p in enumerate(scene.part_names)},
        "lights": [lt.info() for lt in scene.lights],
        "camera": {"eye": list(scene.camera.eye), "target": list(scene.camera.target),
                   "up": list(scene.camera.up), "vfov": scene.camera.vfov},
        "notes": [str(n) for n in scene.extra.get("notes") or []],
    }


@argument_names
@imports_whole
def export_scene(scene: Scene | str | Path, file: str | Path) -> Scene:
    """Write a scene's world-space triangles, in triangle-id order, as ``.ply`` or ``.obj``,
    or the whole scene as a scene file ``.yaml`` (with its ``.obj`` and ``.mtl`` beside it:
    :mod:`tlm.scenes.export`); returns the scene as written: in a ``.yaml`` or ``.obj``, only the materials
    its triangles take (:func:`tlm.scenes.export.used_materials`: one no triangle takes, such as a base's that the
    file's ``geometry:`` left unused, is not written), in a ``.ply`` every material, named by its index. A Scene
    that no scene file could hold (NaN or infinite vertices, as one made with ``dataclasses.replace`` may have) is
    an InputError naming it and its first such triangle, as the loader names a file's, and nothing is written."""
    from tlm.scenes.export import export_triangles

    scene = _scene(scene)
    if not isinstance(file, (str, os.PathLike)):
        raise InputError(f"{_shown(file)} is not a file path (.ply, .obj or .yaml)", key="file")
    return export_triangles(scene, Path(expanded(file, "file")))
