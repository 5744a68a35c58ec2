"""``tlm run SCENE.yaml`` renders a scene file at the default settings; ``tlm scene list``
names the scenes of subfolders."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "scenes" / "examples" / "mesh_on_floor.yaml"


def test_run_a_scene_file(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", str(EXAMPLE), "--out", str(out), "--set", "resolution=[32,32]", "--no-report",
                 "--no-progress"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith(f"{EXAMPLE} is a scene file: rendering it with the default settings")
    assert f"`scene: {EXAMPLE}`" in lines[0]
    results = json.loads((out / "results.json").read_text())
    assert results["scene"]["name"] == "mesh_on_floor"
    assert results["scene"]["triangles"] == 1568
    assert results["scene"]["resolution"] == [32, 32]
    resolved = yaml.safe_load((out / "config.resolved.yaml").read_text())
    assert resolved["scene"] == str(EXAMPLE) and resolved["mode"] == "refract"  # the defaults
    assert (out / "images" / "composite.png").is_file()


def test_run_a_scene_file_that_extends_another(tmp_path, capsys):
    scene = tmp_path / "mine.yaml"
    scene.write_text(f"extends: {EXAMPLE}\nname: mine\nresolution: [16, 12]\n")
    assert main(["run", str(scene), "--out", str(tmp_path / "o"), "--mode", "rcast", "--outputs", "images",
                 "--no-report", "--no-progress"]) == 0
    assert "is a scene file" in capsys.readouterr().out
    results = json.loads((tmp_path / "o" / "results.json").read_text())
    assert results["scene"]["name"] == "mine" and results["scene"]["resolution"] == [16, 12]


def test_neither_a_config_nor_a_scene_file(tmp_path, capsys):
    for text in ("name: x\ncamera: {eye: [0, 0, 0]}\n", "foo: 1\nbar: [2]\n"):
        path = tmp_path / "what.yaml"
        path.write_text(text)
        assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith(f"tlm: error: {path}: neither a run config nor a scene file")
        assert "`scene: " in err and "geometry:" in err
    assert not (tmp_path / "o").exists()


def test_a_config_typo_is_still_an_unknown_key(tmp_path, capsys):
    path = tmp_path / "cfg.yaml"
    path.write_text("scene: ring\nmdoe: rcast\n")
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "mdoe: unknown key (did you mean 'mode'?)" in capsys.readouterr().err
    path.write_text("mdoe: rcast\n")
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "mdoe: unknown key (did you mean 'mode'?)" in capsys.readouterr().err


def test_a_scene_file_typo_is_reported_by_the_scene_loader(tmp_path, capsys):
    path = tmp_path / "s.yaml"
    path.write_text(EXAMPLE.read_text().replace("camera:", "camrea:").replace("pawn.obj", str(REPO / "scenes"
                    / "examples" / "pawn.obj")))
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "camrea: unknown key (did you mean 'camera'?)" in err and err.count("\n") == 1


def test_scene_list_includes_subfolders(capsys):
    assert main(["scene", "list"]) == 0
    names = capsys.readouterr().out.split()
    assert {"cornell", "ring", "room", "thesis/ring", "thesis/room", "examples/mesh_on_floor"} <= set(names)
    assert names == sorted(names)
    assert main(["scene", "list", "--long"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == names
    row = next(line for line in lines if line.startswith("thesis/ring "))
    assert "Gold ring and glass ball" in row


def test_unknown_scene_lists_the_subfolders(tmp_path, capsys):
    path = tmp_path / "cfg.yaml"
    path.write_text("scene: thesis_room\n")
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "thesis/ring" in err and "thesis/room" in err and "examples/mesh_on_floor" in err


def test_a_scene_extending_a_mesh_scene_from_another_folder_keeps_its_mesh(tmp_path):
    """A one-item geometry that adds only a transform or a name merges into the base's, whose
    mesh path stays relative to the base (it was looked for beside the extending file)."""
    import numpy as np

    from tlm.api import load_scene

    base, child = tmp_path / "base", tmp_path / "child"
    base.mkdir()
    child.mkdir()
    (base / "pawn.obj").write_bytes((EXAMPLE.parent / "pawn.obj").read_bytes())
    (base / "b.yaml").write_text("geometry: {mesh: pawn.obj, name: pawn}\n"
                                 "materials: {m: {type: lambertian, albedo: [0.7, 0.7, 0.7]}}\ndefault_material: m\n"
                                 "lights: [{type: point, position: [2, 4, -4], power: [200, 200, 200]}]\n"
                                 "camera: {eye: [0, 0.6, -3], target: [0, 0.5, 0], vfov: 30}\nresolution: [16, 16]\n")
    (child / "big.yaml").write_text("extends: ../base/b.yaml\ngeometry: {transform: {scale: 2}, name: big}\n")
    (child / "box.yaml").write_text("extends: cornell-box\ngeometry: {transform: {translate: [0, 0.5, 0]}}\n")
    pawn, big = load_scene(base / "b.yaml"), load_scene(child / "big.yaml")
    assert np.array_equal(big.triangles, pawn.triangles * 2) and big.part_names == ("big",)
    box, original = load_scene(child / "box.yaml"), load_scene("cornell-box")
    assert np.allclose(box.triangles, original.triangles + [0.0, 0.5, 0.0])
    (child / "own.yaml").write_text("extends: ../base/b.yaml\ngeometry: {mesh: pawn.obj}\n")  # its own: beside it
    with pytest.raises(InputError, match=r"own\.yaml: geometry\.mesh: mesh file .*child/pawn\.obj' not found"):
        load_scene(child / "own.yaml")


def test_a_material_given_another_type_by_extends_is_replaced_whole(tmp_path):
    from tlm.api import load_scene

    (tmp_path / "a.yaml").write_text("extends: cornell\n"
                                     "materials: {glass: {type: mirror, reflectance: [0.9, 0.9, 0.9]}}\n")
    scene = load_scene(tmp_path / "a.yaml")
    glass = next(m for m in scene.materials if m.name == "glass")
    assert glass.kind == "mirror" and glass.reflectance == (0.9, 0.9, 0.9)
    (tmp_path / "b.yaml").write_text("extends: cornell\nmaterials: {glass: {ior: 1.0}}\n")  # the same type: merged
    glass = next(m for m in load_scene(tmp_path / "b.yaml").materials if m.name == "glass")
    assert glass.kind == "dielectric" and glass.ior == 1.0
