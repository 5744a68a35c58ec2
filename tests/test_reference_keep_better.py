"""A reference computed now never replaces a better cached one of the same key.

``tlm reference --set reference.max_rounds=8``, with a 128-round reference cached for the
same key (not converged), computed 8 rounds and overwrote the cache: every later run measured
its error against the worse one. Now a cached one that misses the tolerance with more rounds
than ``reference.max_rounds`` is kept without computing, and one computed now replaces the
cached one only where it is better (it meets the tolerance and the cached one does not, or
neither does and its relative standard error is lower), or with ``--force``; ``tlm
error-vs-cost`` finds its reference the same way.
"""

from __future__ import annotations

import json
import os
import tempfile

import numpy as np
import pytest

from tlm.cli import main
from tlm.experiments import error_cost, reference

# a reference far short of its tolerance: 4 rounds of one ray each, not converged (exit status 1)
SHORT = {"photons": 500, "k_nearest": 20, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 4, "spp": 1}
PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "render": {"spp": 1}, "photons": {"count": 500}}


def _config(tmp_path, ref: dict):
    path = tmp_path / "cfg.json"
    path.write_text(json.dumps({**PMAP, "reference": ref}))
    return str(path)


def _held(cache) -> tuple[dict, np.ndarray]:
    (folder,) = (cache / "references").iterdir()
    return json.loads((folder / "meta.json").read_text()), np.load(folder / "reference.npy")


def _cached(tmp_path, cache, capsys) -> tuple[dict, np.ndarray]:
    """The 4-round reference ``tlm reference`` caches, not converged."""
    assert main(["reference", _config(tmp_path, SHORT), "--no-progress"]) == 1
    capsys.readouterr()
    meta, image = _held(cache)
    assert meta["rounds"] == 4 and meta["converged"] is False
    return meta, image


def _worse_by(monkeypatch, module, factor: float, converged: bool = False) -> None:
    """``module``'s ``compute_reference`` as it is, but for its relative standard error
    (times ``factor``) and whether it converged."""
    real = reference.compute_reference

    def compute(*a, **k):
        image, meta = real(*a, **k)
        return image, {**meta, "relative_standard_error": meta["relative_standard_error"] * factor,
                       "converged": converged}

    monkeypatch.setattr(module, "compute_reference", compute)


def test_fewer_rounds_than_the_cached_reference_keep_it_without_computing(tmp_path, cache, capsys, monkeypatch):
    """As do the same reference settings again (the same rounds, seeded alike)."""
    old, image = _cached(tmp_path, cache, capsys)
    monkeypatch.setattr(reference, "compute_reference", lambda *a, **k: pytest.fail("computed fewer rounds"))
    cfg = _config(tmp_path, {**SHORT, "max_rounds": 2})  # (the same key: the stopping rule is not in it)
    assert main(["reference", cfg, "--no-progress"]) == 1  # (the reference returned is not converged)
    out = capsys.readouterr().out
    said = [line for line in out.splitlines() if "asks for fewer rounds" in line]
    assert len(said) == 1 and f"reference {old['key']} is cached with 4 rounds, relative standard error " in said[0]
    assert "reference.max_rounds 2 asks for fewer rounds than it has, so it is kept" in said[0]
    assert "NOT converged (max_rounds reached) after 4 rounds" in out
    meta, now = _held(cache)
    assert meta == old
    np.testing.assert_array_equal(now, image)

    assert main(["reference", _config(tmp_path, SHORT), "--no-progress"]) == 1  # (its own rule: the same rounds)
    assert "computing it again would repeat the same rounds, so it is kept" in capsys.readouterr().out
    assert _held(cache)[0] == old


