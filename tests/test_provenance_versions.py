"""results.json names the libraries that compute, compile and draw a result (numba and
matplotlib among them) and which kernels ran: the compiled numba ones or the numpy ones
(TLM_KERNELS)."""

from __future__ import annotations

import importlib.metadata as md
import json

import pytest
import yaml

from tlm.cli import main

TINY = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"spp": 1, "light_samples": 1}}


def _run(tmp_path, name: str) -> dict:
    cfg = tmp_path / "tiny.yaml"
    cfg.write_text(yaml.safe_dump(TINY))
    assert main(["run", str(cfg), "--out", str(tmp_path / name), "--no-progress"]) == 0
    return json.loads((tmp_path / name / "results.json").read_text())


def test_a_run_records_numba_matplotlib_and_the_kernels_that_ran(tmp_path, cache, monkeypatch):
    monkeypatch.setenv("TLM_KERNELS", "numpy")
    v = _run(tmp_path, "run")["versions"]
    assert v["numba"] == md.version("numba") and v["matplotlib"] == md.version("matplotlib")
    assert v["kernels"] == "numpy"


@pytest.mark.parametrize(("env", "kernels"), [("numba", "numba"), ("NumPy", "numpy"), ("", None), (None, None)])
def test_the_versions_name_the_engine_tlm_kernels_selects(monkeypatch, env, kernels):
    from tlm.experiments.provenance import versions
    from tlm.kernels.engine import numba_available

    if env is None:
        monkeypatch.delenv("TLM_KERNELS", raising=False)
    else:
        monkeypatch.setenv("TLM_KERNELS", env)
    expected = kernels or ("numba" if numba_available() else "numpy")  # (unset or empty: the default)
    assert versions()["kernels"] == expected


def test_a_sweep_point_and_a_study_record_the_kernels(tmp_path, cache, monkeypatch):
    from tlm.experiments.provenance import provenance

    monkeypatch.setenv("TLM_KERNELS", "numpy")
    assert provenance("study.yaml", 1.0)["versions"]["kernels"] == "numpy"
    sweep = tmp_path / "sw.yaml"
    sweep.write_text(yaml.safe_dump({"base": TINY, "grid": {"arch.fifo_depth": [16]}}))
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "sw"), "--no-progress", "--no-report"]) == 0
    (point,) = (tmp_path / "sw" / "points").iterdir()
    v = json.loads((point / "results.json").read_text())["versions"]
    assert v["kernels"] == "numpy" and v["numba"] == md.version("numba")
