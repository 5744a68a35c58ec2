"""h465: the blur line (tlm.experiments.run_warnings.blur_warnings, h453) compares like with like, per photon map:
each map's own photons a round (the run's caustic group, photons.caustic_count or caustic_fraction of its photons,
feeds its caustic map, the rest its indirect one; the reference's half each, with a mirror or glass; every photon
the indirect map without), and the photons each kernel holds where both take the k nearest alike (filter: knn's
estimate.k_nearest, the indirect map's density rule radius_photons without final gathering; elsewhere the photons
alone). It names the worst map. (h465 also told a k-NN run whose estimate.k_nearest, past the reference's, gathers
over more than BLUR_RATIO times the reference's area that it is the blurrier by design; h478 took that line out: the
error measures a run's own blur as it should, and a run of fewer photons, as blurry, was never told.)"""

from __future__ import annotations

import json

import pytest

import tlm
from tlm.config import config_from_dict
from tlm.experiments.frames import cached_render
from tlm.experiments.run_warnings import BLUR_RATIO, blur_warnings

ERROR = {"available": True, "reference": "k"}
BLUR = "measure the reference's blur more"


def _cfg(scene: str = "cornell", **sections) -> object:
    return config_from_dict({"scene": scene, "mode": "pmap", **sections}, "t")


def _lines(cfg, emitted: int, caustic: int = 1, scene_photons: int = 120000) -> list[str]:
    # (caustic: the caustic photons the run's maps stored, as results.json photons.caustic: 0 without a mirror or glass)
    return blur_warnings(ERROR, cfg, {"emitted": emitted, "caustic": caustic}, scene_photons)


def test_the_caustic_group_is_compared_with_the_references_half():
    assert BLUR_RATIO == 4
    # (350000 in all, 2.92x the reference's 120000: no line before; 0.75 of it is 4.375x the reference's 60000)
    lines = _lines(_cfg(photons={"count": 350000, "caustic_fraction": 0.75}), 350000)
    assert lines == [
        "the photon-map frame's caustic map gets 262500 of the 350000 photons it emits, and that map of its "
        "reference k gets 60000 a round (half of the scene's 120000: reference.photons null): each k-NN round of the "
        "reference (100 photons: reference.k_nearest) gathers in a map 4.38x sparser than this run's, so the pmap "
        "error against it (error.rmse, error.rel_mse) may measure the reference's blur more than this run's noise; "
        "raise reference.photons to 131250 or more (at most 4x this run's on that map) and compute it again with "
        "'tlm reference'"]
    # (a caustic budget of its own: 300000 beside the global group's 100000, 3.33x in all, 5x on the caustic map)
    budget = _lines(_cfg(photons={"count": 100000, "caustic_count": 300000}, reference={"photons": 120000}), 400000)
    assert len(budget) == 1 and "caustic map gets 300000 of the 400000 photons" in budget[0]
    assert "60000 a round (half of reference.photons 120000)" in budget[0] and "to 150000 or more" in budget[0]
    # (its global group alone past the ratio: 500000 against 60000, the caustic map's 300000 5x)
    both = _lines(_cfg(photons={"count": 500000, "caustic_count": 300000}), 800000)
    assert len(both) == 1 and "global map gets 500000 of the 800000 photons" in both[0] and "8.33x sparser" in both[0]


def test_without_a_mirror_or_glass_every_photon_is_the_indirect_maps():
    # (cornell-box: Lambertian only, no caustic photon stored: the reference's photons all its indirect map's too)
    lines = _lines(_cfg("cornell-box"), 500000, caustic=0)
    assert len(lines) == 1 and "global map gets 500000 of the 500000 photons it emits, and that map of its " \
        "reference k gets 120000 a round (the scene's 120000: reference.photons null)" in lines[0] \
        and "4.17x sparser" in lines[0]
    assert _lines(_cfg("cornell-box"), 480000, caustic=0) == []
    # (no caustic map to compare: a k-NN run of 20 is 5x on its indirect map alone)
    knn = _lines(_cfg("cornell-box", estimate={"filter": "knn", "k_nearest": 20, "final_gather": 0}), 120000, caustic=0)
    assert len(knn) == 1 and "indirect map gets 120000" in knn[0]