def test_a_worse_reference_computed_now_does_not_replace_the_cached_one(tmp_path, cache, capsys, monkeypatch):
    """Computed with more rounds but a higher standard error: the cache keeps its own, says so
    with both errors, and the one computed now is kept in the temporary folder; a better one
    replaces it, and ``--force`` replaces it whatever it is."""
    old, image = _cached(tmp_path, cache, capsys)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    kept = tmp_path / "tmp" / f"tlm-cache-{os.getuid()}" / "references" / old["key"]
    cfg = _config(tmp_path, {**SHORT, "max_rounds": 6})
    _worse_by(monkeypatch, reference, 100.0)
    assert main(["reference", cfg, "--no-progress"]) == 1
    out = capsys.readouterr().out
    said = [line for line in out.splitlines() if "the cache keeps its reference" in line]
    e_old = old["relative_standard_error"]
    assert len(said) == 1 and f"(4 rounds, relative standard error {e_old:.4f}, NOT converged" in said[0]
    assert "not the one computed now (6 rounds, relative standard error " in said[0]
    assert "its relative standard error is lower" in said[0] and f"kept in {kept} " in said[0]
    meta, now = _held(cache)
    assert meta == old
    np.testing.assert_array_equal(now, image)
    assert json.loads((kept / "meta.json").read_text())["rounds"] == 6

    _worse_by(monkeypatch, reference, 1e-3)  # (better, and neither meets the tolerance: it replaces)
    assert main(["reference", cfg, "--no-progress"]) == 1
    assert "the cache keeps" not in capsys.readouterr().out
    assert _held(cache)[0]["rounds"] == 6

    _worse_by(monkeypatch, reference, 1e6)  # (--force: computed and cached whatever it is)
    assert main(["reference", _config(tmp_path, SHORT), "--no-progress", "--force"]) == 1
    assert "the cache keeps" not in capsys.readouterr().out
    assert _held(cache)[0]["rounds"] == 4


def test_one_that_meets_the_tolerance_replaces_one_that_does_not(tmp_path, cache, capsys, monkeypatch):
    """Met with a higher error: it replaces the cached one; then a converged one is not replaced by
    another (``tlm run`` computing while another process cached one: the cached one is used)."""
    from tlm import api
    from tlm.experiments.loading import load_frame

    old, _ = _cached(tmp_path, cache, capsys)
    _worse_by(monkeypatch, reference, 2.0, converged=True)
    cfg = _config(tmp_path, {**SHORT, "tolerance": 1e6, "max_rounds": 6})
    assert main(["reference", cfg, "--no-progress"]) == 0
    meta, image = _held(cache)
    assert meta["rounds"] == 2 and meta["converged"] is True  # (fewer rounds, a higher error: it met the tolerance)

    real = reference.compute_reference

    def meanwhile(*a, **k):  # (another process caches a converged one while this one computes)
        got = real(*a, **k)
        reference.save_reference(old["key"], image * 1.5, {**meta, "relative_standard_error": 1e-3})
        return got

    monkeypatch.setattr(reference, "compute_reference", meanwhile)
    (cache / "references" / old["key"]).rename(tmp_path / "held")
    lines: list[str] = []
    frame = load_frame(api.load_config({**PMAP, "reference": {**SHORT, "tolerance": 1e6}}).settings)
    found = reference.ensure_reference(frame, compute=True, say=lines.append)
    assert found.meta["relative_standard_error"] == 1e-3 and "this run uses the cached one" in lines[-1]
    np.testing.assert_array_equal(found.image, (image * 1.5).reshape(-1, 3))
    assert _held(cache)[0]["relative_standard_error"] == 1e-3


def test_error_vs_cost_keeps_the_better_cached_reference(tmp_path, cache, capsys, monkeypatch):
    """The study finds its reference as ``tlm reference`` does: fewer rounds keep the cached one
    without computing; a worse one computed now is not cached, and the study uses the cached one."""
    old, image = _cached(tmp_path, cache, capsys)

    def study(ref: dict, out: str) -> dict:
        exp = tmp_path / "evc.json"
        exp.write_text(json.dumps({"base": {**PMAP, "reference": ref, "estimate": {"final_gather": 0}},
                                   "points": [{"estimate.filter": ["knn"]}]}))
        assert main(["error-vs-cost", str(exp), "--out", str(tmp_path / out), "--truth-spp", "0",
                     "--no-report"]) == 0
        return json.loads((tmp_path / out / "reference.json").read_text())

    monkeypatch.setattr(error_cost, "compute_reference", lambda *a, **k: pytest.fail("computed fewer rounds"))
    got = study({**SHORT, "tolerance": 1e-5, "max_rounds": 2}, "fewer")
    assert got["rounds"] == 4 and got["computed"] is False and got["reference_converged"] is False
    assert "asks for fewer rounds than it has, so it is kept" in capsys.readouterr().out
    assert _held(cache)[0] == old

    _worse_by(monkeypatch, error_cost, 100.0)
    got = study({**SHORT, "tolerance": 1e-5, "max_rounds": 6}, "worse")
    assert got["rounds"] == 4 and got["computed"] is False
    out = capsys.readouterr().out
    assert "the cache keeps its reference (4 rounds" in out and "the study uses the cached one" in out
    meta, now = _held(cache)
    assert meta == old
    np.testing.assert_array_equal(now, image)
