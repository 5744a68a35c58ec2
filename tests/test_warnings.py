"""Warnings for mistakes that give no error (tlm/render/checks.py): each fires on a scene
made to have the mistake, on stderr and in results.json, and none fires on the built-in
scenes."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tlm.cli import main
from tlm.kernels.traverse import build_accel, closest_hit
from tlm.render import checks
from tlm.scenes.loader import load_scene
from tlm.scenes.model import Light

REPO = Path(__file__).resolve().parents[1]
# (packets of 16: a 16x16 frame in packets of 256 is one packet a phase, whose hand-overs put its
# cycles 20-35% off packets of one, and the run rightly warns of that: not what these tests are about)
# (the photon count goes into the config files: a --set of it in a run without the photon-map
# pass is warned of, run_warnings.unread_overrides)
SMALL = ["--set", "resolution=[16,16]", "--set", "render.spp=1",
         "--set", "arch.packet_size=16"]
CORNELL_LIGHT = "corner: [343.0, 548.8, 227.0], power: [1100000.0, 950000.0, 750000.0]"
MIRROR_CENTRE = "[185.5, 245.0, 169.0]"  # the Cornell box's mirror sphere (radius 80)
GLASS_CENTRE = "[400.0, 90.0, 130.0]"  # ... and its glass sphere (radius 90)


def _scene(tmp_path: Path, name: str, body: str) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(f"extends: cornell\nname: {name}\n{body}")
    return path


def _run(tmp_path: Path, capsys, scene: Path | str, mode: str = "pmap",
         outputs: str = "images") -> tuple[list[str], list[str]]:
    """Run the scene; (results.json warnings, stderr warning lines). Exit 0 always."""
    config = tmp_path / f"run_{Path(str(scene)).stem}.yaml"
    config.write_text(f"scene: {scene}\nmode: {mode}\nphotons: {{count: 2000}}\n")
    out = tmp_path / f"out_{Path(str(scene)).stem}"
    code = main(["run", str(config), "--out", str(out), "--no-progress", "--no-report", "--no-reference",
                 "--outputs", outputs, *SMALL])
    assert code == 0
    err = capsys.readouterr().err
    results = json.loads((out / "results.json").read_text())
    lines = [ln.removeprefix("tlm: warning: ") for ln in err.splitlines() if ln.startswith("tlm: warning: ")]
    return results["warnings"], lines


def _only(warnings: list[str], start: str) -> str:
    hits = [w for w in warnings if w.startswith(start)]
    assert len(hits) == 1, warnings
    return hits[0]


# ---------------------------------------------------------------- lights


def test_a_quad_light_facing_away_warns_and_renders_black(tmp_path, capsys):
    """edge_u and edge_v swapped: the light faces up, out of the box through its ceiling."""
    scene = _scene(tmp_path, "away", f"lights:\n  - {{type: quad, {CORNELL_LIGHT}, edge_u: [-130.0, 0.0, 0.0], "
                                     "edge_v: [0.0, 0.0, 105.0]}\n")
    warnings, stderr = _run(tmp_path, capsys, scene, outputs="radiance")
    assert stderr == warnings
    w = _only(warnings, "lights[0] (quad) reaches no surface")
    assert "cross(edge_u, edge_v)" in w
    _only(warnings, "the image is black")
    assert "stored 0 of 2000 emitted photons" in _only(warnings, "the photon map stored")
    # nearly black: light grazing the ceiling the quad lies in (cos ~ 1e-16), nothing else
    assert np.load(tmp_path / "out_away" / "radiance" / "composite.npy").max() < 1e-20


def test_a_point_light_inside_a_mirror_sphere_lights_only_back_faces(tmp_path, capsys):
    scene = _scene(tmp_path, "enclosed", f"lights:\n  - {{type: point, position: {MIRROR_CENTRE}, "
                                         "power: [1.0e6, 1.0e6, 1.0e6]}\n")
    warnings, _ = _run(tmp_path, capsys, scene)
    assert "inside a closed mesh" in _only(warnings, "lights[0] (point) lights only back faces")
    _only(warnings, "the image is black")


def test_a_point_light_far_outside_the_box_lights_only_its_outside(tmp_path, capsys):
    """The box fills a sliver of the light's sphere (the spread rays all miss it); the aimed
    ones find its walls' backs (they face in)."""
    scene = _scene(tmp_path, "far", "lights:\n  - {type: point, position: [278.0, 1.0e7, 279.0], "
                                    "power: [1.0e6, 1.0e6, 1.0e6]}\n")
    warnings, _ = _run(tmp_path, capsys, scene, mode="rcast")
    assert "outside a room whose walls face in" in _only(warnings, "lights[0] (point) lights only back faces")
    _only(warnings, "the image is black")


