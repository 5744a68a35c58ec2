"""Leftovers of earlier reviews, mended (h248): a scene file that ``extends:`` another removes an inherited
material (``materials: {NAME: null}``); a refused report folder's line built from its parts, not edited; ``tlm
sweep --dry-run`` writes nothing to the scene cache."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import yaml

from tests._subproc import held_claim
from tlm.cli import main
from tlm.errors import InputError
from tlm.scenes.loader import load_scene

CHILD = {"extends": "cornell", "name": "cornell_no_chrome"}


def _scene(folder: Path, body: dict, name: str = "child.yaml") -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump(body, sort_keys=False))
    return path


def test_a_null_material_removes_the_inherited_one(tmp_path):
    """Before: ``materials.chrome: must be a mapping, got None``, and no other way to take it out (left alone,
    the base's material is kept with a note that this file cannot act on)."""
    kept = load_scene(str(_scene(tmp_path, {**CHILD, "parts": {"mirror_object": "white"}}, "kept.yaml")))
    assert "chrome" in [m.name for m in kept.materials] and any("materials.chrome" in n for n in kept.extra["notes"])
    scene = load_scene(str(_scene(tmp_path, {**CHILD, "materials": {"chrome": None},
                                             "parts": {"mirror_object": "white"}})))
    assert "chrome" not in [m.name for m in scene.materials] and not scene.extra["notes"]
    assert [m.name for m in scene.materials] == [m.name for m in kept.materials if m.name != "chrome"]
    # a chain: the grandchild gives it again, of its own
    again = load_scene(str(_scene(tmp_path, {"extends": "child.yaml", "materials": {
        "chrome": {"type": "mirror", "reflectance": [0.5, 0.5, 0.5]}}, "parts": {"mirror_object": "chrome"}},
        "grand.yaml")))
    assert [m.reflectance for m in again.materials if m.name == "chrome"] == [(0.5, 0.5, 0.5)]


def test_a_null_material_the_base_does_not_give_or_without_extends_is_one_line(tmp_path):
    path = _scene(tmp_path, {**CHILD, "materials": {"chrom": None}})
    with pytest.raises(InputError) as e:
        load_scene(str(path))
    assert str(e.value).startswith(f"{path}: materials.chrom: null removes an inherited material, and ")
    assert str(e.value).endswith("(extends:) gives none named 'chrom' (did you mean 'chrome'?)")
    alone = yaml.safe_load((Path(__file__).parents[1] / "scenes" / "cornell.yaml").read_text())
    path = _scene(tmp_path, {**alone, "materials": {**alone["materials"], "gone": None}}, "alone.yaml")
    with pytest.raises(InputError) as e:
        load_scene(str(path))
    assert str(e.value) == (f"{path}: materials.gone: null removes an inherited material, and this file extends no "
                            "scene (extends:): give the material's fields, or leave it out")
    path = _scene(tmp_path, {**CHILD, "materials": {"chrome": None}}, "still.yaml")  # (a part still names it)
    with pytest.raises(InputError, match=r"parts\.mirror_object: 'chrome' is not a material"):
        load_scene(str(path))


def test_a_held_report_folders_line_is_built_from_its_parts(tmp_path):
    """Before: the refusal was the claim's line edited by string replacement, which edited the folder's name
    too where it held the words replaced (``... or give another folder with --out/report``), and the holder
    told to a waiting command was cut out of the line by a pattern the folder's name could match."""
    from tlm.cli_report import report_claimed

    given = tmp_path / "a (process 1): wait for it, or give another folder"
    report = given / "report"
    fd = held_claim(report)
    told: list[str] = []
    try:
        with pytest.raises(InputError) as e, report_claimed(report, of=str(given)):
            pass
        assert str(e.value).startswith(f"{given}: another report is writing into its report folder {str(report)!r} "
                                       "(process 4242 on this machine, "), e.value
        assert str(e.value).endswith("): wait for it to end, or give another folder with --out"), e.value

        def wait(holder: str) -> None:  # (told once; the folder then freed, so the claim is taken)
            told.append(holder)
            os.close(fd)

        with report_claimed(report, wait=wait):
            pass
        assert len(told) == 1 and told[0].startswith("process 4242 on this machine, "), told
    finally:
        if not told:
            os.close(fd)


_N = 101  # a grid of 101 x 101 vertices: 20,000 triangles, as many as the scene cache keeps (MIN_TRIANGLES)


def _big_scene(folder: Path) -> Path:
    """A scene file of one OBJ mesh large enough for the scene cache, beside it."""
    u = np.linspace(0.0, 1.0, _N)
    lines = [f"v {x:.5f} 0 {z:.5f}" for x in u for z in u]
    for i in range(_N - 1):
        for j in range(_N - 1):
            a = i * _N + j + 1
            lines += [f"f {a} {a + _N} {a + 1}", f"f {a + 1} {a + _N} {a + _N + 1}"]
    (folder / "grid.obj").write_text("\n".join(lines) + "\n")
    scene = {"name": "big", "geometry": [{"mesh": "grid.obj", "name": "floor"}],
             "materials": {"white": {"type": "lambertian", "albedo": [0.7, 0.7, 0.7]}},
             "parts": {"floor": "white"}, "default_material": "white",
             "lights": [{"type": "quad", "corner": [0.2, 1.0, 0.2], "edge_u": [0.6, 0.0, 0.0],
                         "edge_v": [0.0, 0.0, 0.6], "power": [10.0, 10.0, 10.0]}],
             "camera": {"eye": [0.5, 1.5, -1.0], "target": [0.5, 0.0, 0.5], "up": [0.0, 1.0, 0.0], "vfov": 40.0},
             "resolution": [8, 8], "photons": 1000}
    path = folder / "big.yaml"
    path.write_text(yaml.safe_dump(scene, sort_keys=False))
    return path


def _files(folder: Path) -> dict[str, int]:
    """Every file under ``folder`` with its modification time."""
    return {str(Path(r) / f): os.stat(Path(r) / f).st_mtime_ns for r, _, fs in os.walk(folder) for f in fs}


def test_a_sweeps_dry_run_keeps_no_parse_in_the_scene_cache_and_touches_no_entry(tmp_path, cache, capsys):
    scene = _big_scene(tmp_path)
    sweep = tmp_path / "s.yaml"
    sweep.write_text(yaml.safe_dump({"base": {"scene": str(scene), "mode": "rcast"},
                                     "grid": {"arch.packet_size": [1, 16]}}, sort_keys=False))
    out = tmp_path / "o"
    assert main(["sweep", str(sweep), "--out", str(out), "--dry-run"]) == 0
    said = capsys.readouterr().out
    assert said.splitlines()[0] == f"dry run of {sweep} into {out}: nothing run, nothing written"
    assert _files(cache) == {} and not out.exists()  # (was: the mesh, its normals and its fingerprint kept)
    load_scene(str(scene))  # a load outside a dry run keeps them (so the dry run above had something to keep)
    kept = _files(cache)
    assert any(Path(p).name.startswith("mesh-") for p in kept) and any(Path(p).name.startswith("normals-")
                                                                       for p in kept)
    for p in kept:  # entries a dry run reads are not marked used either (tlm cache prune's order kept)
        os.utime(p, ns=(10**18, 10**18))
    kept = _files(cache)
    assert main(["sweep", str(sweep), "--out", str(out), "--dry-run"]) == 0
    assert _files(cache) == kept
