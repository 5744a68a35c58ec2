"""The Fragment PM's gather costs what its filter does per accepted photon (h235).

The disk filter (eq. 3.2) only accumulates an accepted photon's power; the cone filters
(eq. 3.3: m-voxel, k-voxel, k-NN) compute its weight first. The work item
``photons_weighted`` counts the accepted photons whose weight a filter computes, and the
program table charges the weight on it, so a disk gather costs less than an m-voxel
one over the same photons, and the cone's cost per accepted photon is what it was.
"""

from __future__ import annotations

import numpy as np
import pytest

from tlm.arch.costs import load_programs
from tlm.arch.model import simulate
from tlm.config import config_from_dict
from tlm.experiments.run import render
from tlm.kernels import estimate as est
from tlm.kernels import kvoxel
from tlm.kernels.bsp import build_point_tree


def _map_and_queries(n: int = 3000, q: int = 200, seed: int = 5):
    rng = np.random.default_rng(seed)
    pos, power = rng.uniform(0, 1, (n, 3)), rng.uniform(0, 2, (n, 3))
    inc = rng.normal(size=(n, 3))
    inc /= np.linalg.norm(inc, axis=1, keepdims=True)
    pts = rng.uniform(0.1, 0.9, (q, 3))
    nrm = rng.normal(size=(q, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return pos, power, inc, build_point_tree(pos), pts, nrm


FILTERS = {
    "disk": lambda m, r: est.disk_estimate(*m, r),
    "mvoxel": lambda m, r: est.mvoxel_estimate(*m, r),
    "kvoxel": lambda m, r: kvoxel.kvoxel_estimate(*m, r, k=8),
    "knn": lambda m, r: est.knn_estimate(m[0], m[1], m[2], m[4], m[5], k_nearest=40),
}


@pytest.mark.parametrize("engine", ["numpy", "numba"])
@pytest.mark.parametrize("name", sorted(FILTERS))
def test_photons_weighted_is_what_the_filter_did(name, engine, monkeypatch):
    monkeypatch.setenv("TLM_KERNELS", engine)
    e = FILTERS[name](_map_and_queries(), 0.12)
    assert e.photons_accepted.sum() > 0
    assert e.photons_weighted.dtype == np.int64 and e.photons_weighted.shape == e.photons_accepted.shape
    if name == "disk":  # weight 1 (eq. 3.2): no weight computed
        assert not e.photons_weighted.any()
    else:  # the cone (eq. 3.3) weighs every accepted photon
        np.testing.assert_array_equal(e.photons_weighted, e.photons_accepted)


def test_disk_and_mvoxel_search_alike_and_weigh_differently():
    m = _map_and_queries()
    disk, cone = est.disk_estimate(*m, 0.12), est.mvoxel_estimate(*m, 0.12)
    for k in ("node_visits", "leaves_visited", "photons_tested", "photons_accepted", "gather_misses"):
        np.testing.assert_array_equal(getattr(disk, k), getattr(cone, k), err_msg=k)
    assert disk.photons_weighted.sum() == 0 < cone.photons_weighted.sum()


def test_an_estimate_without_the_count_weighs_every_accepted_photon():
    """An estimator written before the count (a plug-in's positional Estimate) is charged as before."""
    z = np.zeros(4, dtype=np.int64)
    acc = np.array([3, 0, 2, 7], dtype=np.int64)
    e = est.Estimate(np.zeros((4, 3)), z, z, z, acc, z, z)
    np.testing.assert_array_equal(e.photons_weighted, acc)


def test_the_table_charges_the_weight_apart():
    """photons_weighted is priced by the gather job; a cone-filtered photon costs what it did (8)."""
    ins = load_programs().jobs[("fragment", "gather")].instructions
    assert ins["photons_weighted"] > 0
    assert ins["photons_accepted"] + ins["photons_weighted"] == 8


def _frame(name: str):
    cfg = config_from_dict({"seed": 3, "scene": "cornell", "mode": "pmap", "resolution": [16, 12],
                            "photons": {"count": 1500}, "estimate": {"filter": name, "final_gather": 0},
                            "arch": {"frames": 1, "trace": False}}, "test")
    res = render(cfg)
    return res, simulate(res.functional(), load_programs(), cfg.arch)


def test_disk_fragment_cycles_below_the_cone_filters(tmp_path, monkeypatch):
    """Same scene, photon map and gathers: disk's Fragment PM spends less, every other PM the same."""
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))  # render, never read a cache
    (disk, td), (cone, tc) = _frame("disk"), _frame("mvoxel")
    assert td.cycles["fragment"] < tc.cycles["fragment"]
    for pm in ("vertex", "traversal", "intersection"):
        assert td.cycles[pm] == tc.cycles[pm], pm
    dw, cw = ({k: int(v.sum()) for k, v in r.work["pmap"].items()} for r in (disk, cone))
    assert dw["photons_accepted"] > 0 and dw["photons_weighted"] == 0
    assert cw["photons_weighted"] == cw["photons_accepted"]
    assert {k: v for k, v in dw.items() if k != "photons_weighted"} == \
        {k: v for k, v in cw.items() if k != "photons_weighted"}
    # the difference is the weight's instructions on the accepted photons (up to each packet's rounding)
    programs = load_programs()
    want = programs.scale["fragment"] * programs.jobs[("fragment", "gather")].instructions["photons_weighted"] \
        * cw["photons_weighted"]
    assert abs((tc.cycles["fragment"] - td.cycles["fragment"]) - want) <= 0.01 * want
