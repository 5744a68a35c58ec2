"""PMap mode end to end, converged references (cached) and the error-against-cost runs."""

from __future__ import annotations

import csv
import importlib.util
import json

import numpy as np
import pytest

from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments.run import programs_for, render, simulate_run

from .scenes import sphere_scene


def furnace_config(tmp_path, **extra) -> str:
    sphere_scene(tmp_path)
    body = {
        "scene": "furnace.yaml",
        "mode": "pmap",
        "photons": {"count": 6000},
        "estimate": {"radius_fraction": 0.06, "final_gather": 0},  # the indirect map at the eye hits
        "reference": {"photons": 6000, "k_nearest": 80, "tolerance": 0.05, "max_rounds": 16},
        **extra,
    }
    path = tmp_path / "cfg.yaml"
    path.write_text(json.dumps(body))
    return str(path)


@pytest.mark.slow
def test_pmap_run_without_then_with_a_reference(tmp_path, cache, capsys):
    cfg = furnace_config(tmp_path)
    out = tmp_path / "run"
    assert main(["run", cfg, "--out", str(out), "--no-reference"]) == 0
    results = json.loads((out / "results.json").read_text())
    assert results["plan"]["run"] == ["rcast", "pmap"]
    assert results["photons"]["emitted"] == 6000 and results["photons"]["stored"] > 0
    assert results["photons"]["filter"] == "mvoxel"
    assert results["error"]["available"] is False and "tlm reference" in results["error"]["hint"]
    assert (out / "images" / "pmap.png").is_file() and (out / "radiance" / "pmap.npy").is_file()
    work = np.load(out / "aov" / "work.npz")
    assert work["pmap.gathers"].sum() == 4 * 24 * 24  # every eye ray (4 per pixel) hits the diffuse sphere

    assert main(["reference", cfg]) == 0
    printed = capsys.readouterr().out
    assert "converged after" in printed
    (folder,) = (cache / "references").iterdir()
    meta = json.loads((folder / "meta.json").read_text())
    assert meta["converged"] and meta["rounds"] >= 4 and meta["relative_standard_error"] < 0.05
    reference = np.load(folder / "reference.npy")
    assert reference.shape == (24, 24, 3)
    assert abs(reference.mean() - 0.5) < 0.03  # the furnace's indirect half

    assert main(["reference", cfg]) == 0
    assert "cached" in capsys.readouterr().out
    # the stopping rule is not part of the key: a stricter tolerance recomputes the same
    # reference, and a run with other round limits still finds it
    assert main(["reference", cfg, "--set", "reference.tolerance=0.03"]) == 1  # (max_rounds before 0.03: exit 1)
    printed = capsys.readouterr().out
    assert "does not meet tolerance" in printed and "NOT converged (max_rounds reached)" in printed
    assert [p.name for p in (cache / "references").iterdir()] == [folder.name]

    assert main(["run", cfg, "--out", str(out)]) == 0
    error = json.loads((out / "results.json").read_text())["error"]
    assert error["available"] and error["reference"] == folder.name
    assert main(["run", cfg, "--out", str(out), "--set", "reference.max_rounds=40"]) == 0
    assert json.loads((out / "results.json").read_text())["error"]["reference"] == folder.name
    assert 0 < error["rmse"] < 0.2 and 0 < error["rel_mse"] < 0.2
    # the error falls with more photons
    assert main(["run", cfg, "--out", str(out), "--set", "photons.count=48000"]) == 0
    more = json.loads((out / "results.json").read_text())["error"]
    assert more["rmse"] < error["rmse"]