def _lone_object(tmp_path: Path, light: str, size: float = 1.0, far: float = 1.0) -> Path:
    """A small sphere (radius 0.1 size) lit by ``light``, the camera in front of it."""
    path = tmp_path / "lone.yaml"
    path.write_text(f"geometry: [{{shape: sphere, params: {{radius: {0.1 * size}, segments: 24, rings: 12}}, "
                    f"transform: {{translate: [0, 0, {far}]}}}}]\n"
                    "materials: {m: {type: lambertian, albedo: [0.7, 0.7, 0.7]}}\ndefault_material: m\n"
                    f"lights: [{light}]\n"
                    f"camera: {{eye: [0, 0, {far - 1.0 * size}], target: [0, 0, {far}], vfov: 30}}\n"
                    "resolution: [16, 16]\n")
    return path


@pytest.mark.parametrize(("light", "size", "far"), [
    ("{type: point, position: [2, 4, -4], power: [200, 200, 200]}", 1.0, 1.0),  # a lone model
    ("{type: point, position: [3.0e6, 4.0e6, 0], power: [1.0e15, 1.0e15, 1.0e15]}", 1.0e6, 1.0e8),  # far out
], ids=["small", "far-from-the-origin"])
def test_a_lone_object_a_light_reaches_gets_no_light_warning(tmp_path, capsys, light, size, far):
    """The object fills under 1/256 of the light's sphere: every spread ray misses it, and
    the rays aimed at its triangles find it (they once warned "reaches no surface"); far from
    the origin, the probes start where the coordinates' precision allows, not a fraction of
    the scene's size away."""
    scene = load_scene(str(_lone_object(tmp_path, light, size, far)), None, [16, 16])
    accel = build_accel(scene.triangles)
    o, d, _, _ = checks.probe_rays(scene.lights[0])
    assert (closest_hit(accel, o, d, tmin=1e-9 * size).triangle < 0).all()  # (the spread ones alone miss)
    assert checks.probe_light(scene, accel, scene.lights[0])["hits"] > 0
    warnings, _ = _run(tmp_path, capsys, tmp_path / "lone.yaml", mode="rcast")
    assert warnings == []


def test_a_point_light_in_a_glass_globe_is_not_enclosed(tmp_path, capsys):
    """A lamp in a glass sphere lights the box through the glass: no warning."""
    scene = _scene(tmp_path, "globe", f"lights:\n  - {{type: point, position: {GLASS_CENTRE}, "
                                      "power: [1.0e6, 1.0e6, 1.0e6]}\n")
    warnings, _ = _run(tmp_path, capsys, scene)
    assert warnings == []


def test_the_second_light_is_named(tmp_path, capsys):
    scene = _scene(tmp_path, "two", f"lights:\n  - {{type: quad, {CORNELL_LIGHT}, edge_u: [0.0, 0.0, 105.0], "
                                    "edge_v: [-130.0, 0.0, 0.0]}\n"
                                    f"  - {{type: quad, {CORNELL_LIGHT}, edge_u: [-130.0, 0.0, 0.0], "
                                    "edge_v: [0.0, 0.0, 105.0]}\n")
    warnings, _ = _run(tmp_path, capsys, scene, mode="rcast")
    assert len(warnings) == 1 and warnings[0].startswith("lights[1] (quad) reaches no surface")


def _ceiling_light(scene, flip: bool) -> Light:
    ids = np.flatnonzero(scene.part == scene.part_names.index("ceiling"))
    tri = scene.triangles[ids][:, ::-1] if flip else scene.triangles[ids]
    return Light("mesh", (1e6, 1e6, 1e6), name="lamp", ids=ids, triangles=tri.copy(),
                 radiance=np.ones((ids.shape[0], 3)))


