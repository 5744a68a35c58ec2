"""Four defects left from an earlier stop (h232).

1. A relative ``TLM_CACHE`` was read afresh each time against the working folder of the moment:
   ``TLM_CACHE=cache`` then an ``os.chdir`` (a notebook's) moved every cache to another folder, and a
   sweep's workers, given the variable as written, read it from wherever they started. Now it is made
   absolute at its first read (``tlm.caches.own_cache``), from the working folder then.
2. ``tlm.load_config(file, base=...)`` ignored ``base`` unsaid (a file's relative paths start at its
   own folder, docs/api.md): another folder given with a file, a built-in name or a Config is refused.
3. ``tlm error-vs-cost``'s rows had no column for the rule that gave each radius (``density``,
   ``fallback``, ...), which a run's ``results.json`` records: ``radius_rule`` and
   ``caustic_radius_rule``, appended after the old columns.
4. A sweep point's ``host_seconds.one_off`` counted every thread's compile and import spans of its
   process (two points in threads of one Dask worker: each counted the other's); now its own alone,
   as ``tlm run``'s.
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

import tlm
import tlm.render.pmap as pmap
from tlm.caches import cache_home, cache_root
from tlm.config import apply_overrides, config_from_dict
from tlm.errors import InputError
from tlm.experiments import sweep_point
from tlm.experiments.error_cost import COLUMNS, Truth, run_error_vs_cost
from tlm.experiments.loading import load_frame

ROOT = Path(__file__).resolve().parents[1]


# ---------------------------------------------------------------- 1. a relative TLM_CACHE


def test_a_relative_tlm_cache_stays_the_folder_of_its_first_read(tmp_path, monkeypatch):
    first, later = tmp_path / "first", tmp_path / "later"
    first.mkdir()
    later.mkdir()
    monkeypatch.chdir(first)
    monkeypatch.setenv("TLM_CACHE", "rel")
    assert cache_home() == first / "rel"
    assert os.environ["TLM_CACHE"] == str(first / "rel")  # (what workers and child processes are given)
    monkeypatch.chdir(later)  # (the old code: later/rel)
    assert cache_home() == first / "rel" and cache_root("functional") == first / "rel" / "functional"
    monkeypatch.setenv("TLM_CACHE", "other")  # (set again: a first read of its own, from the folder then)
    assert cache_home() == later / "other"


@pytest.mark.slow  # (a subprocess)
def test_a_relative_tlm_cache_is_made_absolute_as_tlms_caches_are_imported(tmp_path):
    """A process started with ``TLM_CACHE=rel`` that changes folder before it reads a cache: its folder is
    the one it started in, and what it passes on (a sweep's workers: its ``TLM_*`` variables) is absolute."""
    start, later = tmp_path / "start", tmp_path / "later"
    start.mkdir()
    later.mkdir()
    code = ("import os, tlm.caches; os.chdir(os.environ['LATER']); from tlm.caches import cache_home; "
            "print(cache_home()); print(os.environ['TLM_CACHE'])")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TLM_CACHE": "rel", "LATER": str(later)}
    done = subprocess.run([sys.executable, "-c", code], cwd=start, env=env, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [str(start / "rel"), str(start / "rel")]


# ---------------------------------------------------------------- 2. base= with a file


def test_base_given_with_a_file_or_a_config_is_refused_not_ignored(tmp_path):
    own, other = tmp_path / "own", tmp_path / "other"
    own.mkdir()
    other.mkdir()
    (own / "x.yaml").write_text("scene: cornell\nmode: rcast\nresolution: [8, 8]\n")
    (own / "box.yaml").write_text("extends: cornell\n")
    cfg = tlm.load_config(own / "x.yaml")
    for config, whose in ((own / "x.yaml", "the config file"), ("cornell", "the config file"),
                          (own / "box.yaml", "the scene file"), (cfg, "the Config's")):
        with pytest.raises(InputError) as e:  # (the old code: base ignored, the file's own folder used)
            tlm.load_config(config, base=other)
        assert e.value.key == "base" and str(e.value).startswith(f"base: {other}: {whose}"), str(e.value)
        assert "relative paths start at its own folder" in str(e.value) and "\n" not in str(e.value)
    # its own folder given: that is the folder used, nothing to refuse; a mapping's base: honoured
    assert tlm.load_config(own / "x.yaml", base=own).base == own
    assert tlm.load_config(cfg, base=own) is cfg
    assert tlm.load_config({"scene": "cornell"}, base=other).base == other


# ---------------------------------------------------------------- 3. the radius rules of error-vs-cost

BASE = {"scene": "cornell", "seed": 0, "resolution": [8, 8], "render": {"spp": 1}, "photons": {"count": 600},
        "reference": {"photons": 500, "k_nearest": 20, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 2,
                      "spp": 1}}
POINTS = [{"estimate.final_gather": [4, 0]},  # (density: the global map's under final gathering, the indirect's)
          {"estimate.final_gather": [0], "estimate.radius_fraction": [0.03], "estimate.caustic_radius": [0.5]},
          {"estimate.final_gather": [0], "photons.count": [2], "seed": [1]},  # (1 photon a map: the fallback)
          {"estimate.filter": ["knn"], "estimate.final_gather": [0]}]  # (no radius: no rule)


@pytest.mark.slow  # (a study)
def test_error_vs_cost_rows_say_the_rule_of_each_radius_as_results_json_does(tmp_path, cache):
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({"base": BASE, "points": POINTS}))
    rows = run_error_vs_cost(exp, tmp_path / "out", truth=Truth(spp=0))
    assert COLUMNS[-4:] == ("radius_rule", "caustic_radius_rule", "photons_weighted", "cut_share")  # (appended: the
    assert COLUMNS.index("simulate_seconds") == len(COLUMNS) - 5  # old ones keep their places)
    points = [{"estimate.final_gather": 4}, {"estimate.final_gather": 0},
              {"estimate.final_gather": 0, "estimate.radius_fraction": 0.03, "estimate.caustic_radius": 0.5},
              {"estimate.final_gather": 0, "photons.count": 2, "seed": 1},
              {"estimate.filter": "knn", "estimate.final_gather": 0}]
    seen = []
    for row, point in zip(rows, points, strict=True):
        cfg = config_from_dict({**apply_overrides(BASE, [f"{k}={json.dumps(v)}" for k, v in point.items()]),
                                "mode": "pmap"})
        frame = load_frame(cfg, tmp_path, str(exp))
        photons = pmap.trace_photon_map(frame).photons
        said = pmap.radii(frame, photons)  # (what a run's results.json records)
        gathered = pmap.gathered_maps(frame, photons)
        if cfg.estimate.filter == "knn":
            assert row["radius_rule"] is None and row["caustic_radius_rule"] is None, row
            continue
        indirect = "global_radius_rule" if "global" in gathered else "radius_rule"
        assert row["radius_rule"] == said[indirect], (point, row["radius_rule"], said)
        assert row["caustic_radius_rule"] == (said["caustic_radius_rule"] if "caustic" in gathered else None)
        seen.append((row["radius_rule"], row["caustic_radius_rule"]))
    assert seen[0][0] == seen[1][0] == "density" and seen[2] == ("fraction", "radius")
    assert seen[3] == ("fallback", "fallback"), seen  # (maps of one photon each: too small to measure)
    with open(tmp_path / "out" / "rows.csv", newline="") as fh:
        cells = list(csv.DictReader(fh))
    assert list(cells[0]) == list(COLUMNS)
    assert [c["radius_rule"] for c in cells] == [r["radius_rule"] or "" for r in rows]  # (none: an empty cell)
    assert cells[-1]["radius_rule"] == cells[-1]["caustic_radius_rule"] == ""


# ---------------------------------------------------------------- 4. a sweep point's one-off seconds


def test_a_sweep_points_one_off_counts_its_own_threads_spans_not_another_points(tmp_path, monkeypatch):
    """Two points in threads of one process (a Dask worker's): one imports a module for the first time
    (0.3 s) while the other's window is open; only the importer counts it (the old code: both did)."""
    name = "tlm_h232_slow_import"
    (tmp_path / f"{name}.py").write_text("import time\ntime.sleep(0.3)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, name, raising=False)
    opened, imported = threading.Event(), threading.Event()
    got: dict[str, float] = {}
    failed: list[BaseException] = []

    def quiet():
        try:
            with sweep_point._one_off_clock() as clock:
                t0 = time.perf_counter()
                opened.set()
                assert imported.wait(30)
                got["quiet"] = clock.within(t0, time.perf_counter())
        except BaseException as e:  # (said below, in the test's thread)
            failed.append(e)
            opened.set()

    def loud():
        try:
            with sweep_point._one_off_clock() as clock:
                assert opened.wait(30)
                t0 = time.perf_counter()
                __import__(name)
                t1 = time.perf_counter()
                imported.set()
                got["loud"] = clock.within(t0, t1)
        except BaseException as e:
            failed.append(e)
            imported.set()

    threads = [threading.Thread(target=quiet), threading.Thread(target=loud)]
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join(60)
    finally:
        sys.modules.pop(name, None)
    assert not failed, failed
    assert got["loud"] >= 0.25, got
    assert got["quiet"] < 0.05, got  # (the old code: about 0.3, the other point's import)
