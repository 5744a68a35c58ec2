"""tlm scaling: a fit group's points differ in N alone, failed points are named, a folder
given twice is read once."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.scaling import fit, record
from tlm.experiments.sweep import run_sweep

DEADLOCK = "Deadlock: the model cannot finish at cycle 0 (arch.max_events = 20 events passed)"


def _config(n: int, **arch) -> dict:
    return {"scene": "cornell", "mode": "rcast", "seed": 0, "resolution": [16, 16],
            "render": {"threads": None, "batch": 4},
            "arch": {"pipelines": n, "scheduler": "static", "page_miss_cycles": 0, "max_events": 200_000_000,
                     **arch}}


def _results(n: int) -> dict:
    """A point's results.json, as much of it as eq. 5.2 reads: the work splits over N pipelines."""
    per = {"traversal": 9000 // n, "intersection": 12000 // n, "fragment": 3000 // n}
    return {"scene": {"name": "cornell"}, "timing": {"pipelines": [per] * n},
            "cycles": {"vertex": 1000, **per, "latency": 2000 + 12000 // n, "throughput": 1000 + 12000 // n}}


def fake_sweep(folder: Path, points: list[tuple[dict, dict, str]]) -> Path:
    """A sweep folder of points (factors, resolved config, status), without rendering."""
    (folder / "points").mkdir(parents=True)
    spec = {"tlm": "sweep/1", "points": []}
    rows = []
    for i, (factors, cfg, status) in enumerate(points):
        h = f"{i:016x}"
        spec["points"].append({"point": i, "hash": h, "factors": factors})
        rows.append({"point": i, "hash": h, "status": status, "error": None if status == "ok" else DEADLOCK,
                     **factors})
        if status == "ok":
            (folder / "points" / h).mkdir()
            (folder / "points" / h / "results.json").write_text(json.dumps(_results(cfg["arch"]["pipelines"])))
            (folder / "points" / h / "config.resolved.yaml").write_text(yaml.safe_dump(cfg))
    (folder / "sweep.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


# ------------------------------------------------------------------ 1: points that differ in more than N


def test_a_fit_group_whose_points_differ_in_another_key_is_refused_naming_it():
    recs = [{**record(_results(n), _config(n, page_miss_cycles=m)), "sweep": "runs/sc"}
            for n, m in ((1, 0), (2, 100), (4, 1000))]
    with pytest.raises(InputError, match=r"differ in more than N") as e:
        fit(recs)
    text = str(e.value)
    assert text.startswith("runs/sc (cornell/rcast/static): arch.page_miss_cycles: ")
    assert "0 at N = 1, 100 at N = 2, 1000 at N = 4" in text


def test_keys_that_leave_the_cycles_as_they_are_may_differ():
    """A cap on events, the trace, the clock, the kernels' threads and batches, the images' exposure,
    the reference."""
    recs = [record(_results(n), {**_config(n, max_events=10 ** 6 * n, trace=n > 1, clock_hz=1e8 * n),
                                 "render": {"threads": n, "batch": n, "batch_rays": 1024 * n, "exposure": 0.5 * n},
                                 "reference": {"tolerance": 0.01 * n}}) for n in (1, 2, 4)]
    fits = fit(recs)
    assert {k[:3] for k in fits} == {("cornell", "rcast", "static")}
    assert [r["pipelines"] for r in fits[("cornell", "rcast", "static", "latency")]["rows"]] == [1, 2, 4]


def test_two_sweeps_of_different_bases_are_not_fitted_as_one(tmp_path, capsys):
    """N = 1, 2 from one sweep and N = 4 from another whose base sets another FIFO depth."""
    a = fake_sweep(tmp_path / "a", [({"arch.pipelines": n}, _config(n), "ok") for n in (1, 2)])
    b = fake_sweep(tmp_path / "b", [({"arch.pipelines": 4}, _config(4, fifo_depth=4), "ok")])
    assert main(["scaling", str(a), str(b), "--out", str(tmp_path / "eq"), "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"tlm: error: {a}, {b} (cornell/rcast/static): arch.fifo_depth: "), err
    assert "4 at N = 4" in err[0]
    assert not (tmp_path / "eq").exists()


def test_a_zipped_sweep_exits_2_naming_the_other_factor(tmp_path, capsys):
    sw = fake_sweep(tmp_path / "sw", [({"arch.pipelines": n, "arch.page_miss_cycles": m},
                                       _config(n, page_miss_cycles=m), "ok") for n, m in ((1, 0), (2, 100), (4, 1000))])
    assert main(["scaling", str(sw), "--out", str(tmp_path / "eq"), "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "arch.page_miss_cycles" in err[0] and str(sw) in err[0], err
    assert not (tmp_path / "eq").exists()


# ------------------------------------------------------------------ 2: failed points are named


def test_a_failed_point_is_left_out_with_a_note(tmp_path, capsys):
    sw = fake_sweep(tmp_path / "sw", [({"arch.pipelines": n, "arch.max_events": e}, _config(n, max_events=e),
                                       "ok" if n < 8 else "failed") for n, e in ((1, 10 ** 8), (2, 10 ** 8),
                                                                                 (4, 10 ** 8), (8, 20))])
    assert main(["scaling", str(sw), "--out", str(tmp_path / "eq")]) == 0
    captured = capsys.readouterr()
    meta = json.loads((tmp_path / "eq" / "eq52.json").read_text())
    assert {tuple(f["pipelines"]) for f in meta["fits"]} == {(1, 2, 4)}
    assert len(meta["notes"]) == 1
    note = meta["notes"][0]
    assert note.startswith(f"{sw}: point 3 (arch.pipelines = 8, arch.max_events = 20) failed (Deadlock: ")
    assert note.endswith("left out of the fit")
    assert f"tlm: note: {note}" in captured.err
    assert f"eq: {note}" in (tmp_path / "eq" / "report" / "report.html").read_text()  # (the report says it too)


def test_a_fit_that_misses_a_failed_point_says_it_failed(tmp_path, capsys):
    """N = 1 failed: the error (no N = 1 to fit through) names the point left out."""
    sw = fake_sweep(tmp_path / "sw", [({"arch.pipelines": n}, _config(n), "failed" if n == 1 else "ok")
                                      for n in (1, 2, 4)])
    assert main(["scaling", str(sw), "--out", str(tmp_path / "eq"), "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "fitted through N = 1" in err[0], err
    assert err[0].endswith(f"(left out, as they failed: {sw}: point 0 (arch.pipelines = 1))")


# ------------------------------------------------------------------ 3: a folder given twice


def test_the_same_folder_given_twice_is_read_once(tmp_path, capsys):
    sw = fake_sweep(tmp_path / "sw", [({"arch.pipelines": n}, _config(n), "ok") for n in (1, 2, 4)])
    again = tmp_path / "x" / ".." / "sw"  # another path to the same folder
    assert main(["scaling", str(sw), str(sw), str(again), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    err = capsys.readouterr().err
    meta = json.loads((tmp_path / "eq" / "eq52.json").read_text())
    assert {tuple(f["pipelines"]) for f in meta["fits"]} == {(1, 2, 4)}
    assert len(meta["sweeps"]) == 1
    assert meta["notes"] == [f"{sw}: given twice (the same folder as {sw}): read once",
                             f"{again}: given twice (the same folder as {sw}): read once"]
    assert "differ" not in err


# ------------------------------------------------------------------ the probe's sweeps, rendered


@pytest.mark.slow
def test_rendered_sweeps_mixed_and_failed(tmp_path, cache, capsys):
    """The outside probe's cases: a zip of N with page-miss cycles exits 2 naming the key; a
    zip whose N = 8 point deadlocks is fitted over N = 1, 2, 4 with a note naming it."""
    (tmp_path / "base.yaml").write_text(yaml.safe_dump({
        "scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 3, "trace": False}}))
    for name, zipped in (("mixed", {"arch.pipelines": [1, 2, 4], "arch.page_miss_cycles": [0, 100, 1000]}),
                         ("failed", {"arch.pipelines": [1, 2, 4, 8], "arch.max_events": [2 * 10 ** 8] * 3 + [20]})):
        (tmp_path / f"{name}.yaml").write_text(yaml.safe_dump({"base": "base.yaml", "zip": zipped}, sort_keys=False))
    assert run_sweep(tmp_path / "mixed.yaml", tmp_path / "mixed", jobs=1).ok == 3
    done = run_sweep(tmp_path / "failed.yaml", tmp_path / "failed", jobs=1)
    assert (done.ok, done.failed) == (3, 1)
    capsys.readouterr()
    assert main(["scaling", str(tmp_path / "mixed"), "--out", str(tmp_path / "eq_m"), "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "arch.page_miss_cycles: " in err[0] and "100 at N = 2" in err[0], err
    assert main(["scaling", str(tmp_path / "failed"), "--out", str(tmp_path / "eq_f"), "--no-report"]) == 0
    meta = json.loads((tmp_path / "eq_f" / "eq52.json").read_text())
    assert {tuple(f["pipelines"]) for f in meta["fits"]} == {(1, 2, 4)}
    failed = [n for n in meta["notes"] if ") failed (" in n]
    assert len(failed) == 1 and "point 3 (arch.pipelines = 8, arch.max_events = 20) failed" in failed[0]
    # (3 frames have no steady window: each point fitted is said to be so, tests/test_scaling_scenes.py)
    assert sum("too short for a steady state" in n for n in meta["notes"]) == 3 == len(meta["notes"]) - 1
