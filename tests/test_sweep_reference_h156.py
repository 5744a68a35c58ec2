"""A photon-map reference computed by the run itself, and a sweep that computes its references when asked.

* ``tlm run`` of a PMap config that computed its reference (none cached: ``reference.auto``) recorded
  ``error.reference_sha256: null``, so a sweep point measured so, or a rerun, could not tell that reference
  from one computed again under its key. It records the sha256 of the ``reference.npy`` it cached now (where
  the cache could not take it, that of the ``reference.npy`` it would have been: the same file as the one
  computed again with the same settings).
* A PMap sweep computed no reference: it said how many points have no error and the ``tlm reference``
  command. ``tlm sweep --reference`` (``run_sweep(reference=True)``) computes, before the points, each
  distinct reference they need that is not cached, with ``tlm reference``'s lines, so that they are measured
  in the same run; a failed or interrupted reference loses no point done, and a rerun reuses the cached ones.
"""

from __future__ import annotations

import json

import pytest
import yaml

from tlm import api
from tlm.cli import main
from tlm.config import config_from_dict
from tlm.errors import EnvironmentFailure, InputError
from tlm.experiments import reference as reference_module
from tlm.experiments import reference_cache, run
from tlm.experiments.reference_cache import cache_dir as reference_dir
from tlm.experiments.sweep import run_sweep

SMALL_REFERENCE = {"photons": 1500, "k_nearest": 20, "max_rounds": 8, "min_rounds": 4, "spp": 2}
PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "photons": {"count": 1500},
        "render": {"light_samples": 1}, "estimate": {"final_gather": 0},
        "arch": {"frames": 1, "trace": False, "packet_size": 32}, "reference": SMALL_REFERENCE}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _cached_sha(key: str) -> str:
    return json.loads((reference_dir() / key / "meta.json").read_text())["npy"]["sha256"]


def test_a_run_that_computes_its_reference_records_the_sha256_of_the_one_it_cached(tmp_path):
    first = api.run(PMAP, tmp_path / "a", outputs="images", reference=True)
    error = first["error"]
    assert error["available"] is True and error["reference_seconds"] is not None  # (computed by this run)
    assert error["reference_sha256"] == _cached_sha(error["reference"])  # (was: None)
    again = api.run(PMAP, tmp_path / "b", outputs="images", reference=True)  # (found in the cache: as before)
    assert again["error"]["reference_seconds"] is None
    assert again["error"]["reference_sha256"] == error["reference_sha256"]


def test_a_run_whose_reference_the_cache_cannot_take_records_the_sha256_it_would_have_had(tmp_path, monkeypatch):
    def refused(key, image, meta, root=None):
        raise EnvironmentFailure("cannot write into the cache (read-only)", source="cache")

    writes = reference_cache.save_reference
    monkeypatch.setattr(reference_cache, "save_reference", refused)
    uncached = api.run(PMAP, tmp_path / "a", outputs="images", reference=True)["error"]
    assert uncached["available"] is True and not (reference_dir() / uncached["reference"]).exists()
    monkeypatch.setattr(reference_cache, "save_reference", writes)  # (not undo(): TLM_CACHE stays the test's)
    cached = api.run(PMAP, tmp_path / "b", outputs="images", reference=True)["error"]  # (computed again, cached)
    assert cached["reference_seconds"] is not None
    assert uncached["reference_sha256"] == cached["reference_sha256"] == _cached_sha(cached["reference"])  # (was None)
    assert uncached["rmse"] == cached["rmse"]


def _sweep(tmp_path, grid=None):
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(PMAP))
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": "base.yaml", "grid": grid or {"arch.pipelines": [1, 2]}}))
    return path, tmp_path / "o"


def _fresh(config: dict) -> dict:
    """The error ``tlm run`` of ``config`` measures against the reference cached now."""
    res = run.render(config_from_dict(config, "test"))
    return run.photon_error(res.frame, res.radiance["pmap"].reshape(-1, 3))


def _unmeasured(outcome) -> list[str]:
    return [w for w in outcome.warnings if "no photon-map error" in w]


