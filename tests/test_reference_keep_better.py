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

from tests.helpers_reference import held_reference
from tlm.cli import main
from tlm.experiments import error_cost, reference, reference_cache

# a reference far short of its tolerance: 4 rounds of one ray each, not converged (exit status 1)
SHORT = {"photons": 500, "k_nearest": 20, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 4, "spp": 1}
PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "render": {"spp": 1}, "photons": {"count": 500}}


def _config(tmp_path, ref: dict):
    path = tmp_path / "cfg.json"
    path.write_text(json.dumps({**PMAP, "reference": ref}))
    return str(path)


def _cached(tmp_path, cache, capsys) -> tuple[dict, np.ndarray]:
    """The 4-round reference ``tlm reference`` caches, not converged."""
    assert main(["reference", _config(tmp_path, SHORT), "--no-progress"]) == 1
    capsys.readouterr()
    meta, image = held_reference(cache)
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
    meta, now = held_reference(cache)
    assert meta == old
    np.testing.assert_array_equal(now, image)

    assert main(["reference", _config(tmp_path, SHORT), "--no-progress"]) == 1  # (its own rule: the same rounds)
    assert "computing it again would repeat the same rounds, so it is kept" in capsys.readouterr().out
    assert held_reference(cache)[0] == old


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
    meta, now = held_reference(cache)
    assert meta == old
    np.testing.assert_array_equal(now, image)
    assert json.loads((kept / "meta.json").read_text())["rounds"] == 6

    _worse_by(monkeypatch, reference, 1e-3)  # (better, and neither meets the tolerance: it replaces)
    assert main(["reference", cfg, "--no-progress"]) == 1
    assert "the cache keeps" not in capsys.readouterr().out
    assert held_reference(cache)[0]["rounds"] == 6

    _worse_by(monkeypatch, reference, 1e6)  # (--force: computed and cached whatever it is)
    assert main(["reference", _config(tmp_path, SHORT), "--no-progress", "--force"]) == 1
    assert "the cache keeps" not in capsys.readouterr().out
    assert held_reference(cache)[0]["rounds"] == 4


def test_one_that_meets_the_tolerance_replaces_one_that_does_not(tmp_path, cache, capsys, monkeypatch):
    """Met with a higher error: it replaces the cached one (4 rounds, short of ``min_rounds`` 6); then
    a converged one is not replaced by another (``tlm run`` computing while another process cached
    one: the cached one is used)."""
    from tlm import api
    from tlm.experiments.loading import load_frame

    old, _ = _cached(tmp_path, cache, capsys)
    _worse_by(monkeypatch, reference, 2.0, converged=True)
    cfg = _config(tmp_path, {**SHORT, "tolerance": 1e6, "min_rounds": 6, "max_rounds": 6})
    assert main(["reference", cfg, "--no-progress"]) == 0
    meta, image = held_reference(cache)
    assert meta["rounds"] == 6  # (a higher error, but it meets the rule asked for, and the cached one does not)
    assert meta["relative_standard_error"] > old["relative_standard_error"]

    real = reference.compute_reference

    def meanwhile(*a, **k):  # (another process caches a converged one while this one computes)
        got = real(*a, **k)
        reference_cache.save_reference(old["key"], image * 1.5, {**meta, "relative_standard_error": 1e-3})
        return got

    monkeypatch.setattr(reference, "compute_reference", meanwhile)
    (cache / "references" / old["key"]).rename(tmp_path / "held")
    lines: list[str] = []
    frame = load_frame(api.load_config({**PMAP, "reference": {**SHORT, "tolerance": 1e6}}).settings)
    found = reference.ensure_reference(frame, compute=True, say=lines.append)
    assert found.meta["relative_standard_error"] == 1e-3 and "this run uses the cached one" in lines[-1]
    np.testing.assert_array_equal(found.image, (image * 1.5).reshape(-1, 3))
    assert held_reference(cache)[0]["relative_standard_error"] == 1e-3


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
    assert held_reference(cache)[0] == old

    _worse_by(monkeypatch, error_cost, 100.0)
    got = study({**SHORT, "tolerance": 1e-5, "max_rounds": 6}, "worse")
    assert got["rounds"] == 4 and got["computed"] is False
    out = capsys.readouterr().out
    assert "the cache keeps its reference (4 rounds" in out and "the study uses the cached one" in out
    meta, now = held_reference(cache)
    assert meta == old
    np.testing.assert_array_equal(now, image)


