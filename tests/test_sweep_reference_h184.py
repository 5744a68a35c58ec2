"""``tlm sweep --reference`` on points that share one reference but ask for different stopping rules.

A reference's tolerance, rounds and ``spp`` are no part of its key, so points that differ in them share one
reference. ``sweep --reference`` computed (or judged a cached one) with the first such point's settings only:
a point asking for a stricter tolerance was measured against a reference that misses it (``reference_converged``
false) though its ``max_rounds`` allowed more, and a rerun did not mend it. It computes and judges the shared
reference by the strictest of its points' settings (the lowest tolerance, the most rounds), and its lines say so
and which of the points' own tolerances it meets.
"""

from __future__ import annotations

import json

import pytest
import yaml

from tlm.errors import InputError
from tlm.experiments import reference as reference_module
from tlm.experiments.reference_cache import cache_dir as reference_dir
from tlm.experiments.sweep import run_sweep

# (at 8 x 8 pixels: tolerance 0.5 is met after 4 rounds, 0.2 after some 12, within max_rounds)
REFERENCE = {"photons": 1500, "k_nearest": 20, "min_rounds": 4, "max_rounds": 64, "spp": 2}
PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "photons": {"count": 1500},
        "render": {"light_samples": 1}, "estimate": {"final_gather": 0},
        "arch": {"frames": 1, "trace": False, "packet_size": 32}, "reference": REFERENCE}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _sweep(tmp_path, grid: dict, name: str = "s"):
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(PMAP))
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump({"base": "base.yaml", "grid": grid}))
    return path, tmp_path / f"{name}-out"


def _errors(out, done) -> list[dict]:
    return [json.loads((out / "points" / r["hash"] / "results.json").read_text())["error"] for r in done.rows]


def _cached_meta(key: str) -> dict:
    return json.loads((reference_dir() / key / "meta.json").read_text())


def test_points_sharing_a_reference_get_the_strictest_tolerance_any_of_them_asks_for(tmp_path, elsewhere):
    # (reference.spp is not in the key either: four points, one reference, computed once)
    path, out = _sweep(tmp_path, {"reference.tolerance": [0.5, 0.2], "reference.spp": [2, 4]})
    lines: list[str] = []
    done = run_sweep(path, out, jobs=1, reference=True, say=lines.append)
    assert done.ok == 4
    errors = _errors(out, done)
    assert len({e["reference"] for e in errors}) == 1 and len(list(reference_dir().iterdir())) == 1
    key = errors[0]["reference"]
    assert all(e["reference_converged"] is True for e in errors)  # (was: false for the points asking 0.2)
    assert _cached_meta(key)["tolerance"] == 0.2  # (was: 0.5, the first point's)
    [computing] = [ln for ln in lines if ln.startswith("sweep --reference: computing reference")]
    assert "computing reference 1 of 1" in computing and "which 4 points of the sweep need" in computing
    assert "tolerance 0.2, 0.5" in computing and "the strictest, tolerance 0.2, 4 to 64 rounds" in computing
    [made] = [ln for ln in lines if ln.startswith(f"reference {key}: converged after")]
    assert made.endswith("against its points' own tolerances it meets 0.2 (2 points) and 0.5 (2 points)")
    lines.clear()
    again = run_sweep(path, out, jobs=1, reference=True, say=lines.append)
    assert again.skipped == 4 and lines == []


def test_a_cached_reference_that_meets_only_the_looser_tolerance_is_computed_again(tmp_path, elsewhere):
    loose, loose_out = _sweep(tmp_path, {"reference.tolerance": [0.5]}, "loose")
    first = run_sweep(loose, loose_out, jobs=1, reference=True)
    [key] = {e["reference"] for e in _errors(loose_out, first)}
    assert _cached_meta(key)["rounds"] == 4  # (met 0.5, misses 0.2)
    path, out = _sweep(tmp_path, {"reference.tolerance": [0.5, 0.2]})
    lines: list[str] = []
    done = run_sweep(path, out, jobs=1, reference=True, say=lines.append)
    [computing] = [ln for ln in lines if ln.startswith("sweep --reference: computing reference")]  # (was: none)
    assert "NOT converged at tolerance 0.2, is computed again" in computing
    assert all(e["reference_converged"] is True for e in _errors(out, done))
    assert _cached_meta(key)["rounds"] > 4


def test_a_failed_reference_stops_no_other_and_each_is_named_once(tmp_path, elsewhere, monkeypatch):
    path, out = _sweep(tmp_path, {"reference.k_nearest": [20, 30], "reference.tolerance": [0.5, 0.2]})
    made = reference_module.make_reference
    asked: list[tuple[int, float]] = []

    def k20_fails(cfg, *args, **kwargs):
        asked.append((cfg.reference.k_nearest, cfg.reference.tolerance))
        if cfg.reference.k_nearest == 20:
            raise InputError("reference.photons = 1500 needs more memory than there is", key="reference.photons")
        return made(cfg, *args, **kwargs)

    monkeypatch.setattr(reference_module, "make_reference", k20_fails)
    lines: list[str] = []
    warned: list[str] = []
    done = run_sweep(path, out, jobs=1, reference=True, say=lines.append, warn=warned.append)
    assert done.ok == 4 and sorted(asked) == [(20, 0.2), (30, 0.2)]  # (each once, to the strictest; was: 0.5)
    by_k = {r["reference.k_nearest"]: [] for r in done.rows}
    for row, error in zip(done.rows, _errors(out, done), strict=True):
        by_k[row["reference.k_nearest"]].append(error)
    assert all(e["available"] is True and e["reference_converged"] is True for e in by_k[30])
    assert all(e["available"] is False for e in by_k[20])
    keys = {k: {e["reference"] for e in errors} for k, errors in by_k.items()}
    assert all(len(v) == 1 for v in keys.values())
    (k20,), (k30,) = keys[20], keys[30]
    computing = [ln for ln in lines if ln.startswith("sweep --reference: computing reference")]
    assert [sum(k in ln for ln in computing) for k in (k20, k30)] == [1, 1]
    [failed] = [w for w in warned if w.startswith("sweep --reference: the photon-map reference")]
    assert k20 in failed and "of 2 points could not be computed" in failed and k30 not in failed
    [unmeasured] = [w for w in done.warnings if "no photon-map error" in w]
    assert unmeasured.count("tlm reference ") == 1  # (one command, for the one reference that failed)
    assert "--set reference.tolerance=0.2" in unmeasured and "reference.tolerance=0.5" not in unmeasured
