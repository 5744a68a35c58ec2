"""A Mitsuba ground truth whose cache cannot be written (tlm/oracle/mitsuba.py): the image
rendered is used all the same, one warning line says the cache could not be written, and no
traceback; it was rendered and then lost to an error naming ``--out`` (exit 2) before.

Skipped as a whole where the optional ``mitsuba`` package is not installed.
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

pytest.importorskip("mitsuba")

from tlm.cli import main
from tlm.oracle import mitsuba as om
from tlm.scenes.loader import load_scene

from .scenes import sphere_scene

WARNING = "cannot write tlm's Mitsuba ground-truth cache"


def _said(err: str) -> list[str]:
    return [line for line in err.splitlines() if WARNING in line]


def _blocked_oracle(tmp_path, monkeypatch):
    """A cache folder whose ``oracle`` is a regular file (unwritable, even for root); the
    other caches (the references') can be written."""
    root = tmp_path / "cache"
    root.mkdir()
    (root / "oracle").write_text("")
    monkeypatch.setenv("TLM_CACHE", str(root))
    return root


def test_ground_truth_keeps_the_image_its_cache_cannot_take(tmp_path, monkeypatch, capsys):
    scene = load_scene(str(sphere_scene(tmp_path, n_seg=8, n_rings=4)))
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "ok"))
    cached = om.ground_truth(scene, "path", spp=1)
    assert cached is not None and cached[0].shape == (24, 24, 3)
    capsys.readouterr()

    root = _blocked_oracle(tmp_path, monkeypatch)
    found = om.ground_truth(scene, "path", spp=1)  # (no exception: the render is not thrown away)
    assert found is not None
    image, meta = found
    np.testing.assert_array_equal(image, cached[0])  # (the values a cached image has: float32 widened)
    assert image.dtype == np.float64
    assert meta["key"] == cached[1]["key"] and meta["spp"] == 1 and meta["integrator"] == "path"
    err = capsys.readouterr().err
    assert "Traceback" not in err
    said = _said(err)
    assert len(said) == 1, err
    assert f"{root / 'oracle'} is a file, not a folder" in said[0]

    again = om.ground_truth(scene, "path", spp=1)  # (rendered again: nothing was cached; said once a process)
    np.testing.assert_array_equal(again[0], cached[0])
    assert _said(capsys.readouterr().err) == []
    assert om.ground_truth(scene, "path", spp=1, compute=False) is None


def test_error_vs_cost_with_an_unwritable_ground_truth_cache_measures_against_the_truth(tmp_path, monkeypatch,
                                                                                      capsys):
    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    _blocked_oracle(tmp_path, monkeypatch)
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({
        "base": {"scene": "furnace.yaml", "resolution": [8, 8], "photons": {"count": 800},
                 "reference": {"photons": 800, "k_nearest": 20, "tolerance": 0.9, "min_rounds": 2,
                               "max_rounds": 2, "spp": 1},
                 "estimate": {"final_gather": 0}},
        "points": [{"estimate.filter": ["disk"]}],
    }))
    out = tmp_path / "out"
    assert main(["error-vs-cost", str(exp), "--out", str(out), "--truth-spp", "1", "--no-report"]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and "error:" not in err, err
    assert len(_said(err)) == 1, err
    with open(out / "rows.csv") as f:
        (row,) = list(csv.DictReader(f))
    assert row["truth_spp"] == "1" and float(row["truth_rel_mse"]) >= 0.0
    truth = json.loads((out / "truth.json").read_text())
    assert truth["available"] is True and truth["spp"] == 1
