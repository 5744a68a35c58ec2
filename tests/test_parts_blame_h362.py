"""A part with no material (and no ``default_material``) in a scene file that extends another is the error
of the file of the ``extends:`` chain that gave the geometry (tlm.scenes.chain.blamed): a file replacing
``examples/mesh_on_floor``'s geometry by the Cornell builder is named, and the base (a built-in scene,
in an installed copy a file in site-packages) only as the file whose ``parts:`` was for the geometry
replaced; the error was the base's, as the file that gave ``parts:``. A base whose own geometry has a part
with no material stays the base's error under a file that only scales it (it was the scaling file's)."""

from __future__ import annotations

from tlm.cli import main
from tlm.scenes.loader import scenes_dir

BASE = scenes_dir() / "examples" / "mesh_on_floor.yaml"
LACK = "part 'back_wall' has no material and there is no default_material (8 parts lack one)"


def _write(tmp_path, name: str, text: str):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _error(capsys, path) -> str:
    capsys.readouterr()
    assert main(["scene", "show", str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    return captured.err


def _base_s_parts(base=BASE) -> str:
    return (f"; the parts: given by {base} (through extends:) is for the geometry this file's geometry: replaces: "
            "give them materials under parts: or set default_material")


def test_the_file_that_replaced_the_geometry_is_named_and_the_base_only_as_the_giver_of_parts(tmp_path, capsys):
    path = _write(tmp_path, "d.yaml", "extends: examples/mesh_on_floor\ngeometry: {builder: cornell}\n")
    assert _error(capsys, path) == f"tlm: error: {path}: parts: {LACK}{_base_s_parts()}\n"
    # through a file that only renames: the middle file that gave the geometry, not the base nor the top
    top = _write(tmp_path, "top.yaml", "extends: d.yaml\nname: top\n")
    assert _error(capsys, top) == f"tlm: error: {path}: parts: {LACK}{_base_s_parts()}\n"
    # a later file's parts: entry (not for every part): the file that gave parts after the geometry, as before
    later = _write(tmp_path, "later.yaml", "extends: d.yaml\nparts: {floor: floor}\n")
    assert _error(capsys, later) == f"tlm: error: {later}: parts: {LACK}\n"
    # the fix the line gives, in the file it names, loads
    _write(tmp_path, "d.yaml", "extends: examples/mesh_on_floor\ngeometry: {builder: cornell}\n"
           "default_material: floor\n")
    assert main(["scene", "show", str(top)]) == 0


def test_a_base_s_own_part_with_no_material_stays_its_error_under_a_file_that_only_scales(tmp_path, capsys):
    base = _write(tmp_path, "base.yaml", "geometry: {builder: cornell}\n"
                  "materials: {m: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n")
    scaled = _write(tmp_path, "scaled.yaml", "extends: base.yaml\ngeometry: {transform: {scale: 2.0}}\n")
    assert _error(capsys, scaled) == f"tlm: error: {base}: parts: {LACK.replace('8', '9')}\n"
    # a base's parts: that is no mapping stays the base's, under a file that replaces the geometry
    _write(tmp_path, "base.yaml", "geometry: {builder: cornell}\n"
           "materials: {m: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\nparts: [m]\n")
    other = _write(tmp_path, "other.yaml", "extends: base.yaml\ngeometry: {builder: ring}\n")
    assert _error(capsys, other) == f"tlm: error: {base}: parts: must be a mapping, got ['m']\n"
