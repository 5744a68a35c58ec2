"""Report figures over sweeps: idle fraction per PM (static against dynamic) and the BSP-levels balance.

The data behind each figure are checked against the sweep's own rows (and, for
floor(ln n), the points' results.json); each figure must exist and not be blank; a sweep
without the data a figure needs gets a note saying why; and ``tlm plots`` (here with
its steps stubbed out) puts the idle figure in the combined report once, from the
scaling sweeps that the eq52 step fits.
"""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from matplotlib.image import imread

from tlm.cli import main
from tlm.errors import InputError
from tlm.report import build_report
from tlm.report.collect import read
from tlm.report.regenerate import REPORTED, SCALING, STEPS, regenerate
from tlm.report.scaling import idle_points
from tlm.report.sweeps import levels_balance

BASE = {"mode": "rcast", "resolution": [32, 32], "render": {"light_samples": 1}, "arch": {"frames": 1, "trace": False}}
PMS = ("vertex", "traversal", "intersection", "fragment")


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory):
    """Two tiny real sweeps: ring over pipelines x scheduler, and ring and cornell over BSP levels."""
    root = tmp_path_factory.mktemp("report_sweeps")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        (root / "sc.yaml").write_text(yaml.safe_dump({
            "base": {**BASE, "scene": "ring"},
            "grid": {"arch.scheduler": ["static", "dynamic"], "arch.pipelines": [1, 2, 4]}}))
        (root / "bsp.yaml").write_text(yaml.safe_dump({
            "base": BASE, "grid": {"scene": ["ring", "cornell"], "bsp.levels": [5, 6, 7, 8]}}))
        for name in ("sc", "bsp"):
            assert main(["sweep", str(root / f"{name}.yaml"), "--out", str(root / name), "--jobs", "1",
                         "--no-progress", "--no-report"]) == 0
    return root


def rows(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "sweep.jsonl").read_text().splitlines() if line.strip()]


def nonblank(png: Path) -> None:
    assert png.is_file(), png
    pixels = np.asarray(imread(png), dtype=float)
    assert pixels.shape[0] > 300 and pixels.shape[1] > 500
    assert pixels[..., :3].std() > 0.05, f"{png.name} is blank"


def section(page: Path, key: str) -> str:
    text = page.read_text(encoding="utf-8")
    start = text.index(f'<section id="{key}">')
    return text[start:text.index("</section>", start)]


def rewrite(folder: Path, change) -> None:
    """Replace the rows of a copied sweep (both files the report could read)."""
    new = [change(dict(r)) for r in rows(folder)]
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in new))
    (folder / "sweep.csv").unlink(missing_ok=True)


def rows_only(folder: Path, spec: dict, new_rows: list[dict]) -> Path:
    """A sweep folder with sweep.yaml and sweep.jsonl but no points/ (no results.json)."""
    folder.mkdir(parents=True)
    (folder / "sweep.yaml").write_text(yaml.safe_dump(spec))
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in new_rows))
    return folder


# ------------------------------------------------------------ idle fraction per PM, static against dynamic


@pytest.mark.slow
def test_idle_points_are_the_rows(sweeps):
    notes: list[str] = []
    groups = idle_points(read([sweeps / "sc"]).sweeps[0], notes)
    assert notes == []
    assert list(groups) == [("ring", "rcast")]
    g = groups[("ring", "rcast")]
    assert g["pms"] == list(PMS)
    by_point = {r["point"]: r for r in rows(sweeps / "sc")}
    assert sorted(p["point"] for p in g["points"]) == sorted(by_point)
    assert [(p["scheduler"], p["pipelines"]) for p in g["points"]] == [
        ("static", 1), ("static", 2), ("static", 4), ("dynamic", 1), ("dynamic", 2), ("dynamic", 4)]
    t1 = {r["arch.scheduler"]: r["cycles.throughput"] for r in by_point.values() if r["arch.pipelines"] == 1}
    for p in g["points"]:
        r = by_point[p["point"]]
        assert (p["scheduler"], p["pipelines"]) == (r["arch.scheduler"], r["arch.pipelines"])
        assert p["idle"] == {pm: r[f"idle.{pm}"] for pm in PMS}
        assert p["throughput"] == r["cycles.throughput"]
        assert p["speedup"] == t1[r["arch.scheduler"]] / r["cycles.throughput"]
        assert all(0.0 <= v <= 1.0 for v in p["idle"].values())
    assert any(p["idle"]["traversal"] > 0 for p in g["points"] if p["pipelines"] > 1)


