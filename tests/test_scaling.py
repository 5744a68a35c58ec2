"""Eq. 5.2 fitted to scaling sweeps (tlm scaling)."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.scaling import fit, fit_group
from tlm.experiments.sweep import run_sweep


def _points(a, b, v, sums, target="throughput"):
    return [{"pipelines": n, "T_vert0": v, "sum_max": s, "max_max": s / n, target: round(a * v + b * s / n)}
            for n, s in sums.items()]


def test_fit_recovers_a_and_b_of_data_that_follow_eq_5_2():
    pts = _points(0.7, 1.3, 1000, {1: 90_000, 2: 91_000, 4: 93_000, 8: 97_000})
    f = fit_group(pts, "throughput")
    assert f["A"] == pytest.approx(0.7, rel=1e-3) and f["B"] == pytest.approx(1.3, rel=1e-4)
    assert f["max_abs_rel_error"] < 1e-4


def test_fit_is_exact_at_one_pipeline_and_least_squares_elsewhere():
    pts = [{"pipelines": 1, "T_vert0": 100, "sum_max": 1000, "max_max": 1000, "latency": 1200},
           {"pipelines": 2, "T_vert0": 100, "sum_max": 1000, "max_max": 500, "latency": 700},
           {"pipelines": 4, "T_vert0": 100, "sum_max": 1000, "max_max": 250, "latency": 500}]
    f = fit_group(pts, "latency")
    one = f["rows"][0]
    assert one["pipelines"] == 1 and one["analytical"] == 1200 and one["rel_error"] == 0
    # x = M(N) - M(1) = -500, -750; y = -500, -700: B = (250000 + 525000) / (250000 + 562500)
    b = (500 * 500 + 750 * 700) / (500 ** 2 + 750 ** 2)
    assert f["B"] == pytest.approx(b)
    assert f["A"] == pytest.approx((1200 - b * 1000) / 100)
    assert [r["speedup"] for r in f["rows"]] == [1.0, pytest.approx(1200 / 700, abs=1e-4), 2.4]


def test_slowest_pipeline_variant_fits_an_uneven_static_tiling():
    """The slowest pipeline keeps most of the work as N grows: T(N) = T_vert0 + its time,
    which the slowest-pipeline variant follows exactly and the mean over the pipelines does not."""
    slowest = {1: 1000, 2: 800, 4: 600, 8: 500}
    pts = [{"pipelines": n, "T_vert0": 100, "sum_max": 1000, "max_max": m, "throughput": 100 + m}
           for n, m in slowest.items()]
    mean = fit_group(pts, "throughput")
    slow = fit_group(pts, "throughput", slowest=True)
    assert slow["max_abs_rel_error"] < 1e-9
    assert mean["max_abs_rel_error"] > 0.05


def test_fit_needs_one_pipeline():
    with pytest.raises(InputError, match="N = 1"):
        fit_group([{"pipelines": n, "T_vert0": 1, "sum_max": 1, "latency": 1} for n in (2, 4)], "latency")


def test_points_that_differ_in_another_key_are_not_mixed():
    pts = [{"pipelines": n, "T_vert0": 1, "sum_max": 10, "max_max": 10, "latency": 20} for n in (1, 2, 2)]
    with pytest.raises(InputError, match="same N"):
        fit_group(pts, "latency")
    with pytest.raises(InputError, match="two values of N"):
        fit_group(pts[:1], "latency")


def test_a_mixed_group_names_its_sweep_folders():
    pts = [{"pipelines": n, "T_vert0": 1, "sum_max": 10, "max_max": 10, "latency": 20, "throughput": 20,
            "scene": "cornell", "mode": "rcast", "scheduler": "static", "sweep": sweep}
           for n, sweep in ((1, "runs/a"), (2, "runs/a"), (2, "runs/b"))]
    with pytest.raises(InputError, match="same N") as e:
        fit(pts)
    assert str(e.value).startswith("runs/a, runs/b (cornell/rcast/static): arch.pipelines: ")
    with pytest.raises(InputError, match=r"^somewhere: arch\.pipelines: two points"):
        fit_group(pts, "latency", source="somewhere")


def test_not_a_sweep_folder_exits_2(tmp_path, capsys):
    assert main(["scaling", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    assert "sweep.jsonl" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_a_scaling_sweep_end_to_end(tmp_path, cache, capsys):
    sweep = tmp_path / "scaling.yaml"
    sweep.write_text(yaml.safe_dump({
        "base": {"scene": "cornell", "mode": "rcast", "resolution": [32, 32], "render": {"light_samples": 1},
                 "arch": {"frames": 2, "trace": False}},
        "grid": {"arch.scheduler": ["static", "dynamic"], "arch.pipelines": [1, 2, 4]},
    }))
    done = run_sweep(sweep, tmp_path / "sw", jobs=1)
    assert done.ok == 6 and done.renders == 1
    assert main(["scaling", str(tmp_path / "sw"), "--out", str(tmp_path / "eq")]) == 0
    out = capsys.readouterr().out
    assert "eq. 5.2" in out
    with open(tmp_path / "eq" / "eq52.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 * 2 * 3  # schedulers x targets x N
    fits = json.loads((tmp_path / "eq" / "eq52.json").read_text())["fits"]
    assert {(f["scheduler"], f["target"]) for f in fits} == {(s, t) for s in ("static", "dynamic")
                                                              for t in ("latency", "throughput")}
    assert Path(tmp_path / "eq" / "scaling_cornell.png").stat().st_size > 10_000
    for r in rows:
        if r["pipelines"] == "1":
            assert r["simulated"] == r["analytical"] == r["analytical_slowest"]
    # more pipelines: every pipeline's share of the work shrinks
    by_n = {int(r["pipelines"]): int(r["sum_max_per_N"]) for r in rows if r["scheduler"] == "dynamic"}
    assert by_n[4] < by_n[2] < by_n[1]


@pytest.fixture(scope="module")
def small_sweep(tmp_path_factory):
    """A finished sweep over N in (1, 2) and two FIFO depths (two points per N)."""
    tmp = tmp_path_factory.mktemp("small")
    path = tmp / "scaling.yaml"
    path.write_text(yaml.safe_dump({
        "base": {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1},
                 "arch": {"frames": 2, "trace": False}},
        "grid": {"arch.pipelines": [1, 2], "arch.fifo_depth": [1, 16]},
    }))
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(tmp / "cache"))
        done = run_sweep(path, tmp / "sw", jobs=1)
    assert done.ok == 4
    return tmp / "sw"


def _copy(small_sweep: Path, tmp_path: Path, depth: int | None = 16) -> tuple[Path, list[str]]:
    """A copy of the sweep folder whose sweep.jsonl keeps the rows of one FIFO depth (None: all)."""
    folder = tmp_path / "sw"
    shutil.copytree(small_sweep, folder)
    lines = [line for line in (folder / "sweep.jsonl").read_text().splitlines(keepends=True)
             if depth is None or json.loads(line)["arch.fifo_depth"] == depth]
    (folder / "sweep.jsonl").write_text("".join(lines))
    return folder, lines


@pytest.mark.slow
def test_points_of_a_crossed_group_are_fitted_per_combination(tmp_path, small_sweep, capsys):
    """A grid of N and the FIFO depth (N = 1, 1, 2, 2): a fit per depth (it was refused)."""
    folder, _ = _copy(small_sweep, tmp_path, depth=None)
    assert main(["scaling", str(folder), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    meta = json.loads((tmp_path / "eq" / "eq52.json").read_text())
    assert sorted((f["group"], f["target"], tuple(f["pipelines"])) for f in meta["fits"]) == [
        (f"arch.fifo_depth = {d}", t, (1, 2)) for d in (1, 16) for t in ("latency", "throughput")]


@pytest.mark.slow
def test_a_torn_last_row_is_left_out(tmp_path, small_sweep, capsys):
    """A sweep killed while writing a row leaves it cut off: the finished rows are fitted."""
    folder, lines = _copy(small_sweep, tmp_path)
    (folder / "sweep.jsonl").write_text("".join(lines) + lines[0][:30])
    assert main(["scaling", str(folder), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    fits = json.loads((tmp_path / "eq" / "eq52.json").read_text())["fits"]
    assert {tuple(f["pipelines"]) for f in fits} == {(1, 2)}


@pytest.mark.parametrize("damage, where", [
    ("middle", "sweep.jsonl: line 2: is not a JSON row"),
    ("not a row", "sweep.jsonl: line 3: is not a JSON row"),
    ("folder", "sweep.jsonl: line 2: point 3: "),
])
def test_a_damaged_sweep_folder_exits_2(tmp_path, small_sweep, capsys, damage, where):
    folder, lines = _copy(small_sweep, tmp_path)
    if damage == "middle":  # a torn row, and more rows after it
        (folder / "sweep.jsonl").write_text(lines[0] + lines[1][:30] + "\n" + lines[1])
    elif damage == "not a row":
        (folder / "sweep.jsonl").write_text("".join(lines) + "[1, 2]\n")
    else:
        shutil.rmtree(folder / "points" / json.loads(lines[1])["hash"])
    assert main(["scaling", str(folder), "--out", str(tmp_path / "eq"), "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tlm: error: ") and where in err[0], err
    if damage == "folder":
        assert "results.json is missing" in err[0]
    assert not (tmp_path / "eq").exists()