@pytest.mark.slow
def test_error_vs_cost_rows(tmp_path, cache, capsys):
    sphere_scene(tmp_path)
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({
        "base": {"scene": "furnace.yaml", "reference": {"photons": 6000, "k_nearest": 40, "tolerance": 0.05},
                 # fixed radii, so that more photons mean a smaller error (the density rule keeps ~k per gather)
                 "estimate": {"radius_fraction": 0.04, "caustic_radius_fraction": 0.01, "final_gather": 0}},
        "points": [
            {"estimate.filter": ["disk", "mvoxel"], "photons.count": [3000, 12000]},
            {"estimate.filter": ["kvoxel"], "photons.count": [12000], "estimate.k": [2, 8]},
            {"estimate.filter": ["knn"], "photons.count": [12000], "estimate.k_nearest": [20]},
            {"estimate.filter": ["mvoxel"], "photons.count": [3000], "arch.pipelines": [2]},
            {"estimate.filter": ["mvoxel"], "photons.count": [3000], "estimate.final_gather": [4]},
        ],
    }))
    out = tmp_path / "evc"
    truth = importlib.util.find_spec("mitsuba") is not None  # the oracle extra (in the test extras)
    assert main(["error-vs-cost", str(exp), "--out", str(out), "--truth-spp", "256"]) == 0
    with open(out / "rows.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 9
    assert [r["filter"] for r in rows] == ["disk", "disk", "mvoxel", "mvoxel", "kvoxel", "kvoxel", "knn", "mvoxel",
                                           "mvoxel"]
    assert [r["final_gather"] for r in rows] == ["0"] * 8 + ["4"]
    assert rows[4]["factors"] == "estimate.filter=kvoxel; photons.count=12000; estimate.k=2"  # (the point's own)
    assert rows[7]["factors"] == "estimate.filter=mvoxel; photons.count=3000; arch.pipelines=2"
    assert {"throughput_cycles", "latency_cycles", "frame_seconds", "fps", "simulate_seconds"} <= set(rows[0])
    jsonl = [json.loads(line) for line in (out / "rows.jsonl").read_text().splitlines()]
    assert len(jsonl) == 9
    fg = jsonl.pop()
    for row in jsonl:
        assert np.isfinite(row["rmse"]) and row["gathers"] == 4 * 24 * 24 and row["gather_seconds"] >= 0
        assert row["throughput_cycles"] > 0 and row["latency_cycles"] > 0 and row["simulate_seconds"] > 0
        assert row["frame_seconds"] == row["throughput_cycles"] / 600e6
        assert row["fps"] == pytest.approx(600e6 / row["throughput_cycles"], rel=1e-12)
    mv = [r for r in jsonl if r["filter"] == "mvoxel"]
    # final gathering: 4 rays from each of the 4 x 24 x 24 eye hits, each a lookup where it lands
    # (a closed sphere: every ray lands), and a longer frame than the same map gathered at the eye
    assert fg["gathers"] == 4 * 4 * 24 * 24 and fg["final_gather"] == 4
    assert fg["throughput_cycles"] > mv[0]["throughput_cycles"] and np.isfinite(fg["rmse"])
    assert mv[1]["photons_tested"] > mv[0]["photons_tested"]  # more photons, more work
    assert mv[1]["throughput_cycles"] > mv[0]["throughput_cycles"]  # ... and a longer frame
    kv = [r for r in jsonl if r["filter"] == "kvoxel"]
    assert kv[1]["leaves_visited"] >= kv[0]["leaves_visited"]
    assert json.loads((out / "reference.json").read_text())["converged"]
    # the composites against Mitsuba's path tracer: the furnace's radiance is 1 everywhere
    meta = json.loads((out / "truth.json").read_text())
    assert meta["available"] is truth
    if truth:
        assert meta["spp"] == 256 and meta["integrator"] == "path"
        for row in jsonl:
            assert 0 < row["truth_rel_mse"] < 0.05 and 0 < row["truth_flip"] < 0.2
        # more photons: closer to the truth (the indirect half is the photon map's)
        assert mv[1]["truth_rel_mse"] < mv[0]["truth_rel_mse"]
    else:
        assert "oracle" in meta["reason"] and all(r["truth_rel_mse"] is None for r in jsonl)
    # the simulated frame is the one 'tlm run' simulates: the same point rendered and simulated
    # on its own gives the same cycles, under each point's own arch settings
    two = mv[2]
    assert two["rmse"] == mv[0]["rmse"] and two["throughput_cycles"] != mv[0]["throughput_cycles"]
    for row, pipes, gather in ((mv[0], 1, 0), (two, 2, 0), (fg, 1, 4)):
        cfg = config_from_dict({"scene": "furnace.yaml", "mode": "pmap",
                                "estimate": {"filter": "mvoxel", "radius_fraction": 0.04,
                                             "caustic_radius_fraction": 0.01, "final_gather": gather},
                                "photons": {"count": 3000}, "arch": {"pipelines": pipes}})
        tm = simulate_run(render(cfg, tmp_path), programs_for(cfg, tmp_path))
        assert (tm.cycles["throughput"], tm.cycles["latency"]) == (row["throughput_cycles"], row["latency_cycles"])


@pytest.mark.parametrize("body,expect", [
    ({"base": {}, "points": []}, "points"),
    ({"base": {}, "points": [{"estimate.filter": ["mvox"]}]}, "did you mean 'mvoxel'"),
    ({"base": {}, "points": [{"estimate.radius": [-1.0]}]}, "estimate.radius"),
    ({"base": {}, "grid": {}}, "grid"),
    ({"base": {"mdoe": "pmap"}, "points": [{"estimate.k": [1]}]}, "mdoe"),
    # what every point takes from the base: refused, not silently the base's (nor an internal error)
    ({"base": {}, "points": [{"estimate.k": [1]}, {"bsp.levels": [0, 8]}]}, "points[1].bsp.levels: a point cannot"),
    ({"base": {}, "points": [{"scene": ["ring"]}]}, "points[0].scene: a point cannot vary scene"),
    ({"base": {}, "points": [{"mode": ["rcast"]}]}, "every point is a photon-map frame"),
    ({"base": {}, "points": [{"render.spp": [1, 4]}]}, "the base's eye rays"),
    ({"base": {}, "points": [{"resolution": [[8, 8]]}]}, "points[0].resolution"),
    # ... also given as a whole section (the point's resolved settings against the base's)
    ({"base": {}, "points": [{"render": [{"spp": 1}]}]}, "a point cannot vary render.spp"),
    ({"base": {}, "points": [{"bsp": [{"levels": 3}]}]}, "a point cannot vary bsp"),
])
def test_bad_experiment_files(tmp_path, capsys, body, expect):
    exp = tmp_path / "bad.yaml"
    exp.write_text(json.dumps(body))
    # (no ground truth: a check that let a point through would not then render one for minutes)
    assert main(["error-vs-cost", str(exp), "--out", str(tmp_path / "out"), "--truth-spp", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tlm: error:") and "bad.yaml" in err[0] and expect in err[0]
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
@pytest.mark.parametrize("filt", ["disk", "mvoxel", "kvoxel", "knn"])
def test_pmap_pass_is_packet_invariant_and_repeats(filt):
    from tlm.config import config_from_dict
    from tlm.kernels.memory import Streams
    from tlm.kernels.photons import trace_photons
    from tlm.kernels.traverse import build_accel
    from tlm.kernels.work import MISS_KEYS
    from tlm.render.frame import Frame, cast
    from tlm.render.pmap import pmap_pass
    from tlm.scenes.loader import load_scene

    scene = load_scene("cornell", resolution=[40, 40])
    accel = build_accel(scene.triangles)
    cfg = config_from_dict({"mode": "pmap", "seed": 3, "estimate": {"filter": filt}})
    frame = Frame.create(scene, accel, cfg)
    photons = trace_photons(scene, accel, 20000, seed=3).photons
    again = trace_photons(scene, accel, 20000, seed=3).photons
    pixels = np.arange(1600)
    full, work = pmap_pass(frame, cast(frame, pixels), photons)
    rng = np.random.default_rng(0)
    for size in (1, 7, 500):  # any subset, any order: all but the misses
        sub = rng.choice(1600, size, replace=False)
        part, wpart = pmap_pass(frame, cast(frame, sub), again)
        np.testing.assert_array_equal(part, full[sub])
        for k in work:
            if k not in MISS_KEYS:
                np.testing.assert_array_equal(wpart[k], work[k][sub])
    for size in (13, 500):  # packets in pixel order with the pair's state carried: everything
        streams = Streams()
        parts = [pmap_pass(frame, cast(frame, pixels[s0 : s0 + size]), again, streams=streams)
                 for s0 in range(0, 1600, size)]
        np.testing.assert_array_equal(np.concatenate([p[0] for p in parts]), full)
        for k in work:
            np.testing.assert_array_equal(np.concatenate([p[1][k] for p in parts]), work[k], err_msg=k)
    if filt == "knn":  # the cKDTree reference reads no photon leaves of the hardware's tree
        assert work["gather_misses"].sum() == 0
    else:
        assert work["gather_misses"].sum() > 0
        cold = sum(pmap_pass(frame, cast(frame, pixels[s0 : s0 + 13]), again)[1]["gather_misses"].sum()
                   for s0 in range(0, 1600, 13))
        assert cold > work["gather_misses"].sum()  # a cold pair per packet misses more
    assert np.isfinite(full).all() and full.max() > 0


def test_error_vs_cost_refuses_a_point_off_the_reference_before_any_work(tmp_path, cache, capsys, monkeypatch):
    """A point that changes what the reference depends on is refused before the reference or
    any point is computed (it was refused when its turn came, hours into a study)."""
    import tlm.experiments.error_cost as ec

    monkeypatch.setattr(ec, "compute_reference", lambda *a, **k: pytest.fail("computed before the check"))
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({"base": {"resolution": [8, 8], "photons": {"count": 500}},
                               "points": [{"estimate.filter": ["disk"]}, {"photons.max_bounces": [2]}]}))
    assert main(["error-vs-cost", str(exp), "--out", str(tmp_path / "out"), "--truth-spp", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert "points: {'photons.max_bounces': 2}: the point changes what the reference depends on" in err
    assert main(["error-vs-cost", str(exp), "--out", str(tmp_path / "out"), "--truth-spp", "-5"]) == 2
    assert "--truth-spp: -5 is not a count" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