def test_a_mesh_light_facing_away_warns():
    """Emissive triangles emit on the side of cross(V1 - V0, V2 - V0): the ceiling wound
    the other way emits out of the box (its own triangles do not count as hits)."""
    scene = load_scene("cornell", None, [16, 16])
    accel = build_accel(scene.triangles)
    ceiling = _ceiling_light(scene, flip=False)
    assert checks.probe_light(scene, accel, ceiling)["hits"] > 0
    away = _ceiling_light(scene, flip=True)
    assert checks.probe_light(scene, accel, away)["hits"] == 0
    warnings = checks.light_warnings(replace(scene, lights=(*scene.lights, ceiling, away)), accel)
    assert len(warnings) == 1 and warnings[0].startswith("lights[2] (mesh 'lamp') reaches no surface")


def test_an_emissive_ceiling_scene_does_not_warn(tmp_path, capsys):
    scene = _scene(tmp_path, "lit_ceiling", "materials:\n  lamp: {type: lambertian, albedo: [0.7, 0.7, 0.7], "
                                            "emission: [5.0, 5.0, 5.0]}\nparts:\n  ceiling: lamp\nlights: []\n")
    warnings, _ = _run(tmp_path, capsys, scene, mode="rcast")
    assert warnings == []


# ---------------------------------------------------------------- the camera


def test_a_camera_inside_a_block_warns(tmp_path, capsys):
    scene = _scene(tmp_path, "inside", "camera: {eye: [368.0, 165.0, 351.0], target: [368.0, 165.0, 1000.0], "
                                       "up: [0.0, 1.0, 0.0], vfov: 39.3}\n")
    warnings, _ = _run(tmp_path, capsys, scene, mode="rcast")
    assert "(100%)" in _only(warnings, "the camera may be inside a closed mesh")


def test_a_camera_facing_nothing_warns(tmp_path, capsys):
    scene = _scene(tmp_path, "nothing", "camera: {eye: [278.0, 273.0, -800.0], target: [278.0, 273.0, -1600.0], "
                                        "up: [0.0, 1.0, 0.0], vfov: 39.3}\n")
    warnings, _ = _run(tmp_path, capsys, scene, mode="rcast")
    _only(warnings, "the camera faces nothing")
    _only(warnings, "the image is black")


def test_a_camera_inside_glass_does_not_warn(tmp_path, capsys):
    scene = _scene(tmp_path, "in_glass", f"camera: {{eye: {GLASS_CENTRE}, target: [278.0, 273.0, 559.0], "
                                         "up: [0.0, 1.0, 0.0], vfov: 39.3}\n")
    warnings, _ = _run(tmp_path, capsys, scene, mode="rcast")
    assert not [w for w in warnings if w.startswith("the camera")]


# ---------------------------------------------------------------- the thresholds


def test_thresholds():
    assert checks.camera_warnings(100, 0, 0)[0].startswith("the camera faces nothing")
    assert checks.camera_warnings(100, 80, 40) == []
    assert checks.camera_warnings(100, 80, 41)[0].startswith("the camera may be inside")
    assert checks.camera_warnings(0, 0, 0) == []
    z = np.zeros((2, 2, 3))
    assert checks.image_warnings({"a": z, "b": z})[0].startswith("the image is black: every pixel")
    tiny = z.copy()
    tiny[0, 0, 0] = 1e-30
    assert checks.image_warnings({"a": tiny}) == []  # no scale: only exact black
    assert checks.image_warnings({"a": tiny}, scale=0.3)[0].startswith("the image is black: its brightest")
    tiny[0, 0, 0] = 1e-6
    assert checks.image_warnings({"a": tiny}, scale=0.3) == []
    assert checks.photon_warnings(1000, 9)[0].startswith("the photon map stored 9 of 1000")
    assert checks.photon_warnings(1000, 10) == []
    assert checks.photon_warnings(0, 0) == []


def test_probes_are_deterministic():
    scene = load_scene("ring", None, [16, 16])
    accel = build_accel(scene.triangles)
    a = checks.probe_light(scene, accel, scene.lights[0])
    assert a == checks.probe_light(scene, accel, scene.lights[0])
    assert a["rays"] == 2 * checks.PROBE_RAYS and 0 < a["hits"] < a["rays"] and a["back"] == 0  # (spread, aimed)


# ---------------------------------------------------------------- the built-in scenes