def test_a_sweep_with_reference_computes_each_distinct_reference_before_its_points(tmp_path, elsewhere):
    path, out = _sweep(tmp_path, {"arch.pipelines": [1, 2], "reference.k_nearest": [20, 30]})
    lines: list[str] = []
    done = run_sweep(path, out, jobs=1, reference=True, say=lines.append)
    assert done.ok == 4 and not _unmeasured(done)
    computing = [ln for ln in lines if ln.startswith("sweep --reference: computing reference")]
    assert len(computing) == 2 and all("which 2 points of the sweep need" in ln for ln in computing)  # (by its key)
    assert any(ln.startswith("  round ") and "relative standard error" in ln for ln in lines)  # (tlm reference's)
    assert len(list(reference_dir().iterdir())) == 2
    for row in done.rows:
        k = row["reference.k_nearest"]
        fresh = _fresh({**PMAP, "reference": {**SMALL_REFERENCE, "k_nearest": k}})
        error = json.loads((out / "points" / row["hash"] / "results.json").read_text())["error"]
        assert row["error.rmse"] == error["rmse"] == fresh["rmse"]
        assert error["reference_sha256"] == fresh["reference_sha256"] == _cached_sha(error["reference"])
    lines.clear()
    again = run_sweep(path, out, jobs=1, reference=True, say=lines.append)  # (all done, all measured: nothing)
    assert again.skipped == 4 and lines == []


def test_a_sweep_without_reference_says_the_flag_and_a_rerun_with_it_measures_the_points_done(tmp_path, elsewhere):
    path, out = _sweep(tmp_path)
    first = run_sweep(path, out, jobs=1)
    assert first.ok == 2 and not (reference_dir().exists() and any(reference_dir().iterdir()))  # (as before)
    [line] = _unmeasured(first)
    assert line.endswith("from their cached frames ('tlm sweep --reference' computes this reference before the "
                         "points, and measures them)")
    lines: list[str] = []
    again = run_sweep(path, out, jobs=1, reference=True, say=lines.append)
    assert again.skipped == 0 and again.renders == 0  # (measured from their cached frames)
    assert not _unmeasured(again) and len([ln for ln in lines if "computing reference" in ln]) == 1
    assert all(r["error.rmse"] == _fresh(PMAP)["rmse"] for r in again.rows)


def test_a_reference_that_fails_loses_no_point_and_says_so(tmp_path, elsewhere, monkeypatch):
    path, out = _sweep(tmp_path)

    def fails(*args, **kwargs):
        raise InputError("reference.photons = 1500 needs more memory than there is", key="reference.photons")

    monkeypatch.setattr(reference_module, "make_reference", fails)
    warned: list[str] = []
    done = run_sweep(path, out, jobs=1, reference=True, warn=warned.append)
    assert done.ok == 2 and all(r["status"] == "ok" and "error.rmse" not in r for r in done.rows)
    [failed] = [w for w in warned if w.startswith("sweep --reference: the photon-map reference")]
    assert "could not be computed (InputError: reference.photons" in failed and "they run without" in failed
    [line] = _unmeasured(done)
    assert "though --reference was given (a line above says why" in line  # (was: "a sweep computes none")
    assert "'tlm sweep --reference' computes" not in line  # (asked for already)


def test_an_interrupted_reference_keeps_the_points_done_and_a_rerun_reuses_the_cached_ones(tmp_path, elsewhere,
                                                                                          monkeypatch):
    path, out = _sweep(tmp_path, {"reference.k_nearest": [20, 30]})
    first = run_sweep(path, out, jobs=1)  # (done, without their error)
    assert first.ok == 2
    made = reference_module.make_reference
    calls: list[int] = []

    def second_interrupted(cfg, *args, **kwargs):
        calls.append(cfg.reference.k_nearest)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return made(cfg, *args, **kwargs)

    monkeypatch.setattr(reference_module, "make_reference", second_interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(path, out, jobs=1, reference=True)
    assert len(list(reference_dir().iterdir())) == 1  # (the first one cached)
    rows = [json.loads(r) for r in (out / "sweep.jsonl").read_text().splitlines()]
    assert len(rows) == 2 and all(r["status"] == "ok" for r in rows)  # (the points done stay)
    assert all((out / "points" / r["hash"] / "results.json").is_file() for r in rows)
    calls.clear()
    again = run_sweep(path, out, jobs=1, reference=True)
    assert calls == [30] and again.ok == 2 and not _unmeasured(again)  # (the cached one reused)


def test_tlm_sweep_reference_on_the_command_line(tmp_path, elsewhere, capsys):
    path, out = _sweep(tmp_path)
    assert main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--reference", "--no-progress",
                 "--no-report"]) == 0
    captured = capsys.readouterr()
    assert "sweep --reference: computing reference 1 of 1" in captured.out and "  round " in captured.out
    assert "no photon-map error" not in captured.err
    rows = [json.loads(r) for r in (out / "sweep.jsonl").read_text().splitlines()]
    assert all(isinstance(r["error.rmse"], float) for r in rows)
