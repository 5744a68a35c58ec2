"""A sweep's report opens with what the sweep found: the factor that moves the frame rate
most and the best point, not "Nothing to show"."""

from __future__ import annotations

import re

import pytest
import yaml

from tlm.experiments.sweep import run_sweep
from tlm.report import build_report

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [24, 16], "render": {"light_samples": 1},
        "arch": {"frames": 2, "trace": False}}


@pytest.mark.slow
def test_a_sweeps_first_screen_names_its_finding(tmp_path, monkeypatch):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.pipelines": [1, 4], "arch.fifo_depth": [1, 16]}},
                                   sort_keys=False))
    out = tmp_path / "o"
    done = run_sweep(path, out, jobs=1)
    assert done.ok == 4
    build_report([out])
    page = (out / "report" / "report.html").read_text()
    first = page[page.index("What the model found"):page.index("</section>", page.index("What the model found"))]
    plain = re.sub("<[^>]+>", "", first)
    assert "Nothing to show" not in plain
    best = max(done.rows, key=lambda r: r["fps"])
    assert "arch.pipelines moves the frame rate most" in plain  # 4 pipelines, not a FIFO depth
    assert f"2 points tie as the best at {best['fps']:.3g} FPS: arch.pipelines = {best['arch.pipelines']}, " \
           "any arch.fifo_depth" in plain