@pytest.mark.slow
def test_idle_figure_and_table_in_the_report(sweeps, tmp_path):
    page = build_report([sweeps / "sc"], tmp_path / "rep")
    nonblank(tmp_path / "rep" / "idle_sc_ring.png")
    nonblank(tmp_path / "rep" / "scaling_sc_ring.png")  # the eq. 5.2 figure is still there
    scaling = section(page, "scaling")
    assert "idle_sc_ring.png" in scaling
    table = scaling[scaling.index("<details>"):scaling.index("</details>")]
    cells = [re.findall(r"<td[^>]*>([^<]*)</td>", tr) for tr in table.split("<tr>")[2:]]
    assert len(cells) == 6  # one row per point, by N then scheduler
    assert [(c[0], c[1]) for c in cells] == [("1", "static"), ("1", "dynamic"), ("2", "static"), ("2", "dynamic"),
                                             ("4", "static"), ("4", "dynamic")]
    by_key = {(r["arch.pipelines"], r["arch.scheduler"]): r for r in rows(sweeps / "sc")}
    for c in cells:
        r = by_key[(int(c[0]), c[1])]
        assert float(c[2]) == pytest.approx(r["cycles.throughput"] / 1e6, rel=1e-3)
        assert c[4:] == [f"{r[f'idle.{pm}']:.3f}" for pm in PMS]
    assert len({len(c[2].partition(".")[2]) for c in cells}) == 1  # (one number of decimals in the column)
    assert "sweeps" in page.read_text() and "idle_sc_ring.png" not in section(page, "sweeps")


@pytest.mark.slow
def test_idle_without_columns_says_why(sweeps, tmp_path):
    old = tmp_path / "old"
    shutil.copytree(sweeps / "sc", old)
    rewrite(old, lambda r: {k: v for k, v in r.items() if not k.startswith("idle.")})
    page = build_report([old], tmp_path / "rep")
    scaling = section(page, "scaling")
    assert "old: no idle fractions to draw: its rows have no idle.&lt;pm&gt; column" in scaling
    assert not list((tmp_path / "rep").glob("idle_*.png"))
    assert (tmp_path / "rep" / "scaling_old_ring.png").is_file()  # eq. 5.2 needs no idle column


def test_idle_from_rows_alone(tmp_path):
    """A sweep folder without points/ still has its idle figure (the factors and idle.* are in the rows);
    a single N says why there is none."""
    new_rows = [{"point": i, "hash": f"h{i}", "status": "ok", "arch.scheduler": s, "arch.pipelines": n,
                 "scene": "ring", "mode": "rcast", "cycles.throughput": 1000 // n + (s == "static") * 50,
                 **{f"idle.{pm}": round(0.1 * k + 0.01 * n, 6) for k, pm in enumerate(PMS)}}
                for i, (s, n) in enumerate((s, n) for s in ("static", "dynamic") for n in (1, 2, 4, 8))]
    spec = {"sweep": "x.yaml", "grid": {"arch.scheduler": ["static", "dynamic"], "arch.pipelines": [1, 2, 4, 8]}}
    sw = rows_only(tmp_path / "syn", spec, new_rows)
    one = rows_only(tmp_path / "one", {**spec, "grid": {"arch.pipelines": [2]}},
                    [{**new_rows[1], "point": 0}])
    page = build_report([sw, one], tmp_path / "rep")
    nonblank(tmp_path / "rep" / "idle_syn_ring.png")
    pts = idle_points(read([sw]).sweeps[0], [])[("ring", "rcast")]["points"]
    assert [p["idle"] for p in pts] == [{pm: r[f"idle.{pm}"] for pm in PMS} for r in new_rows]
    assert pts[3]["speedup"] == 1050 / 175
    scaling = section(page, "scaling")
    assert "one: ring/rcast: no idle figure: one value of N only" in scaling
    assert "syn: no finished point with a results folder: eq. 5.2 not fitted" in scaling


# ------------------------------------------------------------ BSP levels against floor(ln n)


