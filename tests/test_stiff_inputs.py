"""Stiff inputs that gave no error but a wrong or misleading result (tlm/render/checks.py,
tlm/kernels/estimate.py): a scene far from the origin warned of as unlit, and not of its
coarse positions; emission on zero-area triangles dropped without a word; glass branching
without pruning; a search radius whose area overflows."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tlm.cli import main
from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.kernels import estimate, kvoxel
from tlm.kernels.bsp import build_point_tree
from tlm.kernels.traverse import build_accel
from tlm.render import checks
from tlm.scenes.loader import load_scene

REPO = Path(__file__).resolve().parents[1]
CORNELL = REPO / "scenes" / "cornell.yaml"
SMALL = ["--set", "resolution=[16,16]", "--set", "render.spp=1", "--set", "render.light_samples=1",
         "--set", "arch.packet_size=16"]
PHOTONS = ["--set", "photons.count=2000"]  # (pmap runs only: a --set of it elsewhere is warned of)


def _moved(tmp_path: Path, name: str, transform: str) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(f"extends: {CORNELL}\nname: {name}\ntransform: {transform}\n")
    return path


def _run(tmp_path: Path, capsys, scene: Path, mode: str, *more: str) -> tuple[int, list[str], list[str], Path]:
    """``tlm run`` of the scene: exit status, results.json warnings (None when not written),
    stderr lines and the output folder."""
    out = tmp_path / f"out_{scene.stem}"
    code = main(["run", str(scene), "--out", str(out), "--mode", mode, "--no-progress", "--no-report",
                 "--no-reference", "--outputs", "images", *SMALL, *(PHOTONS if mode == "pmap" else []), *more])
    err = capsys.readouterr().err.splitlines()
    results = out / "results.json"
    return code, json.loads(results.read_text())["warnings"] if results.exists() else None, err, out


# ---------------------------------------------------------------- far from the origin


def test_a_scene_far_from_the_origin_is_not_called_unlit_but_coarse(tmp_path, capsys, cache):
    """The Cornell box in metres 1e12 from the origin (float64 spacing 1.2e-4 against its
    0.96 diagonal): before, the light's probe rays started 1.0 from it, past the walls, and
    the run warned "lights[0] (quad) reaches no surface"; now it says the positions are
    coarse (1.3e-4 of the extent), and nothing at 1e9 (spacing 1.2e-7 of the extent)."""
    far = load_scene(str(_moved(tmp_path, "far", "{scale: 1.0e-3, translate: [1.0e12, 0, 0]}")))
    assert checks.light_warnings(far, build_accel(far.triangles)) == []
    code, warnings, err, _ = _run(tmp_path, capsys, tmp_path / "far.yaml", "rcast")
    assert code == 0 and len(warnings) == 1, warnings
    assert warnings[0].startswith("the scene lies far from the origin for its size: float64 positions at its "
                                  "largest coordinate (1e+12) are 0.000122 apart, 0.00013 of its extent (0.961")
    assert f"tlm: warning: {warnings[0]}" in err
    near = load_scene(str(_moved(tmp_path, "near", "{scale: 1.0e-3, translate: [1.0e9, 0, 0]}")))
    assert checks.coordinate_warnings(near) == []


def test_the_probe_starts_a_few_ulps_out_but_never_past_a_fraction_of_the_scene():
    """A point light's probe rays start 16 ulps of its coordinates away; a quad light's 1e-5
    of its size; neither more than 1e-5 of the scene's diagonal."""
    scene = load_scene(str(CORNELL), None, [16, 16])
    accel = build_accel(scene.triangles)
    quad = scene.lights[0]
    assert checks.probe_eps(quad, accel, np.zeros((1, 3))) == pytest.approx(1e-5 * np.sqrt(130.0 * 105.0))
    point = replace(quad, kind="point", position=(278.0, 400.0, 279.0))
    o = np.array([[278.0, 400.0, 279.0]])
    assert checks.probe_eps(point, accel, o) == 16 * np.finfo(float).eps * 400.0
    assert checks.probe_eps(point, accel, o * 1e12) == pytest.approx(1e-5 * accel.scale)


