"""``tlm sweep --reference`` holds the references it computed (or chose) for its points.

It computed a reference its cache could not take (read-only, full, ``references/<key>`` a file), said it was
kept in ``<tmp>/tlm-cache-<uid>``, and then measured no point (``error.available: false``): the points read the
cache only. A ``tlm cache prune``/``clear`` between the reference phase and the points cost them their error
too. The sweep now holds a copy of each reference its points are measured against in its output folder for its
duration (``.references``), which the points read first. And two equal references computed at once: the second
said the cache "keeps its reference, not the one computed now" and left a copy in the temporary folder; an equal
one is dropped, and the line says it is the same.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile

import numpy as np
import pytest
import yaml

from tlm.experiments import sweep_point
from tlm.experiments.reference_cache import ReferenceSettings, kept_root, store_reference
from tlm.experiments.reference_cache import cache_dir as reference_dir
from tlm.experiments.sweep import run_sweep

REFERENCE = {"photons": 1500, "k_nearest": 20, "min_rounds": 4, "max_rounds": 4, "spp": 2}
PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "photons": {"count": 1500},
        "render": {"light_samples": 1}, "estimate": {"final_gather": 0},
        "arch": {"frames": 1, "trace": False, "packet_size": 32}, "reference": REFERENCE}


@pytest.fixture
def own_tmp(tmp_path, monkeypatch):
    """The temporary folder (kept_root's parent) of the test's own."""
    folder = tmp_path / "tmp"
    folder.mkdir(mode=0o700)
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


def _sweep(tmp_path):
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(PMAP))
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": "base.yaml", "grid": {"estimate.filter": ["disk", "mvoxel"]}}))
    return path, tmp_path / "s-out"


def _errors(out, done) -> list[dict]:
    return [json.loads((out / "points" / r["hash"] / "results.json").read_text())["error"] for r in done.rows]


@pytest.mark.parametrize("kept", [True, False])
def test_a_reference_the_cache_cannot_take_still_measures_the_points(tmp_path, monkeypatch, elsewhere, own_tmp, kept):
    blocker = tmp_path / "afile"  # (TLM_CACHE a file: no cache folder can be made)
    blocker.write_text("x\n")
    monkeypatch.setenv("TLM_CACHE", str(blocker))
    if not kept:  # (the temporary folder cannot take it either: kept nowhere but by the sweep)
        shutil.rmtree(own_tmp)
        own_tmp.write_text("x\n")
    path, out = _sweep(tmp_path)
    lines: list[str] = []
    warned: list[str] = []
    done = run_sweep(path, out, jobs=1, reference=True, say=lines.append, warn=warned.append)
    assert done.ok == 2
    errors = _errors(out, done)
    assert all(e["available"] is True for e in errors)  # (was: False, no point measured)
    assert not any("have no photon-map error" in w for w in warned)
    key = errors[0]["reference"]
    if kept:
        meta = json.loads((kept_root() / "references" / key / "meta.json").read_text())
        assert {e["reference_sha256"] for e in errors} == {meta["npy"]["sha256"]}
        assert any(ln.startswith(f"reference {key}: NOT converged") and ln.endswith(key) for ln in lines)
    else:
        assert any(ln.endswith("kept nowhere but for this sweep") for ln in lines)
    assert not (out / ".references").exists()  # (the sweep's own copies: gone with the sweep)


def test_a_prune_while_the_sweep_runs_costs_no_point_its_error(tmp_path, monkeypatch, cache, elsewhere):
    real = sweep_point.cached_render

    def pruned(*args, **kwargs):  # ('tlm cache prune --max-size 0' or 'tlm cache clear' just before the point)
        shutil.rmtree(reference_dir(), ignore_errors=True)
        return real(*args, **kwargs)

    monkeypatch.setattr(sweep_point, "cached_render", pruned)
    path, out = _sweep(tmp_path)
    warned: list[str] = []
    done = run_sweep(path, out, jobs=1, reference=True, warn=warned.append)
    assert done.ok == 2
    errors = _errors(out, done)
    assert all(e["available"] is True for e in errors)  # (was: False, "a line above says why", none did)
    assert len({e["reference_sha256"] for e in errors}) == 1 and errors[0]["reference_sha256"]
    assert not any("have no photon-map error" in w for w in warned)
    assert not (out / ".references").exists()
    assert not reference_dir().exists()  # (pruned: the points read the sweep's own copy)


def test_an_equal_reference_computed_at_once_is_dropped_and_said_the_same(tmp_path, cache, own_tmp):
    settings = ReferenceSettings(photons=100, tolerance=0.02, min_rounds=4, max_rounds=8, spp=4)
    image = np.random.default_rng(0).random((4, 5, 3))
    meta = {"rounds": 8, "relative_standard_error": 0.17, "cycles": 2, "rounds_per_cycle": 4,
            "standard_error_per_cycle": [0.17], "tolerance": 0.02, "min_rounds": 4, "max_rounds": 8, "spp": 4,
            "converged": False}
    first = store_reference("k" * 20, image, meta, settings)
    assert first.replaced
    second = store_reference("k" * 20, image, dict(meta, host_seconds=1.5), settings)  # (the other sweep's)
    assert not second.replaced
    assert "kept in" not in second.line  # (was: "the one computed now is kept in <tmp>/tlm-cache-<uid>/...")
    assert not os.path.exists(kept_root())
    assert "the same reference as the one computed now" in second.line and "dropped" in second.line
    assert second.same
    assert second.meta["npy"] == first.meta["npy"]
