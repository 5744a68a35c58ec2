"""Every photon-map run measures its error: the reference is computed (once) when missing,
keyed only by what changes the converged image, and the run prints, records and draws it."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image
from scipy.spatial import cKDTree

from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments.reference import (
    cycle_length,
    difference_image,
    eye_rays,
    knn_density,
    reference_key,
)
from tlm.experiments.reference_cache import ReferenceSettings
from tlm.kernels.camera import primary_rays
from tlm.scenes.loader import load_scene

from .scenes import sphere_scene


def furnace(tmp_path, **extra) -> str:
    sphere_scene(tmp_path)
    body = {"scene": "furnace.yaml", "mode": "pmap", "photons": {"count": 6000},
            "estimate": {"radius_fraction": 0.06, "final_gather": 0},
            "reference": {"photons": 6000, "k_nearest": 80, "tolerance": 0.05, "max_rounds": 16},
            "arch": {"frames": 2, "trace": False}, **extra}
    path = tmp_path / "cfg.yaml"
    path.write_text(json.dumps(body))
    return str(path)


def run(cfg: str, out, *args) -> dict:
    assert main(["run", cfg, "--out", str(out), "--no-report", "--no-progress", *args]) == 0
    return json.loads((out / "results.json").read_text())


def references(cache) -> list[str]:
    folder = cache / "references"
    return sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []


@pytest.mark.slow
def test_a_pmap_run_computes_its_reference_once_and_every_run_reuses_it(tmp_path, cache, capsys):
    cfg = furnace(tmp_path)
    first = run(cfg, tmp_path / "a")
    printed = capsys.readouterr()
    error = first["error"]
    assert error["available"] and error["reference_converged"] and error["reference_seconds"] > 0
    assert "computing the photon-map reference" in printed.err and "cached in" in printed.err
    line = [x for x in printed.out.splitlines() if "pmap error" in x]
    assert len(line) == 1 and f"reference {error['reference']}" in line[0] and "relative MSE" in line[0]
    assert "RMSE" in line[0] and "computed now in" in line[0] and "images/pmap_error.png" in line[0]
    assert 0 < error["rel_mse"] < 0.2 and error["difference_image"] == "images/pmap_error.png"
    png = Image.open(tmp_path / "a" / "images" / "pmap_error.png")
    assert png.size == (24, 24) and png.mode == "RGB" and error["difference_scale"] > 0
    # (numba compiling or loading a kernel while it ran is the run's one_off, not the reference stage's)
    assert first["host_seconds"]["reference"] + first["host_seconds"]["one_off"] >= error["reference_seconds"]
    assert references(cache) == [error["reference"]]
    # what does not change the converged image finds the same reference: nothing computed
    for args in (["--set", "render.spp=1"], ["--set", "photons.count=3000"], ["--set", "estimate.filter=disk"],
                 ["--seed", "7"], ["--set", "reference.spp=1"], ["--set", "reference.tolerance=0.2"]):
        again = run(cfg, tmp_path / "b", *args)["error"]
        printed = capsys.readouterr()
        assert again["available"] and again["reference"] == error["reference"], args
        assert again["reference_seconds"] is None and "computing" not in printed.err, args
        assert "computed now" not in printed.out and "pmap error against reference" in printed.out
    assert references(cache) == [error["reference"]]
    # a shorter photon path changes it: computed again, beside the first
    other = run(cfg, tmp_path / "c", "--set", "photons.max_bounces=2")["error"]
    assert other["available"] and other["reference"] != error["reference"] and other["reference_seconds"] > 0
    assert references(cache) == sorted([error["reference"], other["reference"]])


@pytest.mark.slow
@pytest.mark.parametrize("how", [["--no-reference"], ["--set", "reference.auto=false"]])
def test_opting_out_computes_nothing_and_says_so(tmp_path, cache, capsys, how):
    res = run(furnace(tmp_path), tmp_path / "a", *how)
    out = capsys.readouterr().out
    assert res["error"]["available"] is False and "tlm reference" in res["error"]["hint"]
    reason = "--no-reference" if how == ["--no-reference"] else "reference.auto: false"
    assert f"pmap error: skipped ({reason})" in out
    assert references(cache) == [] and not (tmp_path / "a" / "images" / "pmap_error.png").exists()
    assert "reference" not in res["host_seconds"]


def test_a_run_without_a_photon_map_looks_up_no_reference(tmp_path, cache, capsys):
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(json.dumps({"scene": "cornell", "mode": "refract", "resolution": [16, 16],
                               "arch": {"frames": 1, "trace": False}, "render": {"light_samples": 1}}))
    res = run(str(cfg), tmp_path / "a")
    assert res["error"] is None and "pmap error" not in capsys.readouterr().out
    assert not (cache / "references").exists() and "reference" not in res["host_seconds"]


def test_the_key_follows_what_changes_the_converged_image():
    scene = load_scene("cornell", resolution=[16, 16])  # mirror and glass: the walks gather too
    base = {"mode": "pmap"}

    def key(body=None, sc=scene):
        cfg = config_from_dict({**base, **(body or {})})
        return reference_key(sc, cfg, ReferenceSettings.from_config(sc, cfg))

    k0 = key()
    same = [{"render": {"spp": 16}}, {"photons": {"count": 5000, "russian_roulette": False, "caustic_count": 9,
                                                  "aim": "box", "caustic_fraction": 0.2, "leaf_photons": 4}},
            {"estimate": {"filter": "knn", "radius": 3.0, "final_gather": 0, "cone_k": 2.0}}, {"seed": 9},
            {"reference": {"spp": 16, "tolerance": 0.1, "max_rounds": 8, "auto": False}},
            {"render": {"light_samples": 9, "batch_rays": 999, "exposure": 2.0}}, {"arch": {"pipelines": 2}}]
    for body in same:
        assert key(body) == k0, body
    differ = [{"photons": {"max_bounces": 3}}, {"render": {"refract_depth": 2}}, {"render": {"reflect_depth": 1}},
              {"render": {"fresnel": False}}, {"render": {"min_weight": 0.1}},
              {"reference": {"photons": 1000}}, {"reference": {"k_nearest": 10}}]
    keys = {key(body) for body in differ}
    assert k0 not in keys and len(keys) == len(differ)
    light = scene.lights[0]
    dimmer = replace(scene, lights=(replace(light, power=tuple(0.5 * p for p in light.power)), *scene.lights[1:]))
    assert key(sc=dimmer) != k0
    assert key(sc=load_scene("cornell", resolution=[16, 8])) != k0
    # without mirrors or glass, the walks' settings gather nothing: one reference for all
    plain = replace(scene, materials=tuple(replace(m, kind="lambertian", albedo=(0.5, 0.5, 0.5))
                                           for m in scene.materials))
    assert key({"render": {"refract_depth": 1, "fresnel": False}}, plain) == key(sc=plain)


def test_a_cycle_of_eye_rays_covers_each_stratum_of_a_pixel_once():
    scene = load_scene("cornell", resolution=[8, 4])

    class F:  # what eye_rays reads of a frame
        pass

    frame = F()
    frame.scene = scene
    pixels = np.arange(32)
    _, every = primary_rays(scene.camera, pixels, 4, 123)
    every = every.reshape(32, 4, 3)
    seen = np.zeros((32, 4), dtype=int)
    for turn in range(4):
        _, d = eye_rays(frame, pixels, 4, turn, 123, 55)
        match = np.all(np.isclose(every, d[:, None, :], rtol=0, atol=1e-15), axis=2)
        assert (match.sum(axis=1) == 1).all()
        seen += match
    assert (seen == 1).all()  # each of the 2 x 2 strata once per pixel
    _, one = eye_rays(frame, pixels, 1, 0, 5, 0)
    _, centre = primary_rays(scene.camera, pixels, 1)
    assert not np.allclose(one, centre)  # one ray: jittered in the pixel, not its centre
    assert cycle_length(ReferenceSettings(photons=1, spp=16, max_rounds=10)) == 5
    assert cycle_length(ReferenceSettings(photons=1, spp=4, max_rounds=3)) == 1


def test_the_grid_estimate_is_the_kd_tree_estimate():
    from tlm.experiments._reference_jit import PhotonGrid

    rng = np.random.default_rng(1)
    n = 3000
    pos = np.concatenate([np.c_[rng.random(n), rng.random(n), np.zeros(n)],
                          np.c_[rng.random(n), np.zeros(n), rng.random(n)], 0.5 + 0.01 * rng.standard_normal((200, 3))])
    power = rng.random((pos.shape[0], 3))
    incoming = rng.standard_normal((pos.shape[0], 3))
    incoming /= np.linalg.norm(incoming, axis=1, keepdims=True)
    pts = rng.random((500, 3)) * 1.6 - 0.3  # inside and outside the photons' box
    nrm = rng.standard_normal((500, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    for k in (1, 30, 400):
        want = knn_density(cKDTree(pos), power, incoming, pts, nrm, k)
        for cell in (0.02, 0.3, 5.0):
            np.testing.assert_allclose(PhotonGrid(pos, power, incoming, cell).density(pts, nrm, k, 1.1), want,
                                       rtol=1e-10, atol=1e-12)


def test_the_difference_image_is_signed():
    ref = np.ones((2, 2, 3))
    ours = np.array([[[2.0] * 3, [1.0] * 3], [[0.0] * 3, [1.5] * 3]])
    rgb, scale = difference_image(ours, ref, scale=1.0)
    assert scale == 1.0
    assert rgb[0, 0].tolist() == [0xFE, 0xE8, 0x38] and rgb[1, 0].tolist() == [0x00, 0x22, 0x4E]
    assert rgb[0, 1].tolist() == [0x7D, 0x7D, 0x7D] and rgb[1, 1, 0] > rgb[1, 1, 2]  # half way to yellow
    assert difference_image(ref, ref)[1] == 1.0  # no difference: a unit scale, all neutral grey


@pytest.mark.slow
def test_the_report_shows_the_error(tmp_path, cache):
    from tlm.report import build_report

    res = run(furnace(tmp_path), tmp_path / "a")
    page = build_report([tmp_path / "a"]).read_text(encoding="utf-8")
    assert "PMap frame against its converged reference" in page
    assert f"relative MSE {res['error']['rel_mse']:.3g}" in page
    assert list((tmp_path / "a" / "report").glob("pmap_error_*.png"))