@pytest.mark.slow
@pytest.mark.parametrize("name", ["cornell", "ring", "room"])
def test_no_warning_on_the_built_in_scenes(name, tmp_path, capsys, cache):
    """No line on the scenes themselves. The stream's period line (h453) is the timing of this tiny
    frame (ring, pmap at 16x16 with two images in flight: a period of two frames 15% apart), not of
    the scene: it is left out here, and only it. In a cache of its own: a reference another run left in the
    user's cache (--no-reference uses a cached one), not converged at 16x16, would be said, rightly."""
    warnings, stderr = _run(tmp_path, capsys, name)
    period = "the stream settled into a period of "
    assert [w for w in warnings if not w.startswith(period)] == []
    assert [e for e in stderr if not e.startswith(period)] == []


# ---------------------------------------------------------------- settings with no effect


def test_a_setting_the_run_does_not_use_is_named(tmp_path, capsys):
    """A knob set away from its default that this run never reads (the k of a filter that
    samples no k voxels, a fraction under a radius given in scene units, the dynamic
    scheduler's tiles under the static one) is a warning, not taken silently."""
    config = tmp_path / "knobs.yaml"
    config.write_text("scene: cornell\nmode: pmap\nphotons: {count: 2000}\n"
                      "estimate: {filter: mvoxel, k: 16, radius: 20.0, "
                      "radius_fraction: 0.02}\narch: {scheduler: static, tiles_per_pipeline: 8}\n")
    out = tmp_path / "out"
    assert main(["run", str(config), "--out", str(out), "--no-progress", "--no-report", "--no-reference",
                 "--outputs", "images", *SMALL]) == 0
    err = capsys.readouterr().err
    results = json.loads((out / "results.json").read_text())
    inert = [w for w in results["warnings"] if "has no effect in this run" in w]
    assert inert == [
        "estimate.k = 16 has no effect in this run: estimate.filter is 'mvoxel': only 'kvoxel' samples k voxels",
        "estimate.radius_fraction = 0.02 has no effect in this run: estimate.radius is set, and comes first",
        "arch.tiles_per_pipeline = 8 has no effect in this run: arch.scheduler is 'static' (one tile a pipeline): "
        "only 'dynamic' queues tiles"]
    assert all(f"tlm: warning: {w}" in err for w in inert)


def test_inert_settings_follow_the_filter_the_mode_and_the_scheduler():
    from tlm.config import config_from_dict
    from tlm.render.planner import inert_changes, inert_settings

    kv = inert_settings(config_from_dict({"mode": "pmap", "estimate": {"filter": "kvoxel"}}))
    assert "estimate.k" not in kv and "estimate.k_nearest" in kv and "estimate.cone_k" not in kv
    knn = inert_settings(config_from_dict({"mode": "pmap", "estimate": {"filter": "knn", "final_gather": 0}}))
    assert "estimate.k_nearest" not in knn and "estimate.k" in knn and "estimate.final_gather_photons" in knn
    disk = inert_settings(config_from_dict({"mode": "pmap", "estimate": {"filter": "disk"}}))
    assert "estimate.cone_k" in disk
    dyn = inert_settings(config_from_dict({"mode": "pmap", "arch": {"scheduler": "dynamic"}}))
    assert "arch.tiles_per_pipeline" not in dyn
    rcast = inert_settings(config_from_dict({"mode": "rcast"}))
    assert rcast["photons.count"].startswith("the photon-map pass does not run (mode 'rcast'")
    # a config holding photon settings for --mode pmap is not warned about in its own mode
    assert inert_changes(config_from_dict({"mode": "refract", "photons": {"count": 200000}})) == []
    assert inert_changes(config_from_dict({"mode": "pmap"})) == []  # the defaults: nothing to say


