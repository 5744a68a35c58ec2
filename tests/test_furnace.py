"""The furnace test: inside a closed diffuse sphere of albedo 0.5 with a point light of
intensity pi at its centre, radiance is 1 everywhere.

Direct light gives ``0.5 / pi * pi / 1**2 = 0.5`` (the ray-cast frame); the photon map
holds everything after the first bounce, ``0.5 / pi * (E_total - E_direct)`` with
``E_total = E_direct / (1 - 0.5)``, so the photon-map frame is 0.5 too.
"""

from __future__ import annotations

import numpy as np
import pytest

from tlm.config import config_from_dict
from tlm.kernels.photons import trace_photons
from tlm.kernels.traverse import build_accel
from tlm.render.frame import Frame, cast
from tlm.render.passes import rcast_pass
from tlm.render.pmap import pmap_pass
from tlm.scenes.loader import load_scene

from .scenes import sphere_scene

FILTERS = ("disk", "mvoxel", "kvoxel", "knn")


@pytest.fixture(scope="module")
def furnace(tmp_path_factory):
    path = sphere_scene(tmp_path_factory.mktemp("furnace"))
    scene = load_scene(str(path))
    accel = build_accel(scene.triangles)
    cfg = config_from_dict({"scene": str(path), "mode": "pmap"})
    frame = Frame.create(scene, accel, cfg)
    g = cast(frame, np.arange(scene.camera.width * scene.camera.height))
    maps = {n: trace_photons(scene, accel, n, seed=1).photons for n in (10000, 160000)}
    return path, scene, accel, g, maps


def _pmap(furnace, n, filt, radius_fraction=0.04):
    path, scene, accel, g, maps = furnace
    # the k-NN estimate is consistent when k grows with the photons (k ~ sqrt(n))
    k_nearest = int(2 * np.sqrt(n))
    cfg = config_from_dict({"scene": str(path), "mode": "pmap",
                            "estimate": {"filter": filt, "radius_fraction": radius_fraction, "k_nearest": k_nearest}})
    rad, work = pmap_pass(Frame.create(scene, accel, cfg), g, maps[n])
    return rad, work


@pytest.mark.slow
def test_direct_light_is_half(furnace):
    path, scene, accel, g, _ = furnace
    frame = Frame.create(scene, accel, config_from_dict({"scene": str(path)}))
    rad, _ = rcast_pass(frame, g)
    assert np.all(g.triangle >= 0)
    # a tessellated sphere: its facets are slightly nearer than 1 and slightly tilted
    np.testing.assert_allclose(rad, 0.5, rtol=0.01)


@pytest.mark.slow
@pytest.mark.parametrize("filt", FILTERS)
def test_every_estimator_finds_the_indirect_half(furnace, filt):
    rad, work = _pmap(furnace, 160000, filt)
    assert np.isfinite(rad).all()
    assert abs(rad.mean() - 0.5) < 0.02, rad.mean()  # within a few percent over the image
    assert np.all(work["gathers"] == furnace[3].spp)  # every sample of every pixel gathers


@pytest.mark.slow
@pytest.mark.parametrize("filt", FILTERS)
def test_error_falls_as_photons_grow(furnace, filt):
    few, _ = _pmap(furnace, 10000, filt)
    many, _ = _pmap(furnace, 160000, filt)
    rmse = [float(np.sqrt(np.mean((x - 0.5) ** 2))) for x in (few, many)]
    assert rmse[1] < rmse[0], rmse
