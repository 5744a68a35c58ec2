"""A base's ``parts:`` entry naming a material of its mesh file, not a part, under a geometry that lists the base's
mesh again (tlm.scenes.chain._typo, h373): the base's error says it as the base alone says it, with the hint that
the name is a material of the mesh file (loader._a_file_material), not only a near part name."""

from __future__ import annotations

from tlm.cli import main

VIEW = ("camera: {eye: [0.0, 1.0, 5.0], target: [0.0, 0.0, 0.0], up: [0.0, 1.0, 0.0], vfov: 40.0}\n"
        "resolution: [16, 12]\nlights: [{type: point, position: [0.0, 3.0, 0.0], power: [10.0, 10.0, 10.0]}]\n")


def _error(capsys, path) -> str:
    capsys.readouterr()
    assert main(["scene", "show", str(path)]) == 2
    return capsys.readouterr().err


def test_a_base_s_part_entry_naming_a_file_material_keeps_its_hint_under_a_new_geometry(tmp_path, capsys):
    (tmp_path / "floor.obj").write_text("mtllib floor.mtl\no floor\nusemtl redpaint\nv -1 0 -1\nv -1 0 1\nv 1 0 1\n"
                                        "v 1 0 -1\nf 1 2 3\nf 1 3 4\n", encoding="utf-8")
    (tmp_path / "floor.mtl").write_text("newmtl redpaint\nKd 0.8 0.1 0.1\n", encoding="utf-8")
    base = tmp_path / "base.yaml"
    base.write_text("geometry: [{mesh: floor.obj}]\nmaterials: {chrome: {type: mirror, reflectance: [0.9, 0.9, 0.9]}}"
                    f"\nparts: {{redpaint: chrome}}\n{VIEW}", encoding="utf-8")
    alone = _error(capsys, base)
    assert "'redpaint' is a material of the mesh file, not a part" in alone, alone
    child = tmp_path / "child.yaml"
    child.write_text("extends: base.yaml\ngeometry: [{mesh: floor.obj}, {shape: sphere, name: ball, params: "
                     "{radius: 0.2, segments: 8, rings: 4}}]\n", encoding="utf-8")
    assert _error(capsys, child) == alone
