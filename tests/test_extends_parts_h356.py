"""A scene file that extends another and gives its own ``geometry`` without some of the base's parts
(docs/scenes.md, extends): the base's ``parts:`` entries for the parts gone are not used, a note each
naming the base file and the part, not an error blaming the base (a built-in scene, in an installed
copy a file the user cannot edit); ``parts: {X: null}`` takes an inherited entry out; an entry the
extending file gives itself for a part that is not there stays its error, with a did-you-mean."""

from __future__ import annotations

import json

import pytest

from tlm.cli import main
from tlm.scenes.loader import load_scene, scenes_dir

BASE = scenes_dir() / "examples" / "mesh_on_floor.yaml"
GEOMETRY = """geometry:
  - shape: plane
    name: floor
    params: {size: [4.0, 4.0]}
  - shape: quad
    name: backdrop
    params: {corner: [-2.0, 0.0, 2.0], edge_u: [0.0, 2.5, 0.0], edge_v: [4.0, 0.0, 0.0]}
"""
GONE = ("ivory_pawn", "gold_pawn", "block", "glass_ball")


def _note(src, part, base=BASE) -> str:
    return (f"{src}: parts.{part} (given by {base}, through extends:): the geometry here has no part {part!r}: the "
            f"entry is not used (`parts: {{{part}: null}}` leaves it out without this note)")


def _write(tmp_path, name: str, text: str):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_a_base_s_parts_entry_for_a_part_the_new_geometry_lacks_is_a_note_naming_the_base(tmp_path, capsys):
    path = _write(tmp_path, "nopawn.yaml", f"extends: examples/mesh_on_floor\n{GEOMETRY}")
    scene = load_scene(str(path))
    assert scene.part_names == ("floor", "backdrop") and scene.triangles.shape[0] == 4
    notes = scene.extra["notes"]
    assert [n for n in notes if ": parts." in n] == [_note(path, p) for p in GONE]
    # (the floor and the backdrop keep the base's materials for them)
    assert [scene.materials[i].name for i in scene.material_index] == ["floor"] * 2 + ["backdrop"] * 2
    capsys.readouterr()
    assert main(["scene", "show", str(path)]) == 0
    assert _note(path, "ivory_pawn") in json.loads(capsys.readouterr().out)["notes"]


def test_through_a_middle_file_the_note_names_the_file_that_gave_the_entry(tmp_path):
    _write(tmp_path, "nopawn.yaml", f"extends: examples/mesh_on_floor\n{GEOMETRY}")
    top = _write(tmp_path, "top.yaml", "extends: nopawn.yaml\nname: top\n")
    notes = load_scene(str(top)).extra["notes"]
    assert [n for n in notes if ": parts." in n] == [_note(top, p) for p in GONE]


@pytest.mark.parametrize("nulls", [GONE, GONE[:1]])
def test_an_inherited_entry_given_as_null_is_taken_out_without_a_note(tmp_path, nulls):
    parts = ", ".join(f"{p}: null" for p in nulls)
    path = _write(tmp_path, "nopawn.yaml", f"extends: examples/mesh_on_floor\n{GEOMETRY}parts: {{{parts}}}\n")
    notes = load_scene(str(path)).extra["notes"]
    assert [n for n in notes if ": parts." in n] == [_note(path, p) for p in GONE if p not in nulls]


