"""The density rule of the search radius: the radius that holds about k photons of a map.

A gather then tests and accepts a bounded number of photons whatever the scene's size
and photon count (the fixed fraction of the diagonal did not: its accepted photons grow
with the map), the radius follows the scene's scale, and it depends on the map alone.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from tlm.cli import main
from tlm.config import EstimateConfig, config_from_dict
from tlm.experiments.run import render
from tlm.kernels.estimate import density_radius
from tlm.render.frame import Frame
from tlm.render.pmap import caustic_radius, radii, radius_rule, search_radius

REPO = Path(__file__).resolve().parents[1]
OLD = {"radius_fraction": 0.04, "caustic_radius_fraction": 0.01}
K, KC = EstimateConfig().radius_photons, EstimateConfig().caustic_radius_photons  # the defaults: 100, 8


def _render(scene: str, photons: int, estimate: dict | None = None, aim: str = "parts", **extra):
    # the indirect map gathered at the eye hits (final gathering off): the rule under test
    raw = {"scene": scene, "mode": "pmap", "resolution": [16, 16], "render": {"spp": 1},
           "photons": {"count": photons, "aim": aim}, "estimate": {"final_gather": 0, **(estimate or {})}, **extra}
    return render(config_from_dict(raw))


def _per_gather(res) -> dict[str, tuple[float, float]]:
    g = int(res.work["pmap"]["gathers"].sum())
    assert g > 0
    return {m: (t["photons_tested"] / g, t["photons_accepted"] / g) for m, t in res.gather_maps.items()}


# ---------------------------------------------------------------- the kernel


def test_uniform_photons_give_the_radius_of_k_photons():
    """Photons uniform on a unit square: pi r^2 n = k within a few percent."""
    rng = np.random.default_rng(3)
    n, k = 40000, 64
    pos = np.column_stack([rng.random(n), rng.random(n), np.zeros(n)])
    r = density_radius(pos, k)
    assert r == pytest.approx(math.sqrt(k / (math.pi * n)), rel=0.06)


def test_the_photon_itself_is_not_its_neighbour():
    pos = np.array([[0.0, 0.0, 0.0], [3.0, 4.0, 0.0]])
    assert density_radius(pos, 1) == 5.0
    assert density_radius(pos, 50) == 5.0  # k capped at n - 1
    assert density_radius(pos[:1], 8) is None  # nothing to measure: the caller falls back
    assert density_radius(np.zeros((0, 3)), 8) is None
    assert density_radius(np.zeros((5, 3)), 2) is None  # stacked on one point


def test_deterministic_and_scale_equivariant():
    rng = np.random.default_rng(7)
    pos = rng.random((5000, 3)) * [100.0, 1.0, 50.0]
    r = density_radius(pos, 32)
    assert density_radius(pos.copy(), 32) == r  # the same map (not the cached array): the same radius
    assert density_radius(pos, 32) == r
    assert density_radius(pos * 1e6, 32) == pytest.approx(r * 1e6, rel=1e-12)
    assert density_radius(pos + 1e3, 32) == pytest.approx(r, rel=1e-9)
    with pytest.raises(ValueError):
        density_radius(pos, 0)


# ---------------------------------------------------------------- the config


@pytest.mark.slow
def test_rules_and_their_precedence():
    res = _render("cornell", 3000)
    photons = res.photons.photons
    frame = res.frame
    diag = frame.accel.scale
    assert radius_rule(frame, "indirect") == radius_rule(frame, "caustic") == "density"
    assert search_radius(frame, photons) == density_radius(photons.indirect_map.position, K)
    assert caustic_radius(frame, photons) == density_radius(photons.caustic_map.position, KC)
    with pytest.raises(ValueError, match="density rule"):
        search_radius(frame)
    for est, want in (({"radius_fraction": 0.02}, (0.02 * diag, None)),
                      ({"radius": 7.0, "radius_fraction": 0.02, "caustic_radius_fraction": 0.01},
                       (7.0, 0.01 * diag)),
                      ({"radius_photons": 16, "caustic_radius": 3.0}, (None, 3.0))):
        f = Frame.create(res.scene, res.accel, config_from_dict({"scene": "cornell", "estimate": est}))
        r = radii(f, photons)
        if want[0] is not None:
            assert r["radius"] == want[0]
        if want[1] is not None:
            assert r["caustic_radius"] == want[1]
    f = Frame.create(res.scene, res.accel, config_from_dict({"scene": "cornell", "estimate": {"radius_photons": 16}}))
    assert radii(f, photons)["radius"] == density_radius(photons.indirect_map.position, 16)
    assert radii(f, photons)["radius"] < radii(frame, photons)["radius"]


def test_the_old_rule_pinned_gives_the_old_radii():
    res = _render("cornell", 3000, OLD)
    diag = res.frame.accel.scale
    assert radii(res.frame, res.photons.photons) == {"radius": 0.04 * diag, "radius_rule": "fraction",
                                                      "caustic_radius": 0.01 * diag,
                                                      "caustic_radius_rule": "fraction"}


# ---------------------------------------------------------------- gathers stay bounded


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["cornell", "room"])
def test_photons_per_gather_do_not_grow_with_the_map(scene):
    """8x the photons: the density rule accepts about as many per gather (the fraction rule
    ~8x as many), and tests a bounded number."""
    small, large = _render(scene, 4000), _render(scene, 32000)
    old_small, old_large = _render(scene, 4000, OLD), _render(scene, 32000, OLD)
    a, b = _per_gather(small)["indirect"], _per_gather(large)["indirect"]
    assert 0.6 < b[1] / a[1] < 1.6
    assert 0.15 * K < b[1] < 2 * K  # about radius_photons (fewer: gathers sit where photons are sparser)
    for res in (small, large):
        for m, (tested, accepted) in _per_gather(res).items():
            assert accepted <= tested < 8 * K, (scene, m)
    old_a, old_b = _per_gather(old_small)["indirect"], _per_gather(old_large)["indirect"]
    assert old_b[1] / old_a[1] > 3


def test_ring_caustic_default_keeps_its_gathers_bounded():
    res = _render("ring", 6000)
    (tested, accepted), = _per_gather(res).values()  # the ring's one (caustic) map
    assert 0 < accepted <= tested < 8 * K


@pytest.mark.slow
def test_a_scaled_scene_gathers_the_same_photons():
    """Cornell at 1e6 times its size: the radius x 1e6, the same photons accepted, and the
    same photons tested up to the photon BSP's splits (rounding moves a few photons across)."""
    # (one aiming box: the cone mixture of photons.aim parts rounds differently at 1e6 times the
    # size, which moves a few caustic photons and so the caustic radius)
    base = _render("cornell", 4000, aim="box")
    big = _render(str(REPO / "scenes" / "extreme" / "cornell_scale_1e6.yaml"), 4000, aim="box")
    rb, rg = radii(base.frame, base.photons.photons), radii(big.frame, big.photons.photons)
    for key in ("radius", "caustic_radius"):
        assert rg[key] == pytest.approx(rb[key] * 1e6, rel=1e-9)
    for m in ("caustic", "indirect"):
        assert big.gather_maps[m]["photons_accepted"] == base.gather_maps[m]["photons_accepted"]
        assert big.gather_maps[m]["photons_tested"] == pytest.approx(base.gather_maps[m]["photons_tested"], rel=0.05)


