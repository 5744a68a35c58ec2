"""The thesis reproduction, the calibration, the packet-size study and the functional cache."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import yaml

import tlm.experiments.run as run_mod
from tlm.arch.costs import DEFAULT_PATH, load_programs
from tlm.arch.model import simulate
from tlm.cli import main
from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.experiments.frames import cached_functional
from tlm.experiments.granularity import run_granularity
from tlm.experiments.run import render
from tlm.experiments.thesis import (
    COLUMNS,
    calibrate,
    fit_scale,
    fit_scale_and_records,
    load_study,
    restrict,
    run_thesis,
    summarize,
    write_calibrated,
)

TINY = {"resolution": [24, 16], "render": {"light_samples": 1}, "photons": {"count": 800},
        "arch": {"frames": 2, "packet_size": 32}}


def _study(tmp_path, **extra) -> str:
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump({"base": TINY, **extra}))
    return path


@pytest.mark.slow
def test_restrict_equals_rendering_the_smaller_mode():
    big = render(config_from_dict({**TINY, "scene": "cornell", "mode": "pmap"}))
    small_cfg = config_from_dict({**TINY, "scene": "cornell", "mode": "reflect"})
    direct = render(small_cfg)
    cut = restrict(big, small_cfg)
    assert cut.plan.run_names == direct.plan.run_names == ["rcast", "reflect"]
    a, b = cut.functional(), direct.functional()
    for p in a.passes:
        for k in a.work[p]:
            np.testing.assert_array_equal(a.work[p][k], b.work[p][k], err_msg=f"{p}.{k}")
    for p in cut.radiance:
        np.testing.assert_array_equal(cut.radiance[p], direct.radiance[p])
    assert cut.photons is None
    # its host seconds: the shared stages and its own passes, not those it leaves out
    assert set(cut.timer.seconds) == set(direct.timer.seconds)  # (the warm-up's: prepare, one_off where compiled)
    assert set(direct.timer.seconds) - {"prepare", "one_off"} == {"load_scene", "build_bsp", "cast", "pass_rcast",
                                                                   "pass_reflect"}


def test_thesis_study_writes_the_comparison(tmp_path):
    path = _study(tmp_path, scenes=["thesis/ring"], modes=["rcast", "pmap"])
    out = tmp_path / "out"
    done = run_thesis(path, out)
    with open(out / "thesis_comparison.csv") as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == COLUMNS
    assert len(rows) == 2 * 6
    marked = {(r["mode"], r["metric"]) for r in rows if r["calibrated"] == "True"}
    assert marked == {("rcast", "TVert"), ("rcast", "TTrav"), ("rcast", "TFrag")}
    for r in rows:
        t, o = float(r["thesis"]), float(r["ours"])
        assert float(r["rel_error"]) == pytest.approx((o - t) / t, abs=1e-5)
    for mode in ("rcast", "pmap"):
        res = json.loads((out / "ring" / mode / "results.json").read_text())
        assert res["mode"] == mode
        assert (out / "ring" / mode / "trace.json").exists()
        assert float(next(r["ours"] for r in rows if r["mode"] == mode and r["metric"] == "TThru")) == \
            pytest.approx(res["cycles"]["throughput"] / 1e6, rel=1e-6)
    summary = json.loads((out / "thesis_summary.json").read_text())
    assert summary["held_out_cells"] == 12 - 3
    assert summary == {**done["summary"], "host_seconds": summary["host_seconds"]}
    assert set(summary["per_item"]) == {"ring/rcast", "ring/pmap"}
    for mode in ("rcast", "pmap"):
        res = json.loads((out / "ring" / mode / "results.json").read_text())
        it = summary["per_item"][f"ring/{mode}"]
        eye = res["work"]["rcast"]
        passes = res["work"].values()
        photon_rays = res["photons"]["work"]["rays"] if mode == "pmap" else 0
        rays = sum(w.get(k, 0) for w in passes for k in ("primary_rays", "secondary_rays", "shadow_rays")) + photon_rays
        assert eye["primary_rays"] == res["primary"]["rays"] and res["primary"]["pixels"] == it["pixels"] == 24 * 16
        assert it["rays"] == rays > it["pixels"]
        assert it["ours"]["trav_cycles_per_ray"] == pytest.approx(res["cycles"]["traversal"] / rays, rel=1e-3)
        assert it["ours"]["frag_cycles_per_pixel"] == pytest.approx(res["cycles"]["fragment"] / (24 * 16), rel=1e-3)
        tests = sum(w.get("tri_tests", 0) + w.get("shadow_tri_tests", 0) for w in passes) + \
            (res["photons"]["work"]["tri_tests"] if mode == "pmap" else 0)
        assert it["tri_tests"] == tests
        assert it["ours"]["tests_per_ray"] == pytest.approx(tests / rays, rel=1e-3)  # counted, not implied
        # the thesis's time over our count: Tisct = 2 cycles per ray + 3 per triangle test
        col = ("rcast", "pmap").index(mode) * 3
        tisct = (10.8, 15.4, 26.1, 27.8)[col] * 1e6
        assert it["thesis"]["tests_per_ray"] == pytest.approx((tisct - 2 * rays) / 3 / rays, rel=1e-3)
        assert it["thesis"]["vert_cycles_per_triangle"] == pytest.approx((0.378, 0.378, 0.378, 1.34)[col] * 1e6 / 646,
                                                                         rel=1e-3)


def test_summary_counts_slowest_pm_matches():
    rows = []
    for metric, ours in (("TVert", 1.0), ("TTrav", 50.0), ("Tisct", 10.0), ("TFrag", 4.0), ("TThru", 51.0),
                         ("FPS", 11.0)):
        t = {"TVert": .378, "TTrav": 24.4, "Tisct": 10.8, "TFrag": 4.12, "TThru": 24.8, "FPS": 24.2}[metric]
        rows.append({"scene": "ring", "mode": "rcast", "metric": metric, "thesis": t, "ours": ours,
                     "rel_error": (ours - t) / t, "calibrated": metric in ("TVert", "TTrav", "TFrag")})
    s = summarize(rows)
    assert s["slowest_pm"]["ring/rcast"] == {"thesis": "TTrav", "ours": "TTrav", "match": True}
    assert s["held_out_cells"] == 3
    held = sorted(abs(r["rel_error"]) for r in rows if not r["calibrated"])
    assert s["median_abs_rel_error_held_out"] == pytest.approx(held[1])


def test_fit_scale_is_the_weighted_least_squares_minimum():
    rng = np.random.default_rng(1)
    n, m, y = rng.uniform(1, 10, 5), rng.uniform(0, 2, 5), rng.uniform(5, 20, 5)
    s = fit_scale(n, m, y)

    def cost(x):
        return float(np.sum(((x * n + m - y) / y) ** 2))

    assert cost(s) < cost(s * 1.01) and cost(s) < cost(s * 0.99)
    assert fit_scale(n, m + 100 * y, y) == 0.0  # never a negative cost


def test_calibrate_fits_and_rewrites_the_table(tmp_path):
    path = _study(tmp_path, scenes=["thesis/ring", "cornell"], modes=["rcast"])
    programs, report = calibrate(path, iterations=3)
    assert set(report["cells"]) == {"ring", "cornell"}
    assert programs.scale["vertex"] > 0 and programs.record_cycles["vertex"] == 0  # a scale alone
    assert report["fitted"] == ["vertex.scale", "traversal.scale", "fragment.scale", "traversal.record_cycles",
                                "fragment.record_cycles"]
    for pm, metric in (("traversal", "TTrav"), ("fragment", "TFrag")):
        assert programs.scale[pm] >= 0 and programs.record_cycles[pm] >= 0
        assert programs.scale[pm] + programs.record_cycles[pm] > 0
        assert all(cells[metric]["ours"] > 0 for cells in report["cells"].values())
    target = tmp_path / "programs.yaml"
    write_calibrated(programs, report, target, "tlm calibrate study.yaml")
    text = target.read_text()
    assert text.startswith(DEFAULT_PATH.read_text().splitlines()[0])  # the documentation is kept
    again = load_programs(target)
    for p in ("vertex", "traversal", "fragment"):
        assert again.scale[p] == pytest.approx(programs.scale[p], rel=1e-5, abs=1e-12)
        assert again.record_cycles[p] == pytest.approx(programs.record_cycles[p], rel=1e-5, abs=1e-12)
    assert again.calibration["command"] == "tlm calibrate study.yaml"
    assert again.calibration["fitted"] == report["fitted"]
    assert again.jobs == load_programs().jobs  # only the free parameters change
    assert "# per ray traversed" in text  # the comments on the rewritten lines stay


def test_calibrate_keeps_the_record_cycles_it_does_not_fit_and_writes_a_missing_line(tmp_path):
    """A table whose Vertex PM has records of its own: calibrate fits vertex.scale around
    them and keeps them; a table without a record_cycles line gets one below the scale."""
    raw = yaml.safe_load(DEFAULT_PATH.read_text())
    raw["vertex"]["record_cycles"] = 300.0
    raw["vertex"]["geometry_bsp"]["records"] = ["elements"]
    del raw["fragment"]["record_cycles"]
    table = tmp_path / "table.yaml"
    table.write_text("# a user's table\ncalibration: {}\n" + yaml.safe_dump({k: v for k, v in raw.items()
                                                                              if k != "calibration"}))
    path = _study(tmp_path, scenes=["thesis/ring", "cornell"], modes=["rcast"])
    spec = yaml.safe_load(path.read_text())
    spec["base"]["arch"] = {**spec["base"]["arch"], "programs": str(table)}
    path.write_text(yaml.safe_dump(spec))
    programs, report = calibrate(path, iterations=2)
    assert programs.record_cycles["vertex"] == 300.0
    assert programs.scale["vertex"] >= 0
    target = tmp_path / "out.yaml"
    write_calibrated(programs, report, target, "tlm calibrate study.yaml")
    again = load_programs(target)
    assert again.record_cycles == pytest.approx(programs.record_cycles, rel=1e-5, abs=1e-9)
    assert again.scale == pytest.approx(programs.scale, rel=1e-5, abs=1e-9)
    assert again.jobs[("vertex", "geometry_bsp")].records == ("elements",)


def test_fit_of_scale_and_record_cycles_recovers_them():
    rng = np.random.default_rng(2)
    n, k, m = rng.uniform(1, 10, 4), rng.uniform(1, 10, 4), rng.uniform(0, 1, 4)
    y = 0.7 * n + 3.5 * k + m
    s, c = fit_scale_and_records(n, k, m, y)
    assert s == pytest.approx(0.7) and c == pytest.approx(3.5)
    # never negative: a table that needs less than its records cost gets no per-record cycles
    s, c = fit_scale_and_records(n, k, m + 100 * y, y)
    assert s == 0.0 and c == 0.0


def test_granularity_rows_and_the_functional_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "g.yaml"
    path.write_text(yaml.safe_dump({"base": {**TINY, "scene": "cornell", "mode": "rcast"},
                                    "packet_sizes": [64, 1, 8, 100000]}))
    rows = run_granularity(path, tmp_path / "g1")
    assert [r["packet_size"] for r in rows] == [1, 8, 64, 100000]
    assert rows[0]["max_abs_rel_error"] == 0.0 and rows[0]["reference"] == 1
    assert rows[0]["simpy_events"] > rows[-1]["simpy_events"]
    # the second study reuses the cached work: rendering would fail now
    monkeypatch.setattr(run_mod, "render", lambda *a, **k: pytest.fail("rendered again"))
    again = run_granularity(path, tmp_path / "g2")
    assert [r["throughput"] for r in again] == [r["throughput"] for r in rows]


def test_granularity_takes_a_run_config_file_as_its_base(tmp_path, monkeypatch):
    """``base: run.yaml`` (relative to the study file), as a sweep's base may be: the same
    study as the inline mapping, the base's own paths relative to the base file."""
    from tlm.experiments.granularity import load_granularity

    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    (tmp_path / "configs" / "scenes").mkdir(parents=True)
    (tmp_path / "configs" / "scenes" / "box.yaml").write_text("extends: cornell\n")
    base = {**TINY, "scene": "scenes/box.yaml", "mode": "rcast", "arch": {"frames": 2}}
    (tmp_path / "configs" / "run.yaml").write_text(yaml.safe_dump(base))
    (tmp_path / "g.yaml").write_text(yaml.safe_dump({"base": "configs/run.yaml", "packet_sizes": [64, 1]}))
    (tmp_path / "configs" / "inline.yaml").write_text(yaml.safe_dump({"base": base, "packet_sizes": [1, 64]}))
    by_file, inline = load_granularity(tmp_path / "g.yaml"), load_granularity(tmp_path / "configs" / "inline.yaml")
    assert by_file == inline and by_file[1] == [1, 64] and by_file[2] == tmp_path / "configs"
    rows = run_granularity(tmp_path / "g.yaml", tmp_path / "out")
    assert [r["packet_size"] for r in rows] == [1, 64] and rows[0]["max_abs_rel_error"] == 0.0


