"""One error per reference, and ``tlm sweep --reference`` deciding on a cached reference as ``tlm reference`` does.

* A run that computed its reference measured its error against the float64 mean it computed, every later run
  against the float32 ``reference.npy`` cached: two errors for one ``reference_sha256``. Every run measures
  against the image as stored (where the cache cannot take it, as it would be stored).
* ``tlm sweep --reference`` used any cached reference as it was, one that misses its tolerance too where the
  sweep's settings allow more rounds, and said nothing; it decides as ``tlm reference`` does (computes it again,
  or keeps it and says why).
* ``tlm sweep --reference`` on a sweep that runs no photon-map pass said nothing: one line says so.
"""

from __future__ import annotations

import json

import yaml

from tlm import api
from tlm.errors import EnvironmentFailure
from tlm.experiments import reference_cache
from tlm.experiments.reference_cache import cache_dir as reference_dir
from tlm.experiments.sweep import run_sweep

# (a tolerance no reference of a few rounds meets: each is cached NOT converged)
NEVER = {"photons": 1500, "k_nearest": 20, "min_rounds": 4, "spp": 2, "tolerance": 1e-9}
PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "photons": {"count": 1500},
        "render": {"light_samples": 1}, "estimate": {"final_gather": 0},
        "arch": {"frames": 1, "trace": False, "packet_size": 32}, "reference": {**NEVER, "max_rounds": 8}}


def test_the_run_that_computes_its_reference_measures_the_error_every_later_run_measures(tmp_path, cache):
    first = api.run(PMAP, tmp_path / "a", outputs="images", reference=True)["error"]
    later = api.run(PMAP, tmp_path / "b", outputs="images", reference=True)["error"]
    assert first["reference_seconds"] is not None and later["reference_seconds"] is None  # (computed, then read)
    assert first["reference_sha256"] == later["reference_sha256"]
    assert (first["rmse"], first["rel_mse"]) == (later["rmse"], later["rel_mse"])  # (was: 1e-9 apart)


def test_a_reference_the_cache_cannot_take_is_measured_as_it_would_be_stored(tmp_path, cache, monkeypatch):
    def refused(key, image, meta, root=None):
        raise EnvironmentFailure("cannot write into the cache (read-only)", source="cache")

    writes = reference_cache.save_reference
    monkeypatch.setattr(reference_cache, "save_reference", refused)
    uncached = api.run(PMAP, tmp_path / "a", outputs="images", reference=True)["error"]
    monkeypatch.setattr(reference_cache, "save_reference", writes)
    api.run(PMAP, tmp_path / "b", outputs="images", reference=True)  # (computes it again, and caches it)
    cached = api.run(PMAP, tmp_path / "c", outputs="images", reference=True)["error"]  # (reads it)
    assert cached["reference_seconds"] is None and uncached["reference_sha256"] == cached["reference_sha256"]
    assert (uncached["rmse"], uncached["rel_mse"]) == (cached["rmse"], cached["rel_mse"])  # (was: 1e-9 apart)


def _sweep(tmp_path, max_rounds: int, grid=None, base=None):
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(base or PMAP))
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": "base.yaml", "set": {"reference.max_rounds": max_rounds},
                                    "grid": grid or {"arch.pipelines": [1, 2]}}))
    return path, tmp_path / "o"


def _cache_reference(max_rounds: int) -> dict:
    """``tlm reference`` of PMAP with ``max_rounds``: the meta of the reference it caches (NOT converged)."""
    made = api.reference({**PMAP, "reference": {**NEVER, "max_rounds": max_rounds}})
    assert made.computed and not made.meets and made.meta["rounds"] == max_rounds
    return made.meta


def _points_errors(out) -> list[dict]:
    rows = [json.loads(r) for r in (out / "sweep.jsonl").read_text().splitlines()]
    return [json.loads((out / "points" / r["hash"] / "results.json").read_text())["error"] for r in rows]


def test_sweep_reference_computes_again_a_cached_one_that_misses_its_tolerance(tmp_path, cache, elsewhere):
    old = _cache_reference(4)
    path, out = _sweep(tmp_path, 8)  # (allows more rounds than the cached one has: tlm reference computes it again)
    lines: list[str] = []
    done = run_sweep(path, out, jobs=1, reference=True, say=lines.append)
    assert done.ok == 2
    [computing] = [ln for ln in lines if ln.startswith("sweep --reference: computing reference 1 of 1")]
    assert "(the cached one, 4 rounds" in computing and "is computed again)" in computing  # (was: nothing computed)
    assert any("is cached but does not meet tolerance 1e-09: computing it again" in ln for ln in lines)
    (key,) = [p.name for p in reference_dir().iterdir()]
    meta = json.loads((reference_dir() / key / "meta.json").read_text())
    assert meta["rounds"] == 8 and meta["npy"]["sha256"] != old["npy"]["sha256"]
    assert all(e["reference_rounds"] == 8 and e["reference_sha256"] == meta["npy"]["sha256"]
               for e in _points_errors(out))


def test_sweep_reference_says_why_it_keeps_a_cached_one_that_misses_its_tolerance(tmp_path, cache, elsewhere):
    old = _cache_reference(8)
    path, out = _sweep(tmp_path, 4)  # (fewer rounds than the cached one has: tlm reference keeps it)
    lines: list[str] = []
    done = run_sweep(path, out, jobs=1, reference=True, say=lines.append)
    assert done.ok == 2 and not any("computing" in ln for ln in lines)
    [kept] = [ln for ln in lines if ln.startswith("sweep --reference: reference")]  # (was: no line)
    assert "which 2 points of the sweep need, is cached with 8 rounds" in kept
    assert "reference.max_rounds 4 asks for fewer rounds than it has, so it is kept, not computed again" in kept
    assert "(raise reference.max_rounds above 8" in kept and " rounds would reach the tolerance" in kept  # (h473)
    assert kept.endswith(", or compute it again with 'tlm reference --force')")
    assert all(e["reference_sha256"] == old["npy"]["sha256"] for e in _points_errors(out))
    path, out = _sweep(tmp_path, 8)  # (the same stopping rule: computing again would repeat its rounds)
    lines.clear()
    run_sweep(path, out, jobs=1, reference=True, say=lines.append)
    [kept] = [ln for ln in lines if ln.startswith("sweep --reference: reference")]
    assert "computing it again would repeat the same rounds, so it is kept" in kept
    lines.clear()
    again = run_sweep(path, out, jobs=1, reference=True, say=lines.append)  # (all done against the one kept)
    assert again.skipped == 2 and lines == []


def test_sweep_reference_without_a_photon_map_pass_says_so(tmp_path, cache, elsewhere):
    path, out = _sweep(tmp_path, 8, base={**PMAP, "mode": "refract"})
    lines: list[str] = []
    done = run_sweep(path, out, jobs=1, reference=True, say=lines.append)
    assert done.ok == 2 and lines == []
    assert done.warnings == ["--reference: no point of this sweep runs the photon-map pass: no reference to "
                             "compute"]  # (was: no warning)
    assert not reference_dir().exists() or not any(reference_dir().iterdir())