@pytest.mark.slow
def test_independent_of_batches():
    one = _render("cornell", 3000)
    many = _render("cornell", 3000, render={"spp": 1, "batch_rays": 37})
    assert np.array_equal(one.radiance["pmap"], many.radiance["pmap"])
    assert one.gather_maps == many.gather_maps
    assert radii(one.frame, one.photons.photons) == radii(many.frame, many.photons.photons)


# ---------------------------------------------------------------- results.json and the summary


@pytest.mark.slow
def test_results_and_summary_report_radii_and_work_per_gather(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", str(REPO / "configs" / "cornell_pmap.yaml"), "--out", str(out), "--no-progress", "--no-report",
                 "--outputs", "images", "--set", "resolution=[16,16]", "--set", "photons.count=3000",
                 "--set", "arch.packet_size=16", "--no-reference"])  # (at 256 a 16x16 frame warns of coarse packets)
    assert code == 0
    text = capsys.readouterr().out
    r = json.loads((out / "results.json").read_text())
    ph, w = r["photons"], r["work"]
    assert ph["radius_rule"] == ph["caustic_radius_rule"] == "density"
    assert ph["radius_photons"] == K and ph["caustic_radius_photons"] == KC
    assert ph["radius"] > 0 and ph["caustic_radius"] > 0
    gathers = w["pmap"]["gathers"]
    # final gathering (the default): the caustic map at the gather points, the global map where
    # the final-gather rays land; each map's work per gather of its own
    assert set(ph["gather"]) == {"caustic", "global"}
    assert ph["global_radius_rule"] == "density"
    assert ph["global_radius_photons"] == EstimateConfig().final_gather_photons
    assert sum(m["gathers"] for m in ph["gather"].values()) == gathers
    assert ph["gather"]["global"]["gathers"] > ph["gather"]["caustic"]["gathers"]
    for k in ("photons_tested", "photons_accepted"):
        assert sum(m[k] for m in ph["gather"].values()) == w["pmap"][k]
        for m in ph["gather"].values():
            assert m[f"{k}_per_gather"] == pytest.approx(m[k] / m["gathers"])
    assert w["pmap"]["photons_accepted_per_gather"] == pytest.approx(w["pmap"]["photons_accepted"] / gathers)
    assert w["rcast"]["tri_tests_per_ray"] > 0 and w["rcast"]["tri_tests_per_shadow_ray"] > 0
    assert "per gather: tested" in text and "caustic r=" in text and "global r=" in text
    assert f"(density, ~{KC} photons)" in text
    assert "per ray" in text and "per shadow ray" in text
    assert r["warnings"] == []