@pytest.mark.parametrize(("body", "says"), [
    ({"base": "nowhere.yaml", "packet_sizes": [1]}, "'nowhere.yaml': file not found (relative to the study file)"),
    ({"base": "run.yaml", "packet_sizes": []}, "must be a non-empty list"),
])
def test_a_bad_granularity_base_file_exits_2(tmp_path, capsys, body, says):
    (tmp_path / "run.yaml").write_text(yaml.safe_dump({"scene": "cornell", "mode": "rcast"}))
    path = tmp_path / "g.yaml"
    path.write_text(yaml.safe_dump(body))
    assert main(["granularity", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and says in err[0]
    assert not (tmp_path / "o").exists()


def test_a_granularity_base_file_that_is_no_run_config_names_that_file(tmp_path, capsys):
    (tmp_path / "run.yaml").write_text(yaml.safe_dump({"scene": "cornell", "arch": {"packet_size": 0}}))
    path = tmp_path / "g.yaml"
    path.write_text(yaml.safe_dump({"base": "run.yaml", "packet_sizes": [1]}))
    assert main(["granularity", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(tmp_path / "run.yaml") in err[0] and "arch.packet_size" in err[0]


@pytest.mark.slow
def test_cached_functional_simulates_like_a_fresh_render(tmp_path, monkeypatch):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path))
    cfg = config_from_dict({**TINY, "scene": "ring", "mode": "pmap"})
    fresh, hit = cached_functional(cfg)
    assert not hit
    cached, hit = cached_functional(cfg)
    assert hit
    a = simulate(fresh, load_programs(), cfg.arch)
    b = simulate(cached, load_programs(), cfg.arch)
    assert a.cycles == b.cycles and a.units == b.units
    other = config_from_dict({**TINY, "scene": "ring", "mode": "pmap", "seed": 3})
    assert not cached_functional(other)[1]  # the seed changes the work: another entry


@pytest.mark.parametrize("body, key", [
    ({"base": {}, "scenes": ["ring"], "modez": ["rcast"]}, "modez"),
    ({"base": {"scene": "ring"}}, "base.scene"),
    ({"base": {}, "modes": ["rcast", "raytrace"]}, "modes"),
    ({"base": {"arch": {"packet_size": 0}}}, "arch.packet_size"),
    ({"base": {}, "scenes": []}, "scenes"),
])
def test_bad_study_files(tmp_path, body, key):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(body))
    with pytest.raises(InputError) as e:
        load_study(path)
    assert key in str(e.value) and str(path) in str(e.value)


@pytest.mark.parametrize("body", [
    {"base": {}, "packet_sizes": [0, 4]},
    {"base": {}, "packet_sizes": []},
    {"base": {}, "packet_sizes": [4], "frames": 2},
])
def test_bad_granularity_files_exit_2(tmp_path, capsys, body):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(body))
    assert main(["granularity", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0]
    assert not (tmp_path / "o").exists()


def test_bad_programs_table_fails_before_the_render(tmp_path, capsys):
    table = tmp_path / "p.yaml"
    table.write_text(DEFAULT_PATH.read_text().replace("  scale: ", "  scael: ", 1))
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({"scene": "ring", "arch": {"programs": "p.yaml"}}))
    assert main(["run", str(cfg), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert "scael" in err and "p.yaml" in err
    assert not (tmp_path / "run").exists()


def test_a_flush_probability_from_a_programs_table(tmp_path):
    """`flushes: {leaf_visits: 0.3}`: a flush on 30% of the leaf visits, rounded exactly over
    the job (the running sums are the rounded running sums), not per packet."""
    raw = yaml.safe_load(DEFAULT_PATH.read_text())
    raw["traversal"]["rays"]["flushes"] = {"leaf_visits": 0.3}
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(raw))
    progs = load_programs(tmp_path / "p.yaml")
    visits = np.array([1, 1, 1, 4, 0, 7], dtype=np.int64)
    items = np.ones(6, dtype=np.int64)
    _, flushes, _ = progs.cost("traversal", "rays", {"leaf_visits": visits}, items)
    # running sums 0.3 0.6 0.9 2.1 2.1 4.2 round to 0 1 1 2 2 4
    assert flushes.tolist() == [0, 1, 0, 1, 0, 2]
    _, default, _ = load_programs().cost("traversal", "rays", {"leaf_visits": visits}, items)
    assert default.tolist() == visits.tolist()  # the default: one flush per leaf visit


def test_a_study_rerun_into_its_folder_keeps_the_user_s_files(tmp_path, cache):
    """As a rerun of ``tlm run`` does: the study's own files are replaced (an output it no
    longer writes goes), a user's notes and analysis folder are carried into the new folder."""
    study = tmp_path / "g.yaml"
    base = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"light_samples": 1, "spp": 1},
            "arch": {"frames": 2, "trace": False}}
    study.write_text(yaml.safe_dump({"base": base, "packet_sizes": [1, 64]}))
    out = tmp_path / "g"
    assert main(["granularity", str(study), "--out", str(out)]) == 0
    (out / "notes.md").write_text("mine")
    (out / "analysis").mkdir()
    (out / "analysis" / "fit.py").write_text("mine")
    (out / "granularity.csv").write_text("stale")  # the study's own: replaced
    mine = set((out / ".tlm-files").read_text().split())
    assert {"granularity.jsonl", "granularity.csv", "provenance.json", "report", ".tlm-files"} <= mine
    assert main(["granularity", str(study), "--out", str(out), "--no-report"]) == 0
    assert (out / "notes.md").read_text() == "mine" and (out / "analysis" / "fit.py").read_text() == "mine"
    assert (out / "granularity.csv").read_text() != "stale" and not (out / "report").exists()


