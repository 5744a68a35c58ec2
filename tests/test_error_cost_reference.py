"""``tlm error-vs-cost`` and a cached photon-map reference that is not converged (a ``tlm
reference`` stopped at ``reference.max_rounds``): the study computes it again to the base's
tolerance, as ``tlm reference`` would, or, where that would repeat the same rounds, warns and
marks every row ``reference_converged: false``."""

from __future__ import annotations

import csv
import json

import pytest

from tlm.cli import main

from .scenes import sphere_scene

# a reference that stops after two rounds, far short of its tolerance
SHORT = {"photons": 800, "k_nearest": 20, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 2, "spp": 1}
LOOSE = 0.12  # a tolerance that reference misses (relative standard error about 0.17) and 16 rounds meet


def _study(tmp_path, reference: dict):
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({
        "base": {"scene": "furnace.yaml", "resolution": [8, 8], "reference": reference,
                 "photons": {"count": 800}, "estimate": {"final_gather": 0}},
        "points": [{"estimate.filter": ["disk", "mvoxel"]}],
    }))
    return exp


def _short_reference(tmp_path, cache, capsys) -> dict:
    """A reference cached by ``tlm reference`` that is NOT converged; its meta.json."""
    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(json.dumps({"scene": "furnace.yaml", "mode": "pmap", "resolution": [8, 8], "reference": SHORT}))
    assert main(["reference", str(cfg), "--no-progress"]) == 1
    assert "NOT converged" in capsys.readouterr().out
    (folder,) = (cache / "references").iterdir()
    meta = json.loads((folder / "meta.json").read_text())
    assert meta["converged"] is False
    return meta


def _rows(out):
    with open(out / "rows.csv") as f:
        return list(csv.DictReader(f)), [json.loads(line) for line in (out / "rows.jsonl").read_text().splitlines()]


def test_a_reference_short_of_the_base_tolerance_is_computed_again(tmp_path, cache, capsys):
    """The base asks for a tolerance the cached reference misses (its relative standard error, not
    its converged flag: see test_a_cached_reference_within_a_looser_tolerance_is_used), with other
    round limits: the study computes it again (and caches it), as ``tlm reference`` does; it
    measured every point against the unconverged one before, saying nothing."""
    old = _short_reference(tmp_path, cache, capsys)
    assert old["relative_standard_error"] > LOOSE  # (2 rounds: about 0.17)
    exp = _study(tmp_path, {**SHORT, "tolerance": LOOSE, "max_rounds": 16})  # (the same key: photons, k)
    out = tmp_path / "out"
    assert main(["error-vs-cost", str(exp), "--out", str(out), "--truth-spp", "0", "--no-report"]) == 0
    captured = capsys.readouterr()
    assert f"does not meet tolerance {LOOSE}: computing it again" in captured.out
    assert "NOT converged" not in captured.err
    ref = json.loads((out / "reference.json").read_text())
    assert ref["key"] == old["key"] and ref["converged"] is True and ref["reference_converged"] is True
    assert ref["computed"] is True and ref["relative_standard_error"] < LOOSE
    (folder,) = (cache / "references").iterdir()
    assert json.loads((folder / "meta.json").read_text())["converged"] is True  # (cached for the next run)
    text, rows = _rows(out)
    assert [r["reference_converged"] for r in rows] == [True, True]
    assert [r["reference_converged"] for r in text] == ["True", "True"]


def test_a_reference_the_base_rule_cannot_converge_is_used_with_a_warning(tmp_path, cache, capsys, monkeypatch):
    """The base's own stopping rule made the cached reference: computing it again would repeat
    the same rounds, so the study uses it, says so in one warning line and marks every row."""
    import tlm.experiments.error_cost as ec

    _short_reference(tmp_path, cache, capsys)
    monkeypatch.setattr(ec, "compute_reference", lambda *a, **k: pytest.fail("computed the same reference again"))
    out = tmp_path / "out"
    assert main(["error-vs-cost", str(_study(tmp_path, SHORT)), "--out", str(out), "--truth-spp", "0",
                 "--no-report"]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "NOT converged" in line]
    assert len(warned) == 1
    assert warned[0].startswith("tlm: warning: error-vs-cost: the photon-map reference ")
    assert "reference.tolerance 1e-06" in warned[0] and "reference.max_rounds" in warned[0]
    ref = json.loads((out / "reference.json").read_text())
    assert ref["reference_converged"] is False and ref["computed"] is False
    text, rows = _rows(out)
    assert [r["reference_converged"] for r in rows] == [False, False]
    assert [r["reference_converged"] for r in text] == ["False", "False"]


def test_a_converged_cached_reference_is_used_as_it_is(tmp_path, cache, capsys, monkeypatch):
    """A cached reference that meets the base's tolerance is not computed again, and no line warns."""
    import tlm.experiments.error_cost as ec

    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    loose = {**SHORT, "tolerance": 0.9, "max_rounds": 8}
    exp = _study(tmp_path, loose)
    first, second = tmp_path / "first", tmp_path / "second"
    assert main(["error-vs-cost", str(exp), "--out", str(first), "--truth-spp", "0", "--no-report"]) == 0
    assert json.loads((first / "reference.json").read_text())["computed"] is True
    monkeypatch.setattr(ec, "compute_reference", lambda *a, **k: pytest.fail("computed a converged reference again"))
    capsys.readouterr()
    assert main(["error-vs-cost", str(exp), "--out", str(second), "--truth-spp", "0", "--no-report"]) == 0
    assert "NOT converged" not in capsys.readouterr().err
    ref = json.loads((second / "reference.json").read_text())
    assert ref["computed"] is False and ref["reference_converged"] is True
    assert [r["reference_converged"] for r in _rows(second)[1]] == [True, True]