@pytest.mark.parametrize("parts, said", [
    ("{flor: red}", "parts.flor: the geometry has no part 'flor' (parts: floor, backdrop) (did you mean 'floor'?)"),
    ("{flor: null}", "parts.flor: the geometry has no part 'flor' (parts: floor, backdrop) (did you mean 'floor'?)"),
    ("{gold_pawn: red}", "parts.gold_pawn: the geometry has no part 'gold_pawn' (parts: floor, backdrop)"),
])
def test_an_entry_the_extending_file_gives_for_a_part_not_there_is_its_own_error(tmp_path, capsys, parts, said):
    path = _write(tmp_path, "nopawn.yaml", f"extends: examples/mesh_on_floor\n{GEOMETRY}parts: {parts}\n")
    capsys.readouterr()
    assert main(["scene", "show", str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == f"tlm: error: {path}: {said}\n"


def test_a_base_s_own_wrong_entry_is_the_base_s_error_until_a_later_file_changes_the_geometry(tmp_path, capsys):
    base = _write(tmp_path, "base.yaml", "geometry: {shape: plane, name: floor, params: {size: [1.0, 1.0]}}\n"
                  "materials: {m: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\nparts: {floor: m, flore: m}\n"
                  "lights: [{type: point, position: [0.0, 1.0, 0.0], power: [1.0, 1.0, 1.0]}]\n"
                  "camera: {eye: [0.0, 1.0, -2.0], target: [0.0, 0.0, 0.0], vfov: 40.0}\nresolution: [8, 8]\n")
    renamed = _write(tmp_path, "renamed.yaml", "extends: base.yaml\nname: renamed\n")
    capsys.readouterr()
    assert main(["scene", "show", str(renamed)]) == 2
    assert capsys.readouterr().err == (f"tlm: error: {base}: parts.flore: the geometry has no part 'flore' (parts: "
                                       "floor) (did you mean 'floor'?)\n")
    scaled = _write(tmp_path, "scaled.yaml", "extends: base.yaml\ngeometry: {transform: {scale: 2.0}}\n")
    assert main(["scene", "show", str(scaled)]) == 2  # (a transform keeps the parts: still the base's error, h358)
    assert capsys.readouterr().err.startswith(f"tlm: error: {base}: parts.flore: the geometry has no part 'flore'")
    renamed = _write(tmp_path, "ground.yaml", "extends: base.yaml\ngeometry: {name: ground}\nparts: {ground: m}\n")
    # (renamed: the base's floor entry is a note; its flore, which names no part of the base's plane either, stays
    # its error: a shape's part names are known without building it, h369)
    assert main(["scene", "show", str(renamed)]) == 2
    assert capsys.readouterr().err.startswith(f"tlm: error: {base}: parts.flore: the geometry has no part 'flore'")
    _write(tmp_path, "base.yaml", "geometry: {shape: plane, name: floor, params: {size: [1.0, 1.0]}}\n"
           "materials: {m: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\nparts: {floor: m}\n"
           "lights: [{type: point, position: [0.0, 1.0, 0.0], power: [1.0, 1.0, 1.0]}]\n"
           "camera: {eye: [0.0, 1.0, -2.0], target: [0.0, 0.0, 0.0], vfov: 40.0}\nresolution: [8, 8]\n")
    assert load_scene(str(renamed)).extra["notes"] == [_note(renamed, "floor", base)]


def test_a_one_item_merge_of_a_builder_s_params_that_drops_a_part_makes_the_base_s_entry_a_note(tmp_path):
    base = _write(tmp_path, "ring_glass.yaml", "extends: ring\ngeometry: {params: {glass_radius: 3.0}}\n"
                  "materials: {glass: {type: dielectric, ior: 1.5}}\nparts: {glass: glass}\n")
    assert load_scene(str(base)).part_names == ("floor", "ring", "glass")
    plain = _write(tmp_path, "plain.yaml", "extends: ring_glass.yaml\ngeometry: {params: {glass_radius: 0.0}}\n")
    scene = load_scene(str(plain))
    assert scene.part_names == ("floor", "ring")
    assert [n for n in scene.extra["notes"] if ": parts." in n] == [_note(plain, "glass", base)]


def test_conference_keeping_one_ceiling_panel(tmp_path):
    mesh = scenes_dir() / "meshes" / "conference.obj.xz"
    path = _write(tmp_path, "one_panel.yaml", f"extends: conference\ngeometry:\n  - mesh: {json.dumps(str(mesh))}\n"
                  "  - shape: quad\n    name: panel_table\n    params: {corner: [150.0, 649.0, -215.0], "
                  "edge_u: [300.0, 0.0, 0.0], edge_v: [0.0, 0.0, 150.0]}\n")
    scene = load_scene(str(path))
    assert [n for n in scene.extra["notes"] if ": parts." in n] == [
        _note(path, "panel_window", scenes_dir() / "conference.yaml")]
    panel = scene.part_names.index("panel_table")
    assert {scene.materials[i].name for i in scene.material_index[scene.part == panel]} == {"panel"}