def test_granularity_loads_the_flow_shop_kernel_before_its_timed_sizes(tmp_path, monkeypatch):
    """A frame too large for the estimate's Python loop (here: a budget of 0 packets) loads the
    compiled flow shop before the first timed simulation, not inside the first coarse size's
    (whose host seconds booked numba's import, ~2 s, against 0.07 s of simulation)."""
    import tlm.arch.granularity as arch_granularity
    import tlm.experiments.granularity as study

    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(arch_granularity, "FLOW_SHOP_LOOP_PACKETS", 0)
    events: list[str] = []
    real_shop, real_simulate = arch_granularity.flow_shop, study.simulate

    def shop(*a, **k):
        events.append("kernel")
        return real_shop(*a, **k)

    def simulate(*a, **k):
        events.append("simulate")
        return real_simulate(*a, **k)

    monkeypatch.setattr(arch_granularity, "flow_shop", shop)
    monkeypatch.setattr(study, "simulate", simulate)
    path = tmp_path / "g.yaml"
    path.write_text(yaml.safe_dump({"base": {**TINY, "scene": "cornell", "mode": "rcast"}, "packet_sizes": [1, 8]}))
    rows = run_granularity(path, tmp_path / "g")
    assert [r["packet_size"] for r in rows] == [1, 8]
    assert events[0] == "kernel" and events.index("simulate") > 0, events[:5]
