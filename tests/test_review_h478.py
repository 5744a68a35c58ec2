"""h478, a review of h465's per-map blur line (tlm.experiments.run_warnings.blur_warnings): (A) a run blurrier than
its reference (a k-NN estimate.k_nearest past reference.k_nearest) is not told: the error measures its own blur, as
it should, and a run of fewer photons, as blurry, never was. (B) A caustic budget of its own (photons.caustic_count)
is emitted only in a scene with a mirror or glass: where its caustic map stored nothing (glass of ior 1, the
photons cross it as if it were not there), its global group, not every photon, is the indirect map's, and the
reference's half. (C) The line says what the run's map gets of the photons it emits and what that map of its
reference gets a round (the run has no rounds), and the committed configs that draw it say what docs/usage.md
quotes."""

from __future__ import annotations

from pathlib import Path

import tlm
from tlm.config import config_from_dict, load_config
from tlm.experiments.run_warnings import blur_warnings
from tlm.scenes.loader import load_scene

ROOT = Path(__file__).resolve().parents[1]
ERROR = {"available": True, "reference": "k"}


def _lines(cfg, emitted: int, caustic: int = 1, scene_photons: int = 120000) -> list[str]:
    return blur_warnings(ERROR, cfg, {"emitted": emitted, "caustic": caustic}, scene_photons)


def test_a_run_blurrier_than_its_reference_is_not_told():
    knn = {"filter": "knn", "final_gather": 0, "k_nearest": 500}
    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "estimate": knn}, "t")
    assert _lines(cfg, 120000) == []  # (500 nearest of the same photons: 5x the reference's area)
    assert _lines(cfg, 12000) == []  # (and of 10x fewer: 50x)


def test_a_caustic_budget_is_a_mirror_or_glass_even_where_its_caustic_map_stored_nothing():
    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "photons": {"count": 100000, "caustic_count": 400000},
                            "estimate": {"final_gather": 0}}, "t")
    # (its indirect map gets the global group's 100000, the reference's 60000: 1.67x; no caustic map to compare)
    assert _lines(cfg, 500000, caustic=0) == []
    line = _lines(cfg, 500000)  # (with caustic photons stored: the caustic map's 400000 against 60000)
    assert len(line) == 1 and "caustic map gets 400000 of the 500000 photons" in line[0]


def test_a_run_whose_glass_stores_no_caustic_photon(tmp_path, cache):
    scene = tmp_path / "matched.yaml"
    scene.write_text(f"extends: {ROOT / 'scenes' / 'cornell.yaml'}\nname: matched\nmaterials:\n"
                     "  chrome: {type: lambertian, albedo: [0.5, 0.5, 0.5]}\n"
                     "  glass: {ior: 1.0, transmittance: [1.0, 1.0, 1.0]}\n")
    cfg = tlm.load_config({"scene": str(scene)}, {"mode": "pmap", "resolution": [8, 8], "render.spp": 1,
                           "render.light_samples": 1, "photons.count": 2000, "photons.caustic_count": 8000,
                           "reference.photons": 2000, "reference.k_nearest": 20, "reference.spp": 1,
                           "reference.min_rounds": 2, "reference.max_rounds": 4, "arch.packet_size": 16,
                           "arch.frames": 2, "estimate.filter": "knn", "estimate.k_nearest": 20,
                           "estimate.final_gather": 0})
    ran = tlm.run(cfg, tmp_path / "r", outputs="images")
    assert ran["error"]["available"] and ran["photons"]["emitted"] == 10000 and ran["photons"]["caustic"] == 0
    # (its indirect map: the global group's 2000 against the reference's 1000, 2x; h465 took all 10000 against 2000)
    assert [w for w in ran["warnings"] if "reference.k_nearest" in w] == []


def test_the_line_and_the_committed_configs_it_names():
    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "estimate": {"final_gather": 0}}, "t")
    assert _lines(cfg, 500000) == [
        "the photon-map frame's indirect map gets 250000 of the 500000 photons it emits, and that map of its "
        "reference k gets 60000 a round (half of the scene's 120000: reference.photons null): each k-NN round of the "
        "reference (100 photons: reference.k_nearest) gathers over 4.17x the area of this run's gathers of 100 "
        "(estimate.radius_photons), so the pmap error against it (error.rmse, error.rel_mse) may measure the "
        "reference's blur more than this run's noise; raise reference.photons to 125000 or more (at most 4x this "
        "run's on that map) and compute it again with 'tlm reference'"]
    # (docs/usage.md's two: cornell-water's caustic map, 1,500,000 against 240,000; ring's global map, 200,000
    # against 10,000; both with a mirror or glass)
    for name, said in (("cornell-water", "caustic map gets 1500000 of the 2000000 photons it emits, and that map of "
                        "its reference k gets 240000 a round (half of the scene's 480000"),
                       ("ring", "global map gets 200000 of the 300000 photons it emits, and that map of its reference "
                        "k gets 10000 a round (half of the scene's 20000")):
        run, base = load_config(ROOT / "configs" / f"{name}.yaml", ["mode=pmap"])
        photons = load_scene(run.scene, base).photons
        emitted = (run.photons.count or photons) + (run.photons.caustic_count or 0)
        [line] = _lines(run, emitted, scene_photons=photons)
        assert said in line, line
