"""``tlm.run`` returns what ``results.json`` holds: equal to ``json.loads`` of the file, a number
that is not finite (which strict JSON does not have) None in both, not ``inf`` in the dict only.

The one such number a run can hold is ``fps`` where ``cycles.throughput`` is 0, a frame
program with no work; no rendered frame has one (every frame copies its tree and vertices,
a cycle at least: tiny runs of cornell in rcast, reflect, refract and pmap hold no value that
is not finite). So the case is made as tests/test_strict_json.py makes it: the timing
model's ``fps`` replaced by ``inf``, the value it gives for a throughput of 0 cycles.
"""

from __future__ import annotations

import dataclasses
import json
import math

import pytest

import tlm
import tlm.arch.model as model
import tlm.experiments.run as run_mod
from tlm.cli import main

TINY = {"resolution": [8, 8], "mode": "rcast", "render.light_samples": 1}


@pytest.fixture
def endless_fps(monkeypatch):
    """The timing model with its fps infinite (what it gives for a throughput of 0 cycles)."""
    real = model.simulate

    def simulate(*args, **kw):
        return dataclasses.replace(real(*args, **kw), fps=math.inf)

    monkeypatch.setattr(model, "simulate", simulate)
    monkeypatch.setattr(run_mod, "simulate", simulate)


def test_a_number_that_is_not_finite_is_returned_as_the_none_the_file_holds(tmp_path, cache, endless_fps):
    results = tlm.run(tlm.load_config("cornell", TINY), tmp_path / "run", outputs=())
    written = json.loads((tmp_path / "run" / "results.json").read_text())
    assert written["fps"] is None
    assert results["fps"] is None  # (was inf)
    assert results == written


def test_tlm_run_says_there_is_no_frame_rate(tmp_path, cache, endless_fps, capsys):
    assert main(["run", "cornell", "--set", "resolution=[8,8]", "--mode", "rcast", "--out", str(tmp_path / "r"),
                 "--no-report", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "  no frame rate: a frame of no cycles\n" in out and "frames per second" not in out