def test_levels_balance_is_the_rows(sweeps):
    notes: list[str] = []
    series, summary = levels_balance(read([sweeps / "bsp"]).sweeps[0], notes)
    assert notes == []
    table = rows(sweeps / "bsp")
    assert sorted(series) == [("cornell",), ("ring",)]
    assert [s["scene"] for s in summary] == ["cornell", "ring"]
    for s in summary:
        mine = sorted((r for r in table if r["scene"] == s["scene"]), key=lambda r: r["bsp.levels"])
        pts = series[(s["scene"],)]
        assert [p["level"] for p in pts] == [5, 6, 7, 8]
        ratio = {r["bsp.levels"]: r["cycles.traversal"] / r["cycles.intersection"] for r in mine}
        assert [p["ratio"] for p in pts] == [ratio[v] for v in (5, 6, 7, 8)]
        assert [p["fps"] for p in pts] == [r["fps"] for r in mine]
        results = [json.loads((sweeps / "bsp" / "points" / r["hash"] / "results.json").read_text()) for r in mine]
        n = results[0]["scene"]["triangles"]
        assert s["triangles"] == n and s["floor_ln"] == math.floor(math.log(n))
        assert s["floor_ln"] == {"ring": 6, "cornell": 7}[s["scene"]]  # 646 and 2604 triangles
        assert s["ratio_at_floor"] == ratio[s["floor_ln"]]
        assert s["fps_at_floor"] == next(r["fps"] for r in mine if r["bsp.levels"] == s["floor_ln"])
        closest = min(ratio, key=lambda v: abs(math.log(ratio[v])))
        assert (s["closest_level"], s["closest_ratio"]) == (closest, ratio[closest])
        best = max(mine, key=lambda r: r["fps"])
        assert (s["best_level"], s["best_fps"]) == (best["bsp.levels"], best["fps"])


@pytest.mark.slow
def test_levels_figure_and_table_in_the_report(sweeps, tmp_path):
    page = build_report([sweeps / "bsp"], tmp_path / "rep")
    nonblank(tmp_path / "rep" / "bsp_balance_bsp.png")
    text = section(page, "sweeps")
    assert "bsp_balance_bsp.png" in text
    _, summary = levels_balance(read([sweeps / "bsp"]).sweeps[0], [])
    for s in summary:
        row = (f'<td class="l">{s["scene"]}</td><td>{s["triangles"]}</td><td>{s["floor_ln"]}</td>'
               f'<td>{s["ratio_at_floor"]:.4f}</td><td>{s["fps_at_floor"]:.4g}</td><td>{s["closest_level"]}</td>'
               f'<td>{s["closest_ratio"]:.4f}</td><td>{s["best_level"]}</td><td>{s["best_fps"]:.4g}</td>')
        assert row in text, row
    # a sweep that does not vary bsp.levels gets no such figure or table
    other = build_report([sweeps / "sc"], tmp_path / "rep2")
    assert "floor(ln n)" not in section(other, "sweeps")
    assert not list((tmp_path / "rep2").glob("bsp_balance_*.png"))


@pytest.mark.slow
def test_levels_without_the_data_says_why(sweeps, tmp_path):
    blind = tmp_path / "blind"
    shutil.copytree(sweeps / "bsp", blind)
    rewrite(blind, lambda r: {k: v for k, v in r.items() if k not in ("cycles.traversal", "cycles.intersection")})
    bare = rows_only(tmp_path / "bare", {"sweep": "x.yaml", "grid": {"bsp.levels": [6, 7]}},
                     [{"point": i, "hash": f"h{i}", "status": "ok", "scene": "ring", "mode": "rcast",
                       "bsp.levels": v, "cycles.traversal": 300 + i, "cycles.intersection": 600, "fps": 10.0 + i}
                      for i, v in enumerate((6, 7))])
    page = build_report([blind, bare], tmp_path / "rep")
    text = section(page, "sweeps")
    assert "blind: no BSP-levels balance: no finished point with cycles.traversal and cycles.intersection" in text
    assert "bare: no results.json for ring: its triangle count n, hence floor(ln n), is unknown" in text
    assert '<td class="l">ring</td><td></td><td>unknown</td>' in text
    assert (tmp_path / "rep" / "bsp_balance_bare.png").is_file()
    assert not (tmp_path / "rep" / "bsp_balance_blind.png").exists()


# ------------------------------------------------------------ tlm plots: the idle figure reaches plots/, once


def test_plots_runs_every_step_and_needs_a_folder_to_report(tmp_path):
    """The fast part of the test below: every step in order, its argv filled in and without
    its own report; an unknown ``--only`` step, or no step's folder at all, is bad input."""
    called = []
    with pytest.raises(InputError, match="no step's folder exists"):
        regenerate(Path("configs"), tmp_path, tmp_path / "plots", run_command=lambda argv: called.append(argv) or 0,
                   say=lambda _: None)
    assert [argv[:-1] for argv in called] == [[a.format(configs="configs", runs=tmp_path) for a in argv]
                                              for _, argv in STEPS]
    assert {argv[-1] for argv in called} == {"--no-report"}
    eq52 = next(argv for argv in called if argv[0] == "scaling")
    assert eq52[1:1 + len(SCALING)] == [str(tmp_path / s) for s in SCALING]
    with pytest.raises(InputError, match="unknown step 'nope'"):
        regenerate(Path("configs"), tmp_path, tmp_path / "plots", ["nope"], run_command=called.append)