def test_a_knn_run_compares_its_k_with_the_references():
    knn = {"filter": "knn", "final_gather": 0}
    # (the reference's photons, 20 nearest against its 100: its kernel 5x the area on both maps; the first named)
    lines = _lines(_cfg(estimate={**knn, "k_nearest": 20}), 120000)
    assert len(lines) == 1 and "indirect map gets 60000 of the 120000 photons it emits" in lines[0]
    assert "gathers over 5.00x the area of this run's gathers of 20 (estimate.k_nearest)" in lines[0]
    assert "raise reference.photons to 150000 or more" in lines[0]
    # (5x the photons, 500 nearest: the same area as the reference's 100, no line; h453 said 5x)
    assert _lines(_cfg(estimate={**knn, "k_nearest": 500}), 600000) == []
    # (final gathering: its global map a bounce away by photons alone; the caustic map still by k)
    fg = _lines(_cfg(estimate={**knn, "k_nearest": 20, "final_gather": 16}), 120000)
    assert len(fg) == 1 and "caustic map gets 60000" in fg[0] and "gathers of 20 (estimate.k_nearest)" in fg[0]


def test_a_knn_run_blurrier_than_its_reference_is_not_told():
    """h478: a k-NN run of 500 nearest against the reference's 100, the same photons, gathers over 5x its area:
    the error measures that blur, as it does a run of 5x fewer photons (never told), so no line."""
    knn = {"filter": "knn", "final_gather": 0}
    assert _lines(_cfg(estimate={**knn, "k_nearest": 500}), 120000) == []
    assert _lines(_cfg(estimate={**knn, "k_nearest": 100}), 24000) == []  # (5x fewer photons, as blurry)
    assert _lines(_cfg(estimate={"radius_photons": 1000, "final_gather": 0}), 120000) == []


def test_the_indirect_maps_density_rule_compares_its_photons():
    one = {"final_gather": 0, "caustic_radius_fraction": 0.01}  # (the caustic map's radius fixed: not compared)
    # (5x the photons, a radius holding about 500: as wide as the reference's 100; h453 said 5x)
    assert _lines(_cfg(estimate={**one, "radius_photons": 500}), 600000) == []
    lines = _lines(_cfg(estimate={**one, "radius_photons": 20}), 120000)
    assert len(lines) == 1 and "indirect map gets 60000" in lines[0] \
        and "gathers over 5.00x the area of this run's gathers of 20 (estimate.radius_photons)" in lines[0]
    # (the caustic map's density rule and final gathering's global map: the photons alone, at any k; the defaults:
    # caustic_radius_photons 8, final_gather_photons 16 against the reference's 100 give no line)
    assert _lines(_cfg(), 120000) == []
    assert len(_lines(_cfg(), 482000)) == 1


TINY = {"mode": "pmap", "resolution": [8, 8], "render.spp": 1, "render.light_samples": 1, "photons.count": 2000,
        "reference.photons": 2000, "reference.k_nearest": 20, "reference.spp": 1, "reference.min_rounds": 2,
        "reference.max_rounds": 4, "arch.packet_size": 16, "arch.frames": 2,
        "estimate.filter": "knn", "estimate.k_nearest": 4, "estimate.final_gather": 0}


@pytest.mark.parametrize("k, said", [(4, 1), (200, 0)])
def test_a_run_and_its_cached_frame_say_the_line(tmp_path, cache, k, said):
    """A run's k-NN estimate of 4 nearest against its reference's 20, the same photons: the reference's kernel 5x
    the run's, in results.json and again when the cached frame is read; of 200, the run's 10x the reference's: no
    line either time (h478: the run's own blur, which its error measures)."""
    cfg = tlm.load_config("cornell", {**TINY, "estimate.k_nearest": k})
    ran = tlm.run(cfg, tmp_path / "r", outputs="images")
    assert ran["error"]["available"] and ran["photons"]["caustic"] > 0
    lines = [w for w in ran["warnings"] if "k_nearest" in w]  # (h465's line on a run blurrier said estimate.k_nearest)
    assert len(lines) == said and all(BLUR in w for w in lines), ran["warnings"]
    assert json.loads((tmp_path / "r" / "results.json").read_text())["warnings"] == ran["warnings"]
    # (rendered and cached, then read: its line measured again, from the count its summary keeps)
    for cached in (False, True):
        got = cached_render(cfg.settings, cfg.base, cfg.label)
        assert got.cached is cached and [w for w in got.summary["warnings"] if "k_nearest" in w] == lines