# ---------------------------------------------------------------- emission without area


def test_emission_on_zero_area_triangles_is_named(tmp_path, capsys, cache):
    """A material whose every triangle has no area emits nothing (the pmap pass is left out:
    "no light with power"); before, nothing said why, now one line names the material and
    its part. A material that also has triangles with area is not named."""
    (tmp_path / "m.obj").write_text("v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nv 0 0 0\nv 0.5 0 0.5\n"
                                    "o floor\nf 1 3 2\nf 1 4 3\no zero\nf 5 5 6\nf 1 6 3\n")
    path = tmp_path / "glow.yaml"
    path.write_text("geometry: {mesh: m.obj}\nmaterials:\n  white: {type: lambertian, albedo: [0.7, 0.7, 0.7]}\n"
                    "  glow: {type: lambertian, albedo: [0.5, 0.5, 0.5], emission: [5.0, 5.0, 5.0]}\n"
                    "parts: {floor: white, zero: glow}\n"
                    "lights: [{type: point, position: [0, 1, 0], power: [0, 0, 0]}]\n"
                    "camera: {eye: [0, 1.5, -3], target: [0, 0, 0], vfov: 45}\nresolution: [16, 16]\n")
    code, warnings, _, _ = _run(tmp_path, capsys, path, "pmap")
    line = "material 'glow' emits (emission [5.0, 5.0, 5.0]) only on 2 triangles of zero area (part 'zero')"
    assert code == 0 and sum(w.startswith(line) for w in warnings) == 1, warnings
    scene = load_scene(str(path))
    lit = replace(scene, material_index=np.where(np.arange(4) == 0, scene.material_index[-1], scene.material_index))
    assert checks.emission_warnings(lit) == []


# ---------------------------------------------------------------- glass branching


def _cfg(**render):
    return config_from_dict({"scene": "cornell", "mode": "refract", "resolution": [16, 16],
                             "render": {"spp": 1, **render}})


def test_min_weight_zero_with_a_deep_walk_is_warned_of():
    """min_weight 0 (allowed) prunes no glass branch: 2^(depth + 1) - 2 rays an eye ray,
    once the run that never finished (depth 20 at 16x16). Warned of from 2^12 on, naming
    both keys, the rays a pixel may spawn and the frame's; not with a min_weight above 0,
    Snell only (fresnel false), a mode without the walk or a scene without glass."""
    lines = checks.branching_warning(_cfg(refract_depth=20, min_weight=0.0))
    assert len(lines) == 1 and lines[0].startswith(
        "render.min_weight = 0 with render.refract_depth = 20: every glass hit splits a path in two (its Fresnel "
        "reflection and refraction) and no branch is pruned, so one eye ray may spawn up to 2,097,150 rays "
        "(2^(depth + 1) - 2), 5.4e+08 for this 16x16 frame at render.spp = 1")
    assert "render.min_weight above 0 prunes" in lines[0]
    assert checks.branching_warning(_cfg(refract_depth=11, min_weight=0.0)) == []  # 4,094 rays
    assert len(checks.branching_warning(_cfg(refract_depth=12, min_weight=0.0))) == 1  # 8,190
    assert checks.branching_warning(_cfg(refract_depth=20, min_weight=1e-3)) == []
    assert checks.branching_warning(_cfg(refract_depth=20, min_weight=0.0, fresnel=False)) == []
    assert checks.branching_warning(replace(_cfg(refract_depth=20, min_weight=0.0), mode="reflect")) == []
    deep_mirror = replace(_cfg(reflect_depth=30, min_weight=0.0), mode="reflect")
    assert "render.reflect_depth = 30" in checks.branching_warning(deep_mirror)[0]
    room = load_scene("cornell-box")  # (no mirror, no glass)
    assert checks.branching_warning(_cfg(refract_depth=20, min_weight=0.0), room) == []


