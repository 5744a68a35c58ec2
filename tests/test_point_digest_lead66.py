"""A sweep point written before points recorded their scene digest (h393) is still reported by its files as they are
now, said so: "(of its files now: not recorded)" (the case that tests/test_scene_digest_h346.py held before h393)."""

from __future__ import annotations

import json

import pytest

from tests.test_scene_digest_h346 import _project, _summaries
from tlm.experiments.provenance import scene_identity
from tlm.experiments.sweep import run_sweep


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py: a TLM_CACHE of the test's own)
    return cache


def test_a_point_of_an_older_tlm_is_digested_now_and_says_so(tmp_path, monkeypatch):
    from tlm.report import build_report

    p = _project(tmp_path / "p")
    assert run_sweep(p / "sw.yaml", tmp_path / "sw", jobs=1).ok == 2
    for results in (tmp_path / "sw" / "points").glob("*/results.json"):
        record = json.loads(results.read_text())
        assert record.pop("scene_digest") == scene_identity(p / "s.yaml")  # (recorded now: removed, as of old)
        results.write_text(json.dumps(record))
    monkeypatch.chdir(tmp_path)
    (said,) = _summaries(build_report([tmp_path / "sw"], tmp_path / "rep").read_text())
    assert (f"inputs {scene_identity(p / 's.yaml')} (of its files now: not recorded) (runs sw #0 and sw #1)"
            in said), said
