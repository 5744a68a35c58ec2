"""A researcher's first run of a published mesh with no emitter (McGuire's conference room as
published: every Ke 0) renders black; the run says why and what to give (h387)."""

from __future__ import annotations

import json
import re
from pathlib import Path

from tlm.cli import main
from tlm.kernels.traverse import build_accel
from tlm.render import checks
from tlm.scenes.loader import load_scene
from tlm.scenes.materials import HIGHLIGHT, parse_mtl

REPO = Path(__file__).resolve().parents[1]
DARK = ("geometry: [{shape: box, params: {min: [-1, 0, -1], max: [1, 1, 1]}}]\n"
        "materials: {m: {type: lambertian, albedo: [0.7, 0.7, 0.7]}}\ndefault_material: m\n"
        "camera: {eye: [0, 3, -4], target: [0, 0.5, 0], vfov: 40}\nresolution: [8, 8]\n")


def test_a_scene_with_no_light_is_warned_of_with_how_to_give_one(tmp_path, capsys):
    scene = tmp_path / "dark.yaml"
    scene.write_text(DARK)
    out = tmp_path / "run"
    assert main(["run", str(scene), "--out", str(out), "--mode", "rcast", "--no-progress", "--no-report",
                 "--outputs", "images"]) == 0
    warnings = json.loads((out / "results.json").read_text())["warnings"]
    (said,) = [w for w in warnings if w.startswith("the scene has no lights")]
    assert said == checks.NO_LIGHTS and "lights:" in said and "emission" in said
    assert any(w.startswith("the image is black") for w in warnings)  # (the consequence, kept)
    assert f"tlm: warning: {said}" in capsys.readouterr().err


def test_a_lit_scene_gets_no_such_line(tmp_path):
    scene = tmp_path / "lit.yaml"
    scene.write_text(DARK + "lights: [{type: point, position: [0, 3, 0], power: [10, 10, 10]}]\n")
    loaded = load_scene(str(scene))
    assert checks.NO_LIGHTS not in checks.light_warnings(loaded, build_accel(loaded.triangles))


def test_the_docs_do_not_say_the_conference_mtl_gives_colours_in_0_255():
    """docs/scenes.md said the conference room's Kd were in 0-255 in all 35 materials: its MTL
    gives none over 1 (and every Ke 0, which the docs now say)."""
    mtl = (REPO / "scenes" / "meshes" / "conference.mtl").read_text()
    colours = [float(x) for line in mtl.splitlines() if line.split()[:1] in (["Kd"], ["Ks"], ["Ke"])
               for x in line.split()[1:]]
    assert colours and max(colours) <= 1.0
    assert all(float(x) == 0.0 for line in mtl.splitlines() if line.split()[:1] == ["Ke"] for x in line.split()[1:])
    docs = " ".join((REPO / "docs" / "scenes.md").read_text().split())
    assert not re.search(r"conference room's `Kd` in 0-255", docs)
    assert "the scene has no lights" in docs


def test_the_docs_say_which_illum_2_highlight_is_noted_as_the_code_decides():
    """The rule is max(Ks) >= 0.5 and max(Ks) > max(Kd) (docs/scenes.md said 'at least 0.5 over
    the Kd'): the conference room's Ks 0.2 over its Kd 0.047 is left out unnoted, as the docs say."""
    mtl = REPO / "scenes" / "meshes" / "conference.mtl"
    dark = {m.name: m for m in parse_mtl(mtl.read_text(), str(mtl), [])}["mesh34_SG"]
    assert dark.kind == "lambertian" and HIGHLIGHT not in dark.ignored
    (noted,) = parse_mtl("newmtl g\nillum 2\nKd 0.3 0.3 0.3\nKs 0.5 0.5 0.5\n", "g.mtl", [])
    assert HIGHLIGHT in noted.ignored
    docs = " ".join((REPO / "docs" / "scenes.md").read_text().split())
    assert "of at least 0.5 over the material's `Kd`" not in docs
    assert "whose largest channel is at least 0.5 and above the `Kd`'s" in docs
    assert "`mesh34_SG`'s `Kd 0.047059`" in docs