@pytest.mark.slow
def test_plots_report_draws_the_scaling_sweeps_idle_once(sweeps, tmp_path):
    runs = tmp_path / "runs"
    runs.mkdir()
    shutil.copytree(sweeps / "sc", runs / "scaling_ring")
    shutil.copytree(sweeps / "bsp", runs / "bsp_levels")
    assert main(["scaling", str(runs / "scaling_ring"), "--out", str(runs / "eq52"), "--no-report"]) == 0
    called = []
    page = regenerate(Path("configs"), runs, tmp_path / "plots", run_command=lambda argv: called.append(argv) or 0,
                      say=lambda _: None)
    assert len(called) == len(STEPS)
    eq52 = next(argv for argv in called if argv[0] == "scaling")
    assert eq52[1:1 + len(SCALING)] == [str(runs / s) for s in SCALING]
    assert not set(SCALING) & set(REPORTED)
    files = {p.name for p in (tmp_path / "plots").glob("*.png")}
    assert "idle_scaling_ring_ring.png" in files
    assert "scaling_eq52_ring.png" in files
    assert not [f for f in files if f.startswith("scaling_scaling_ring")], "eq. 5.2 drawn twice"
    assert "bsp_balance_bsp_levels.png" in files
    nonblank(tmp_path / "plots" / "idle_scaling_ring_ring.png")
    assert "<h3>scaling_ring</h3>" not in section(page, "sweeps")
    assert str(runs / "scaling_ring" / "points") not in section(page, "provenance")
    assert "<h3>bsp_levels</h3>" in section(page, "sweeps")


def test_scaling_sweeps_must_be_sweeps(sweeps, tmp_path):
    with pytest.raises(InputError, match="must be sweep folders"):
        build_report([sweeps / "bsp"], tmp_path / "rep", scaling_sweeps=[sweeps / "sc" / "points" /
                                                                         rows(sweeps / "sc")[0]["hash"]])


@pytest.mark.slow
def test_a_torn_last_row_is_left_out_and_a_corrupt_one_refused(sweeps, tmp_path):
    """A sweep killed while writing a row leaves it cut off: the report reads the others."""
    torn = tmp_path / "torn"
    shutil.copytree(sweeps / "sc", torn)
    (torn / "sweep.csv").unlink()
    with open(torn / "sweep.jsonl", "a") as f:
        f.write('{"point": 99, "status": "o')
    page = build_report([torn], tmp_path / "rep")
    scaling = section(page, "scaling")
    table = scaling[scaling.index("<details>"):scaling.index("</details>")]
    assert len(table.split("<tr>")[2:]) == 6
    lines = (torn / "sweep.jsonl").read_text().splitlines()
    (torn / "sweep.jsonl").write_text("\n".join([lines[0], "{not json", *lines[1:]]) + "\n")
    with pytest.raises(InputError, match="line 2"):
        build_report([torn], tmp_path / "rep2")
    assert not (tmp_path / "rep2").exists()


@pytest.mark.slow
def test_a_scaling_study_alone_brings_its_sweeps_idle_figure(sweeps, tmp_path):
    """`tlm report` of a scaling study's folder draws the idle fractions of the sweeps it
    recorded in eq52.json (and only notes their absence when they are gone)."""
    sc = tmp_path / "sc"
    shutil.copytree(sweeps / "sc", sc)
    assert main(["scaling", str(sc), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    assert json.loads((tmp_path / "eq" / "eq52.json").read_text())["sweeps"] == ["../sc"]
    page = build_report([tmp_path / "eq"], tmp_path / "rep")
    nonblank(tmp_path / "rep" / "idle_sc_ring.png")
    assert "idle_sc_ring.png" in section(page, "scaling")
    moved = tmp_path / "moved"  # the study and its sweep moved together: still found
    moved.mkdir()
    shutil.move(str(sc), moved / "sc")
    shutil.move(str(tmp_path / "eq"), moved / "eq")
    build_report([moved / "eq"], tmp_path / "rep1")
    nonblank(tmp_path / "rep1" / "idle_sc_ring.png")
    shutil.rmtree(moved / "sc")
    page = build_report([moved / "eq"], tmp_path / "rep2")
    assert not list((tmp_path / "rep2").glob("idle_*.png"))
    assert "eq: its sweep " in section(page, "scaling") and "is gone: no idle fractions from it" in section(
        page, "scaling")
    assert list((tmp_path / "rep2").glob("scaling_*.png"))  # the eq. 5.2 figure needs no sweep folder
