"""A researcher's own scene, McGuire's CornellBox-Glossy as published (h378): its MTL's sphere and
short box are ``illum 2`` with ``Ks`` 0.9 and 0.8 over ``Kd`` (a glossy highlight, ``Ns 40``),
which tlm renders as a Lambertian of ``Kd``, as docs/functional.md tables it. That was said
nowhere: ``tlm scene show``'s materials, the run's warnings and the report's "ignored (not
rendered)" column were silent, and a glossy box rendered diffuse. Such a ``Ks`` is now kept on the
material's ``ignored`` (so the run warns of it, and a ``materials:`` entry that replaces the
material takes the warning away); the conference room's ``Ks 0.2`` beside a dark ``Kd`` is not."""

from __future__ import annotations

import json
from pathlib import Path

from tlm import api
from tlm.cli import main
from tlm.render.checks import material_warnings
from tlm.scenes.materials import parse_mtl

# the materials of McGuire's CornellBox-Glossy.mtl (CC BY 3.0), as its file writes them
GLOSSY_MTL = """newmtl sphere
\tNs 40.0000
\tNi 1.5000
\tillum 2
\tKd 0.4860 0.6310 0.6630
\tKs 0.9000 0.9000 0.9000
newmtl wall
  Ns 10.0000
  illum 2
  Kd 0.725 0.71 0.68
  Ks 0 0 0
newmtl light
  illum 2
  Kd 0.78 0.78 0.78
  Ks 0 0 0
  Ke 17 12 4
"""


def _ignored(mtl: str) -> dict[str, tuple[str, ...]]:
    return {m.name: m.ignored for m in parse_mtl(mtl, "t.mtl", [])}


def test_a_dominant_illum_2_highlight_is_kept_as_not_rendered():
    got = _ignored(GLOSSY_MTL)
    (entry,) = got["sphere"]
    assert "Ks" in entry and "illum 2" in entry and "highlight" in entry
    assert got["wall"] == () and got["light"] == ()


def test_a_weak_or_minor_highlight_or_another_illum_is_not():
    # the conference room: Ks 0.2 over a Kd of 0.05 (a weak highlight), Ks 0.6 under a brighter Kd
    assert _ignored("newmtl dark\nillum 2\nKd 0.047 0.047 0.047\nKs 0.2 0.2 0.2\n")["dark"] == ()
    assert _ignored("newmtl lit\nillum 2\nKd 0.8 0.8 0.8\nKs 0.6 0.6 0.6\n")["lit"] == ()
    # illum 1 has no highlight at all; illum 3 and no illum with a dominant Ks are mirrors already
    assert _ignored("newmtl a\nillum 1\nKd 0.1 0.1 0.1\nKs 0.9 0.9 0.9\n")["a"] == ()
    (m,) = parse_mtl("newmtl b\nKd 0.1 0.1 0.1\nKs 0.9 0.9 0.9\n", "t.mtl", [])
    assert m.kind == "mirror" and m.ignored == ()


def _scene(folder: Path, extra: str = "") -> Path:
    """A floor of 'wall', a panel of 'sphere' and a ceiling light of 'light', in an OBJ over GLOSSY_MTL."""
    (folder / "g.mtl").write_text(GLOSSY_MTL)
    (folder / "g.obj").write_text(
        "mtllib g.mtl\n"
        "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\n"
        "v -0.5 0 -0.5\nv 0.5 0 -0.5\nv 0.5 1 -0.5\nv -0.5 1 -0.5\n"
        "v -0.2 1.5 -0.2\nv 0.2 1.5 -0.2\nv 0.2 1.5 0.2\nv -0.2 1.5 0.2\n"
        "g floor\nusemtl wall\nf 1 4 3 2\n"
        "g ball\nusemtl sphere\nf 5 6 7 8\n"
        "g lamp\nusemtl light\nf 9 10 11 12\n")
    path = folder / "s.yaml"
    path.write_text("geometry: {mesh: g.obj}\ncamera: {eye: [0, 0.8, 3], target: [0, 0.5, 0], vfov: 50}\n"
                    "resolution: [8, 8]\n" + extra)
    return path


def test_the_run_warns_of_the_glossy_material_until_a_scene_file_replaces_it(tmp_path, capsys):
    (line,) = material_warnings(api.load_scene(_scene(tmp_path)))
    assert "'sphere'" in line and "highlight" in line and "'wall'" not in line
    capsys.readouterr()
    assert main(["scene", "show", str(_scene(tmp_path))]) == 0
    shown = {m["name"]: m for m in json.loads(capsys.readouterr().out)["materials"]}
    assert shown["sphere"]["type"] == "lambertian" and "highlight" in shown["sphere"]["ignored"][0]
    assert "ignored" not in shown["wall"]
    mirror = "materials:\n  sphere: {type: mirror, reflectance: [0.9, 0.9, 0.9]}\n"
    assert material_warnings(api.load_scene(_scene(tmp_path, mirror))) == []


def test_a_pmap_run_of_a_scene_file_without_photons_says_where_to_give_them(tmp_path, cache, capsys):
    """A scene file written as docs/scenes.md's Keys table allows, without `photons:` (default 0),
    run in pmap mode: the warning said "photons.count is 0" of a config whose photons.count is null,
    and not where the count goes. Since h474 that run is an error before any work (exit 2) naming the scene
    file and how to give the count; a config that sets photons.count=0 itself gets the line as before."""
    scene = _scene(tmp_path)
    args = ["--mode", "pmap", "--outputs", "images", "--no-report", "--no-progress"]
    assert main(["run", str(scene), "--out", str(tmp_path / "null"), *args]) == 2
    assert "add `photons: N` to the scene file" in capsys.readouterr().err and not (tmp_path / "null").exists()
    out = tmp_path / "zero"
    assert main(["run", str(scene), "--out", str(out), *args, "--set", "photons.count=0"]) == 0
    (line,) = [w for w in json.loads((out / "results.json").read_text())["warnings"] if "photon-map pass" in w]
    assert line.endswith("(its passes: rcast)")
