"""A scene file whose ``geometry:`` replaces its base's but lists the base's parts again (its mesh files, its
builder, its shapes) keeps a base's ``parts:`` typo (a part name that matches nothing) the base's error, as a
file that only transforms the geometry does (tlm.scenes.chain.stale_parts): the part names of a listed item are
known without building the base's geometry (a shape's from its kind and ``name``, a mesh file's or a builder's
from the same item in the new geometry). An entry for a part the base's geometry had and the new one lacks stays
a note, as does one where a part of the base's geometry cannot be known so (a mesh file no longer listed).
``tlm scene export`` of such a file writes the materials its triangles use, not the base's unused ones as the
file's own: the exported file loads as the same scene, without notes, and exports again to the same files."""

from __future__ import annotations

import numpy as np
import yaml

from tlm.api import export_scene, load_scene
from tlm.cli import main

MATERIALS = ("materials:\n  grey: {type: lambertian, albedo: [0.5, 0.5, 0.5]}\n"
             "  red: {type: lambertian, albedo: [0.6, 0.1, 0.1]}\n"
             "  chrome: {type: mirror, reflectance: [0.9, 0.9, 0.9]}\n")
VIEW = ("camera: {eye: [0.0, 1.0, 5.0], target: [0.0, 0.0, 0.0], up: [0.0, 1.0, 0.0], vfov: 40.0}\n"
        "resolution: [16, 12]\nlights: [{type: point, position: [0.0, 3.0, 0.0], power: [10.0, 10.0, 10.0]}]\n")
SPHERE = "{shape: sphere, name: ball, params: {radius: 0.2, segments: 8, rings: 4}}"


def _write(path, text: str):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def _meshes(tmp_path) -> None:
    _write(tmp_path / "m" / "floor.obj", "v -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\nf 1 2 3\nf 1 3 4\n")
    _write(tmp_path / "m" / "box.obj", "v 0 0 0\nv 0.5 0 0\nv 0 0.5 0\nf 1 2 3\n")