def test_params_document_the_rule(capsys):
    assert main(["params"]) == 0
    text = capsys.readouterr().out
    for key in ("estimate.radius_photons", "estimate.caustic_radius_photons", "estimate.radius_fraction"):
        assert key in text


def test_the_radii_made_before_the_batches_are_the_ones_the_batches_ask_for(monkeypatch):
    """``density_requests`` (what ``_warm`` computes at once on the threads before the
    batches) lists each radius the frame's ``radii`` asks for, and nothing else: with final
    gathering or without, each rule, each map."""
    import dataclasses

    import tlm.kernels.photons as photon_module
    from tlm.render.pmap import density_requests

    def fresh(photons):  # the maps without the radii the render kept
        return dataclasses.replace(photons, **{name: dataclasses.replace(m, _memo={}) for name in
                                               ("caustic_map", "indirect_map", "global_map")
                                               if (m := getattr(photons, name)) is not None})

    real = photon_module.density_radius
    asked = []
    # (a map's copies below share its position array: its id names the map)
    monkeypatch.setattr(photon_module, "density_radius", lambda pos, k: asked.append((id(pos), k)) or real(pos, k))
    seen = 0
    for fg in (0, 3):
        res = _render("cornell", 3000, {"final_gather": fg})
        for est in ({}, {"radius_fraction": 0.02}, {"caustic_radius": 3.0, "radius_photons": 16},
                    {"radius": 7.0, "final_gather_photons": 24}, {"caustic_radius_photons": 5}):
            f = Frame.create(res.scene, res.accel, config_from_dict(
                {"scene": "cornell", "mode": "pmap", "estimate": {"final_gather": fg, **est}}))
            photons = fresh(res.photons.photons)
            requests = density_requests(f, photons)
            assert len({(id(m), k) for m, k in requests}) == len(requests)  # (each once)
            asked.clear()
            want = radii(f, fresh(photons))  # what the frame asks for, from maps with no radii kept
            assert sorted(asked) == sorted((id(m.position), k) for m, k in requests), est
            for m, k in requests:
                m.density_radius(k)
            asked.clear()
            assert radii(f, photons) == want and asked == []  # every radius was made: only looked up
            seen += bool(requests)
    assert seen >= 6


def test_a_warm_photon_trace_makes_what_the_batches_read(monkeypatch):
    """``trace_photon_map(warm=True)`` (a render whose batches run at once) makes, with the
    maps' trees, each gathered map's leaf order and every density radius the frame asks for: the
    same maps, radii and leaf order as a cold trace makes later, and the frame's radii are
    then only looked up."""
    import tlm.kernels.photons as photon_module
    from tlm.kernels import threads
    from tlm.render.pmap import density_requests, gathered_maps, trace_photon_map

    res = _render("cornell", 3000, {"final_gather": 3})
    asked = []
    real = photon_module.density_radius
    monkeypatch.setattr(photon_module, "density_radius", lambda pos, k: asked.append(k) or real(pos, k))
    seen = 0
    for est in ({"final_gather": 3}, {"final_gather": 0}, {"final_gather": 3, "radius_fraction": 0.02},
                {"final_gather": 0, "caustic_radius_photons": 5}):
        f = Frame.create(res.scene, res.accel, config_from_dict(
            {"scene": "cornell", "mode": "pmap", "photons": {"count": 3000}, "estimate": est}))
        cold = trace_photon_map(f).photons
        with threads.using(2):
            warm = trace_photon_map(f, warm=True).photons
        requests = density_requests(f, warm)
        assert requests and len(requests) == len(density_requests(f, cold))
        names = ("caustic_map", "indirect_map", "global_map")
        gathered = list(gathered_maps(f, warm).values())
        for name in names:
            a, b = getattr(warm, name), getattr(cold, name)
            assert (a is None) == (b is None) and (a is None or a.position.tobytes() == b.position.tobytes())
            if a is not None:
                # (only the maps the frame gathers: with final gathering not the indirect map)
                assert ("leaf_order" in a._memo) == any(a is m for m in gathered) and "leaf_order" not in b._memo
                for row in ("pos", "inc", "pow", "first", "size"):
                    assert getattr(a.prepared(), row).tobytes() == getattr(b.prepared(), row).tobytes(), row
        for m, k in requests:
            assert k in m._memo  # made with the maps
        asked.clear()
        from_warm = radii(f, warm)
        assert asked == []  # every radius made with the maps: only looked up
        assert from_warm == radii(f, cold) and len(asked) == len(requests)  # (the cold maps make theirs now)
        seen += len(asked)
    assert seen >= 4