def test_the_tolerance_is_judged_as_asked_for_now_not_by_the_stored_flag():
    """:func:`~tlm.experiments.reference_cache.meets_tolerance` is the stopping rule of the settings
    asked for now (error below ``tolerance``, at least ``min_rounds`` rounds), not the
    ``converged`` flag of the run that computed the reference: a 12-round reference that missed
    tolerance 0.0001 (error 0.08) is better at tolerance 0.5 than an 8-round one that met it
    (error 0.12), which replaced it before."""
    loose = reference_cache.ReferenceSettings(photons=3000, tolerance=0.5, min_rounds=2, max_rounds=12)
    strict = {"relative_standard_error": 0.0817, "rounds": 12, "cycles": 3, "converged": False}
    met = {"relative_standard_error": 0.1233, "rounds": 8, "cycles": 2, "converged": True}
    assert reference_cache.meets_tolerance(strict, loose) and reference_cache.meets_tolerance(met, loose)
    assert not reference_cache.better(met, strict, loose)
    assert "0.0817, converged at tolerance 0.5" in reference_cache.describe(strict, loose)
    short = {**met, "relative_standard_error": 0.01, "rounds": 2}  # (converged with min_rounds 2: asked for 4)
    assert not reference_cache.meets_tolerance(short, reference_cache.ReferenceSettings(photons=3000, tolerance=0.5))
    assert not reference_cache.meets_tolerance({**met, "relative_standard_error": 0.5}, loose)  # (the rule stops below)


def test_a_cached_reference_within_a_looser_tolerance_is_used(tmp_path, cache, capsys, monkeypatch):
    """A cached reference that missed its own tolerance but meets the looser one asked for now is
    used as it is, by ``tlm reference`` (exit 0) and ``tlm error-vs-cost`` (rows converged);
    before, both computed another, which replaced it though its error was higher."""
    old, image = _cached(tmp_path, cache, capsys)
    loose = {**SHORT, "tolerance": round(old["relative_standard_error"] * 1.5, 4), "max_rounds": 8}
    monkeypatch.setattr(reference, "compute_reference", lambda *a, **k: pytest.fail("computed it again"))
    monkeypatch.setattr(error_cost, "compute_reference", lambda *a, **k: pytest.fail("computed it again"))
    assert main(["reference", _config(tmp_path, loose), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert (f"reference {old['key']} is cached, relative standard error {old['relative_standard_error']:.4f} "
            f"< tolerance {loose['tolerance']} after {old['rounds']} rounds") in out
    meta, now = held_reference(cache)
    assert meta == old
    np.testing.assert_array_equal(now, image)

    exp = tmp_path / "evc.json"
    exp.write_text(json.dumps({"base": {**PMAP, "reference": loose, "estimate": {"final_gather": 0}},
                               "points": [{"estimate.filter": ["knn"]}]}))
    assert main(["error-vs-cost", str(exp), "--out", str(tmp_path / "evc"), "--truth-spp", "0", "--no-report"]) == 0
    assert "NOT converged" not in capsys.readouterr().err
    got = json.loads((tmp_path / "evc" / "reference.json").read_text())
    assert got["rounds"] == 4 and got["computed"] is False and got["reference_converged"] is True
    assert held_reference(cache)[0] == old


def test_a_kept_reference_is_said_against_the_tolerance_asked_for_now(tmp_path, cache, capsys):
    """A reference cached at a loose tolerance (converged there), kept by a stricter ``tlm
    reference`` that asks for no more rounds: the command says it is NOT converged at the
    tolerance asked for and exits 1 (it said "converged", exit 0, from the stored flag)."""
    loose = {**SHORT, "tolerance": 1e6}
    assert main(["reference", _config(tmp_path, loose), "--no-progress"]) == 0
    meta, _ = held_reference(cache)
    assert meta["converged"] is True
    capsys.readouterr()
    assert main(["reference", _config(tmp_path, SHORT), "--no-progress"]) == 1
    out = capsys.readouterr().out
    assert "NOT converged" in out and "\nconverged" not in f"\n{out}", out