def _error(capsys, path) -> str:
    capsys.readouterr()
    assert main(["scene", "show", str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    return captured.err


def _notes(path) -> list[str]:
    return load_scene(path).extra["notes"]


def _stale(path, part: str, base) -> str:
    return (f"{path}: parts.{part} (given by {base}, through extends:): the geometry here has no part {part!r}: the "
            f"entry is not used (`parts: {{{part}: null}}` leaves it out without this note)")


def test_a_base_s_typo_stays_its_error_where_the_new_geometry_lists_the_base_s_mesh_files_again(tmp_path, capsys):
    _meshes(tmp_path)
    base = _write(tmp_path / "base" / "base.yaml", "geometry: [{mesh: ../m/floor.obj}, {mesh: ../m/box.obj}]\n"
                  f"{MATERIALS}parts: {{floor: grey, box: red, bx: chrome}}\n{VIEW}")
    line = "parts.bx: the geometry has no part 'bx' (parts: floor, box) (did you mean 'box'?)\n"
    assert _error(capsys, base) == f"tlm: error: {base}: {line}"  # (the base alone)
    # the base's mesh files listed again (one reached by another way), and a ball: the base's line, as it says it
    child = _write(tmp_path / "base" / "c.yaml", "extends: base.yaml\ngeometry: [{mesh: ../m/floor.obj}, "
                   f"{{mesh: ../base/../m/box.obj, transform: {{scale: 2.0}}}}, {SPHERE}]\nparts: {{ball: red}}\n")
    assert _error(capsys, child) == f"tlm: error: {base}: {line}"
    # through a file that only renames it: the same
    top = _write(tmp_path / "top.yaml", "extends: base/c.yaml\nname: top\n")
    assert _error(capsys, top) == f"tlm: error: {base}: {line}"
    # the base's box listed no more: its part names are not read (a mesh file the geometry no longer has): a note
    _write(child, f"extends: base.yaml\ngeometry: [{{mesh: ../m/floor.obj}}, {SPHERE}]\nparts: {{ball: red}}\n")
    assert _notes(child)[:2] == [_stale(child, "box", base), _stale(child, "bx", base)]
    # the typo fixed: the real part the new geometry lacks stays a note
    _write(base, "geometry: [{mesh: ../m/floor.obj}, {mesh: ../m/box.obj}]\n"
           f"{MATERIALS}parts: {{floor: grey, box: red}}\n{VIEW}")
    assert _notes(child)[0] == _stale(child, "box", base)


def test_a_base_s_typo_among_shapes_and_builders_is_its_error_and_a_part_gone_a_note(tmp_path, capsys):
    base = _write(tmp_path / "base.yaml", "geometry: [{shape: plane, name: floor, params: {size: [4.0, 4.0]}}, "
                  f"{{shape: box, name: block}}]\n{MATERIALS}parts: {{floor: grey, block: red, blok: chrome}}\n{VIEW}")
    # the block left out: a shape's part name is its name (or its kind), known without building it
    child = _write(tmp_path / "c.yaml", "extends: base.yaml\ngeometry: [{shape: plane, name: floor}]\n")
    assert _error(capsys, child) == (f"tlm: error: {base}: parts.blok: the geometry has no part 'blok' (parts: floor, "
                                     "block) (did you mean 'block'?)\n")
    _write(base, "geometry: [{shape: plane, name: floor, params: {size: [4.0, 4.0]}}, "
           f"{{shape: box, name: block}}]\n{MATERIALS}parts: {{floor: grey, block: red}}\n{VIEW}")
    assert _notes(child)[0] == _stale(child, "block", base)
    # a builder listed again (same builder, same params): its parts are the new geometry's
    cornell = _write(tmp_path / "cornell.yaml", "geometry: {builder: cornell}\nmaterials: {m: {type: lambertian, "
                     f"albedo: [0.5, 0.5, 0.5]}}}}\ndefault_material: m\nparts: {{flor: m}}\n{VIEW}")
    more = _write(tmp_path / "more.yaml", "extends: cornell.yaml\n"
                  f"geometry: [{{builder: cornell, transform: {{scale: 2}}}}, {SPHERE}]\n")
    assert _error(capsys, more) == (f"tlm: error: {cornell}: parts.flor: the geometry has no part 'flor' (parts: "
                                    "floor, ceiling, back_wall, left_wall, right_wall, short_block, tall_block, "
                                    "mirror_object, glass_object) (did you mean 'floor'?)\n")
    # another builder: the base's parts are not built: a note, as before
    ring = _write(tmp_path / "ring.yaml", "extends: cornell.yaml\ngeometry: {builder: ring}\n")
    assert _notes(ring)[0] == _stale(ring, "flor", cornell)
    # an entry for a part that a middle file's geometry has (not the base's own): a note where it is gone
    base = _write(tmp_path / "base.yaml", "geometry: [{shape: plane, name: floor}]\n"
                  f"{MATERIALS}parts: {{floor: grey, ball: red}}\n{VIEW}")
    mid = _write(tmp_path / "mid.yaml", f"extends: base.yaml\ngeometry: [{{shape: plane, name: floor}}, {SPHERE}]\n")
    assert load_scene(mid).extra["notes"][:1] == [
        f"{mid}: materials.chrome (given by {base}, through extends:): used by no triangle here: it is not rendered"]
    top = _write(tmp_path / "top.yaml", "extends: mid.yaml\ngeometry: [{shape: plane, name: floor}]\n")
    assert _notes(top)[0] == _stale(top, "ball", base)


def test_the_export_of_a_file_replacing_the_geometry_writes_only_the_materials_it_uses(tmp_path, capsys):
    _write(tmp_path / "base.yaml", "geometry: [{shape: plane, name: floor, params: {size: [4.0, 4.0]}}, "
                  f"{{shape: box, name: block}}]\n{MATERIALS}parts: {{floor: grey, block: red}}\n{VIEW}")
    child = _write(tmp_path / "c.yaml", "extends: base.yaml\ngeometry: [{shape: plane, name: floor}]\n"
                   "parts: {block: null}\n")
    a = load_scene(child)
    assert [m.name for m in a.materials] == ["grey", "red", "chrome"] and len(a.extra["notes"]) == 2
    out = tmp_path / "out" / "c.yaml"
    out.parent.mkdir()
    assert main(["scene", "export", str(child), str(out)]) == 0
    capsys.readouterr()
    doc = yaml.safe_load(out.read_text(encoding="utf-8"))
    assert list(doc["materials"]) == ["grey"]
    assert [s for s in out.with_suffix(".mtl").read_text(encoding="utf-8").splitlines()
            if s.startswith("newmtl")] == ["newmtl grey"]
    b = load_scene(out)
    assert b.extra["notes"] == [] and [m.name for m in b.materials] == ["grey"]
    assert np.array_equal(a.triangles, b.triangles) and a.part_names == b.part_names
    assert [a.materials[i] for i in a.material_index] == [b.materials[i] for i in b.material_index]
    assert (a.lights, a.camera, a.photons, a.name) == (b.lights, b.camera, b.photons, b.name)
    # the exported scene exports again to the same files: the same scene
    again = tmp_path / "again" / "c.yaml"
    again.parent.mkdir()
    assert main(["scene", "export", str(out), str(again)]) == 0
    for suffix in (".yaml", ".obj", ".mtl"):
        assert again.with_suffix(suffix).read_bytes() == out.with_suffix(suffix).read_bytes(), suffix
    # tlm.export_scene returns the scene as written
    assert [m.name for m in export_scene(child, tmp_path / "out" / "d.yaml").materials] == ["grey"]
    # an OBJ alone: its MTL library holds the materials the triangles use
    assert main(["scene", "export", str(child), str(tmp_path / "out" / "t.obj")]) == 0
    assert [s for s in (tmp_path / "out" / "t.mtl").read_text(encoding="utf-8").splitlines()
            if s.startswith("newmtl")] == ["newmtl grey"]