@pytest.mark.parametrize(("arch", "cache", "key", "why"), [
    ({"fanout": "serial"}, {}, "arch.fanout = 'serial'", "arch.pipelines is 1 (no other pipeline to copy to)"),
    ({"images_in_flight": 1, "context_switch_cycles": 0}, {}, "arch.context_switch_cycles = 0",
     "arch.images_in_flight is 1 (a PM never has an older image's job to switch to)"),
    ({}, {"pairs": 2}, "cache.pairs = 2", "a PM phase reads at most 2 cached streams, so 2 or more pairs give each a "
                                          "pair of its own, as the default 4 does"),
    ({}, {"pairs": 3}, "cache.pairs = 3", "a PM phase reads at most 2 cached streams"),
])
def test_timing_settings_that_cannot_change_cycles_are_named(arch, cache, key, why):
    """Copies to other pipelines with one pipeline, context switches with one image in
    flight, cache pairs beyond a phase's streams: each changes no cycle
    (test_inert_timing_settings_change_no_cycle), and the run says so; where the same key
    can matter (two pipelines, two images, one pair), it says nothing."""
    from tlm.config import config_from_dict
    from tlm.render.planner import inert_changes

    lines = inert_changes(config_from_dict({"arch": arch, "cache": cache}))
    assert len(lines) == 1 and lines[0].startswith(f"{key} has no effect in this run: {why}")
    where_it_matters = {"fanout": {"pipelines": 2}, "context_switch_cycles": {"images_in_flight": 2}}
    for k in arch:
        if k in where_it_matters:
            assert inert_changes(config_from_dict({"arch": {**arch, **where_it_matters[k]}})) == []
    if cache:
        assert inert_changes(config_from_dict({"cache": {"pairs": 1}})) == []


def test_inert_timing_settings_change_no_cycle():
    """What those warnings claim, simulated: the same cycles (and work) at the inert value as
    at the default, and each value warned of."""
    from tlm.arch.costs import load_programs
    from tlm.arch.model import simulate
    from tlm.config import config_from_dict
    from tlm.experiments.run import render
    from tlm.render.planner import inert_changes

    cfg = config_from_dict({"scene": "cornell", "mode": "rcast", "resolution": [12, 12], "render": {"spp": 1},
                            "arch": {"frames": 2, "packet_size": 16, "trace": False}}, "test")
    fn, programs = render(cfg).functional(), load_programs()

    def same(**kw):
        changed = replace(cfg, arch=replace(cfg.arch, **kw))
        default = replace(cfg.arch, **{k: v for k, v in kw.items() if k == "images_in_flight"})
        assert simulate(fn, programs, changed.arch).cycles == simulate(fn, programs, default).cycles
        return inert_changes(changed)

    assert len(same(fanout="serial")) == 1
    assert len(same(images_in_flight=1, context_switch_cycles=0)) == 1
    two = replace(cfg, cache=replace(cfg.cache, pairs=2))
    assert render(two).work_totals() == render(cfg).work_totals() and len(inert_changes(two)) == 1


def test_what_only_the_run_can_tell_is_warned_of(tmp_path, capsys):
    """A 4x4 image cut for 32 pipelines (a 4x8 grid: 16 tiles without a pixel), one image in
    flight and one frame (already the steady value: no "too short" warning), the serial
    fan-out (32 pipelines: it matters) and a FIFO depth no packet of 16 pixels can feel, not called
    unread (h349: the packets-of-one estimate, timing.granularity, reads arch.fifo_depth unless a
    phase's addresses plus arch.packet_size a packet fit in the smaller depth, 1024; not here), but said to
    change no simulated cycle by the FIFOs' peaks (h425: every put found its FIFO empty at either depth)."""
    out = tmp_path / "o"
    assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--out", str(out), "--no-progress", "--no-report",
                 "--no-reference", "--outputs", "images", "--mode", "rcast", "--set", "resolution=[4,4]",
                 "--set", "render.spp=1", "--set", "arch.pipelines=32", "--set", "arch.images_in_flight=1",
                 "--set", "arch.frames=1", "--set", "arch.fanout=serial", "--set", "arch.fifo_depth=2048"]) == 0
    err = capsys.readouterr().err
    warnings = json.loads((out / "results.json").read_text())["warnings"]
    assert warnings == [
        "arch.pipelines = 32: 16 of the 32 image tiles have no pixels (a 4x4 image cut into a 4x8 grid): a pipeline "
        "given one has no pixel work in it",
        "arch.fifo_depth = 2048 changes no simulated cycle in this run (cycles, stalls and frame times are those of "
        "the default 1024): no FIFO held more than 1 packet, entries 924 of 2048 (an entry a triangle address, a "
        "packet the whole FIFO at most) or triangle addresses 924 (not cut to the depth) "
        "at once (timing.fifo: peak_packets, peak_entries, peak_addresses); every "
        "put found its FIFO empty, so no put ever waited, at depth 1024 or at 2048; only timing.granularity, the "
        "packets-of-one estimate, reads the depth (lower arch.packet_size to see it in the cycles)"]
    assert all(f"tlm: warning: {w}" in err for w in warnings)