def test_the_branching_warning_is_said_before_the_render_and_kept(tmp_path, capsys, cache):
    """``tlm run`` says it on stderr before the render starts (a render that may not end
    says why up front) and keeps it in results.json's warnings."""
    code, warnings, err, _ = _run(tmp_path, capsys, CORNELL, "refract", "--set", "render.min_weight=0",
                                  "--set", "render.refract_depth=12", "--set", "resolution=[8,8]")
    assert code == 0
    said = [i for i, line in enumerate(err) if line.startswith("tlm: warning: render.min_weight = 0 with "
                                                               "render.refract_depth = 12")]
    assert said == [0], err  # (the first line of the run, before the render's own; said once, not again at the end)
    assert sum(w.startswith("render.min_weight = 0 with render.refract_depth = 12") for w in warnings) == 1


# ---------------------------------------------------------------- search radius


def test_a_radius_whose_area_overflows_is_refused_naming_the_key(tmp_path, capsys, cache):
    """r = 1e200: pi r^2 is infinite and every density was 0 (an all-black photon frame,
    no warning); now refused, one line, exit 2, nothing written. The caustic map is
    gathered first: its key is named; the k-voxel filter, which does not say which map it
    gathers, names both. A config refuses it before any work (at most 1e150); the estimate
    refuses it too, for a caller of the kernels."""
    code, warnings, err, out = _run(tmp_path, capsys, CORNELL, "pmap", "--set", "estimate.filter=disk",
                                    "--set", "estimate.caustic_radius=1e200", "--set", "estimate.final_gather=0")
    assert code == 2 and warnings is None and not out.exists()
    assert err[-1].startswith("tlm: error: ") and err[-1].endswith("estimate.caustic_radius: 1e200 must be <= 1e150")
    rng = np.random.default_rng(1)
    pos = rng.uniform(0, 1, (200, 3))
    inc = np.tile([0.0, 0.0, -1.0], (200, 1))
    args = (pos, np.ones((200, 3)), inc, build_point_tree(pos), pos[:4], np.tile([0.0, 0.0, 1.0], (4, 1)))
    with pytest.raises(InputError, match=r"^estimate\.radius: 1e\+200: "):
        estimate.disk_estimate(*args, 1e200)
    with pytest.raises(InputError, match=r"^estimate\.caustic_radius: 1e\+154: "):
        estimate.mvoxel_estimate(*args, 1e154, stream="caustic_photons")
    with pytest.raises(InputError, match=r"^estimate\.radius or estimate\.caustic_radius: 1e\+160: "):
        kvoxel.kvoxel_estimate(*args, 1e160)
    assert np.isfinite(estimate.disk_estimate(*args, 7e153).density).all()  # (under the bound: finite)


def test_a_radius_over_the_scene_diagonal_is_warned_of():
    """A fixed radius past the scene's diagonal gathers the whole map at every point; the
    line says how far past and what the estimate then is. Not under the diagonal, with the
    k-nearest filter, or outside mode pmap."""
    pmap = config_from_dict({"scene": "cornell", "mode": "pmap", "estimate": {"radius": 1e6}})
    lines = checks.radius_warnings(pmap, 961.0)
    assert len(lines) == 1 and lines[0].startswith(
        "estimate.radius = 1e+06 is 1.04e+03 times the scene's diagonal (961): every gather takes every photon of "
        "the map within reach and pi r^2 = 3.14e+12")
    both = config_from_dict({"mode": "pmap", "estimate": {"radius": 10.0, "caustic_radius": 1e150}})
    assert [w.split(" = ")[0] for w in checks.radius_warnings(both, 961.0)] == ["estimate.caustic_radius"]
    assert "pi r^2 = 3.14e+300" in checks.radius_warnings(both, 961.0)[0]
    assert checks.radius_warnings(replace(pmap, mode="refract"), 961.0) == []
    knn = config_from_dict({"mode": "pmap", "estimate": {"radius": 1e6, "filter": "knn"}})
    assert checks.radius_warnings(knn, 961.0) == []
