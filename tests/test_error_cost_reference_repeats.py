"""``tlm error-vs-cost`` keeps a cached reference that computing again would only repeat, as ``tlm
reference`` does (:func:`tlm.experiments.reference_cache.repeats`).

A reference that stopped at ``reference.max_rounds`` short of its tolerance is what computing it
again gives wherever the base's settings allow as many cycles of the same length and no earlier
cycle meets their tolerance: a stricter tolerance, or a ``max_rounds`` that is no whole cycle more.
The study compared the stopping rule's four settings for equality and computed those again (the
same rounds, the same image, the seconds lost); now it uses the cached one, with its warning that
the reference is not converged, as for the base's own rule."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

import tlm.experiments.error_cost as ec
from tests.helpers_reference import held_reference
from tlm.cli import main

from .scenes import sphere_scene

# 2 cycles of 2 rounds, far short of the tolerance: not converged
SHORT = {"photons": 500, "k_nearest": 20, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 4, "spp": 2}


@pytest.mark.parametrize("asked", [{"tolerance": 1e-7}, {"max_rounds": 5}, {"tolerance": 1e-7, "min_rounds": 3}],
                         ids=["stricter-tolerance", "max-rounds-no-whole-cycle-more", "stricter-and-min-rounds"])
def test_a_study_keeps_a_cached_reference_that_computing_again_would_repeat(
        tmp_path, cache, capsys, monkeypatch, asked):
    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps({"scene": "furnace.yaml", "mode": "pmap", "resolution": [8, 8], "reference": SHORT}))
    assert main(["reference", str(cfg), "--no-progress"]) == 1  # (not converged)
    capsys.readouterr()
    old, image = held_reference(cache)
    assert old["rounds"] == 4 and old["cycles"] == 2 and old["converged"] is False

    computed = []

    def compute(*a, **k):
        computed.append(a[2])  # (its settings)
        raise AssertionError("computed the same rounds again")

    monkeypatch.setattr(ec, "compute_reference", compute)
    exp = tmp_path / "evc.json"
    exp.write_text(json.dumps({
        "base": {"scene": "furnace.yaml", "resolution": [8, 8], "reference": {**SHORT, **asked},
                 "photons": {"count": 500}, "estimate": {"final_gather": 0}},
        "points": [{"estimate.filter": ["disk", "mvoxel"]}],
    }))
    out = tmp_path / "out"
    code = main(["error-vs-cost", str(exp), "--out", str(out), "--truth-spp", "0", "--no-report"])
    captured = capsys.readouterr()
    assert not computed, "error-vs-cost computed the cached reference's rounds again"
    assert code == 0, captured.err
    assert "computing it again" not in captured.out + captured.err
    warned = [line for line in captured.err.splitlines() if "NOT converged" in line]
    assert len(warned) == 1 and f"the photon-map reference {old['key']} is NOT converged" in warned[0]
    ref = json.loads((out / "reference.json").read_text())
    assert ref["key"] == old["key"] and ref["computed"] is False and ref["reference_converged"] is False
    assert ref["rounds"] == 4
    with open(out / "rows.csv") as f:
        assert [r["reference_converged"] for r in csv.DictReader(f)] == ["False", "False"]
    meta, now = held_reference(cache)
    assert meta == old
    np.testing.assert_array_equal(now, image)