def test_a_coarse_packet_is_warned_of_and_its_estimate_holds(tmp_path, capsys, monkeypatch):
    """Cornell refract at 32x32, one image in flight, packets of 256: four packets per ray
    pass, whose hand-overs add about a sixth to TThru (timing.granularity.share); tlm run
    says so, and tlm granularity measures as much against packets of one (with one image
    in flight the estimate is the change itself: share = change / TThru, the measured
    error change / (TThru - change))."""
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    config = tmp_path / "c.yaml"
    run_cfg = {"scene": "cornell", "mode": "refract", "resolution": [32, 32],
               "arch": {"frames": 2, "images_in_flight": 1, "trace": False}}
    config.write_text(json.dumps(run_cfg))
    out = tmp_path / "r"
    assert main(["run", str(config), "--out", str(out), "--no-progress", "--no-report", "--no-reference",
                 "--outputs", "images"]) == 0
    results = json.loads((out / "results.json").read_text())
    share = results["timing"]["granularity"]["share"]
    (line,) = [w for w in results["warnings"] if w.startswith("arch.packet_size = 256 is coarse for this frame: ")]
    assert f"about {share:.0%} of cycles.throughput" in line and f"tlm: warning: {line}" in capsys.readouterr().err
    study = tmp_path / "g.yaml"
    study.write_text(json.dumps({"base": run_cfg, "packet_sizes": [1, 256]}))
    assert main(["granularity", str(study), "--out", str(tmp_path / "g"), "--no-report"]) == 0
    fine, coarse = (json.loads(x) for x in (tmp_path / "g" / "granularity.jsonl").read_text().splitlines())
    assert coarse["throughput"] == results["cycles"]["throughput"] and coarse["granularity_share"] == share
    assert coarse["rel_error_throughput"] == pytest.approx(share / (1 - share), abs=1e-4)  # (share: 4 digits)
    assert fine["granularity_share"] == 0.0


def test_a_sweep_factor_that_changes_nothing_is_warned_about(tmp_path, capsys):
    from tlm.experiments.sweep import load_sweep

    path = tmp_path / "sw.yaml"
    path.write_text("base: {scene: cornell, mode: rcast}\ngrid: {photons.count: [1000, 2000], "
                    "arch.fifo_depth: [1, 16]}\n")
    assert load_sweep(path).inert_factors() == [
        f"{path}: the factor photons.count changes nothing in any point: the photon-map pass does not run "
        "(mode 'rcast' does not include the pmap (photon-map) pass)"]
    path.write_text("base: {scene: cornell, mode: pmap}\n"
                    "zip: {estimate.filter: [mvoxel, kvoxel], estimate.k: [4, 8]}\n")
    assert load_sweep(path).inert_factors() == []  # (k matters in the kvoxel point)


def test_a_light_close_to_a_huge_surface_finds_it(tmp_path, capsys):
    """A floor 1e8 across, a point light 3 above it: the probes start where the light's
    coordinates' precision allows, not 1e-5 of the scene's diagonal (1,400) away, past the floor."""
    (tmp_path / "floor.obj").write_text("v -5e7 0 -5e7\nv 5e7 0 -5e7\nv 5e7 0 5e7\nv -5e7 0 5e7\nf 1 4 3 2\n")
    path = tmp_path / "floor.yaml"
    path.write_text("geometry: {mesh: floor.obj}\nmaterials: {m: {type: lambertian, albedo: [0.7, 0.7, 0.7]}}\n"
                    "default_material: m\nlights: [{type: point, position: [0, 3, 0], power: [100, 100, 100]}]\n"
                    "camera: {eye: [0, 10, -10], target: [0, 0, 0], vfov: 40}\nresolution: [16, 16]\n")
    scene = load_scene(str(path), None, [16, 16])
    p = checks.probe_light(scene, build_accel(scene.triangles), scene.lights[0])
    assert p["hits"] > 0 and p["back"] == 0
    warnings, _ = _run(tmp_path, capsys, path, mode="rcast")
    assert warnings == []
