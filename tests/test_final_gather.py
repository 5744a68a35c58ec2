"""Final gathering (``estimate.final_gather``): rays from every gather point gather the
global map where they land, in place of the indirect map's estimate at the point."""

from __future__ import annotations

import numpy as np
import pytest

from tlm.config import config_from_dict
from tlm.experiments.run import render
from tlm.kernels.photons import trace_photons
from tlm.kernels.traverse import build_accel
from tlm.render.frame import Frame, cast
from tlm.render.passes import fgather_pass, gather_points
from tlm.render.planner import plan
from tlm.render.pmap import final_gather_directions, pmap_pass
from tlm.scenes.loader import load_scene

from .scenes import sphere_scene


@pytest.fixture(scope="module")
def furnace(tmp_path_factory):
    path = sphere_scene(tmp_path_factory.mktemp("fg_furnace"))
    scene = load_scene(str(path))
    accel = build_accel(scene.triangles)
    traced = trace_photons(scene, accel, 40000, seed=1, global_map=True)
    return path, scene, accel, traced


def _frame(path, scene, accel, **estimate):
    cfg = config_from_dict({"scene": str(path), "mode": "pmap", "estimate": estimate})
    return Frame.create(scene, accel, cfg)


@pytest.mark.slow
def test_furnace_final_gather_finds_the_indirect_half(furnace):
    """Inside a closed sphere of albedo 0.5 lit from its centre, every surface's radiance is 1,
    so the rays gather 1 everywhere and the indirect half is 0.5 (the estimator without
    final gathering finds it too: tests/test_furnace.py)."""
    path, scene, accel, traced = furnace
    frame = _frame(path, scene, accel, final_gather=16)
    g = cast(frame, np.arange(scene.camera.width * scene.camera.height))
    rad, work = pmap_pass(frame, g, traced.photons)
    assert abs(rad.mean() - 0.5) < 0.02, rad.mean()
    # each pixel averages 16 x spp smooth lookups: no pixel is far off
    assert np.abs(rad - 0.5).max() < 0.15
    fg = g.memo["fgather_work"]
    points = gather_points(frame, g)[0].shape[0]
    # a closed diffuse sphere: every ray lands on a Lambertian point, once
    assert fg["secondary_rays"].sum() == points * 16
    assert fg["fragments"].sum() == points * 16
    assert fg["specular_bounces"].sum() == 0
    assert fg["primary_rays"].sum() == 0 and fg["shadow_rays"].sum() == 0
    assert work["gathers"].sum() == points * 16  # no caustic map in a diffuse scene: the global lookups
    _, again = fgather_pass(frame, g)
    assert again is fg and "fgather_work" not in g.memo


def test_fgather_pass_needs_the_pmap_pass_first(furnace):
    path, scene, accel, _ = furnace
    frame = _frame(path, scene, accel, final_gather=4)
    g = cast(frame, np.arange(16))
    with pytest.raises(ValueError, match="pmap_pass"):
        fgather_pass(frame, g)


def test_directions_are_cosine_weighted_and_stratified():
    n = np.tile([[0.0, 0.0, 1.0]], (2000, 1))
    keys = np.arange(2000, dtype=np.int64) * 7
    j, r, d = final_gather_directions(n, keys, 16, seed=3)
    assert np.array_equal(j, np.repeat(np.arange(2000), 16)) and np.array_equal(r, np.tile(np.arange(16), 2000))
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0)
    cos = d[:, 2]
    assert cos.min() >= 0.0
    # E[cos] under a cosine-weighted pdf is 2/3; E[cos^2] is 1/2
    assert abs(cos.mean() - 2 / 3) < 0.005
    assert abs((cos ** 2).mean() - 0.5) < 0.005
    # 16 = 4 x 4 strata: the polar sample u1 = 1 - cos^2 of ray r lies in stratum r // 4
    u1 = 1.0 - cos.reshape(2000, 16) ** 2
    stratum = np.floor(u1 * 4).astype(int)
    assert np.array_equal(stratum, np.tile(np.arange(16) // 4, (2000, 1)))
    # seeded per point and ray, not by the neighbours
    _, _, d2 = final_gather_directions(n[:5], keys[:5], 16, seed=3)
    assert np.array_equal(d2, d[: 5 * 16])


def _cornell(**over):
    raw = {"scene": "cornell", "mode": "pmap", "resolution": [24, 24], "photons": {"count": 6000},
           "render": {"spp": 1}, "arch": {"frames": 2, "trace": False}}
    for k, v in over.items():
        raw.setdefault(k, {}).update(v) if isinstance(v, dict) else raw.__setitem__(k, v)
    return config_from_dict(raw)


@pytest.mark.slow
def test_plan_and_work_of_final_gathering():
    on = render(_cornell(estimate={"final_gather": 4}))
    off = render(_cornell(estimate={"final_gather": 0}))
    assert on.plan.runs("fgather") and not off.plan.runs("fgather")
    assert "fgather" in off.plan.to_dict()["left_out"]
    assert "fgather" not in on.radiance  # work only: its light is the pmap frame's
    fg = on.work["fgather"]
    points = int(on.work["pmap"]["gathers"].sum())
    # Cornell has a mirror and a glass sphere: some rays go on through them
    assert fg["secondary_rays"].sum() >= 4 * (points // 5)
    assert fg["specular_bounces"].sum() > 0
    assert fg["tri_tests"].sum() > 0 and fg["trav_misses"].sum() > 0
    # the composite is the frames' sum, the same quantity either way (the photon maps differ)
    assert abs(on.radiance["pmap"].mean() / off.radiance["pmap"].mean() - 1) < 0.1
    # the timing model charges the rays (Traversal, Intersection PMs) and their hits (Fragment PM)
    from tlm.arch.costs import load_programs
    from tlm.arch.model import simulate

    t_on = simulate(on.functional(), load_programs(), on.cfg.arch)
    t_off = simulate(off.functional(), load_programs(), off.cfg.arch)
    for pm in ("traversal", "intersection"):
        assert t_on.cycles[pm] > t_off.cycles[pm], pm
    # (the Fragment PM shades the rays' hits and gathers where they land, but each lookup of
    # ~final_gather_photons photons replaces a gather of ~radius_photons at the eye: its total
    # may go either way; the hits it shades are work of the fgather pass)
    assert fg["fragments"].sum() > 0


@pytest.mark.slow
def test_final_gathering_does_not_depend_on_the_batch():
    """Chunks of whole pixels in pixel order: radiance and work (misses included) are the
    whole image's whatever the batch of eye rays."""
    whole = render(_cornell(estimate={"final_gather": 4}))
    small = render(_cornell(estimate={"final_gather": 4}, render={"spp": 1, "batch_rays": 37}))
    for name in whole.radiance:
        assert np.array_equal(whole.radiance[name], small.radiance[name]), name
    for name in whole.work:
        for k in whole.work[name]:
            assert np.array_equal(whole.work[name][k], small.work[name][k]), (name, k)


def test_final_gather_off_plans_the_thesis_passes():
    scene = load_scene("cornell", resolution=[8, 8])
    assert plan(scene, _cornell(estimate={"final_gather": 0})).run_names == ["rcast", "reflect", "refract", "pmap"]
    assert plan(scene, _cornell()).run_names[-1] == "fgather"  # the default gathers
