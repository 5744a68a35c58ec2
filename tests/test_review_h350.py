"""h350: review of 23f73e6 (results.json ``scene_digest`` from a load's records; the report's scene tables).

* The report grouped a sweep's points (which record no digest: their files are digested now) with a run whose
  recorded digest is that of the files now, though another run of the same scene file recorded other contents:
  the points, run before an edit, were shown as the edited scene's, with no word that their inputs were not
  recorded (before 23f73e6 they were a record of their own, "(of its files now: not recorded)").
* A load's ``("side", path, sha256, size)`` record: the identity took the sha256 the load read with the size of the
  file now, a digest of neither version where the file was saved to another size between the load and the digest.
"""

from __future__ import annotations

import html
import json
import re
import shutil
from pathlib import Path

import pytest

from tests.test_h339 import OBJ
from tests.test_scene_digest_h346 import _project
from tlm.cli import main
from tlm.config import noting_reads
from tlm.experiments.provenance import scene_identity
from tlm.experiments.sweep import run_sweep
from tlm.scenes.loader import load_scene


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py: a TLM_CACHE of the test's own)
    return cache


def test_sweep_points_are_not_given_the_inputs_of_a_run_of_other_recorded_contents(tmp_path, monkeypatch):
    from tlm.report import build_report

    p = _project(tmp_path / "p")
    first = scene_identity(p / "s.yaml")
    assert run_sweep(p / "sw.yaml", tmp_path / "sw", jobs=1).ok == 2  # (they read the first contents)
    (p / "m.obj").write_text(OBJ.replace("v 0 1 0", "v 0 1.01 0"))  # (then the mesh edited)
    assert main(["run", str(p / "exp.yaml"), "--out", str(tmp_path / "b"), "--no-progress", "--no-report",
                 "--outputs", "images"]) == 0
    now = json.loads((tmp_path / "b" / "results.json").read_text())["scene_digest"]
    assert now == scene_identity(p / "s.yaml")
    shutil.copytree(tmp_path / "b", tmp_path / "a")  # (a run of the first contents: its recorded digest another)
    results = json.loads((tmp_path / "a" / "results.json").read_text())
    results["scene_digest"] = "sha256 0123456789abcdef"
    (tmp_path / "a" / "results.json").write_text(json.dumps(results))
    monkeypatch.chdir(tmp_path)
    out = build_report([tmp_path / "a", tmp_path / "sw", tmp_path / "b"], tmp_path / "rep").read_text()
    said = [html.unescape(re.sub(r"<[^>]+>", "", s)) for s in re.findall(r"<summary>(scene .*?)</summary>", out)]
    points = [s for s in said if "sw #0" in s]
    assert len(said) == 3 and len(points) == 1, said  # (was two: the points with run b, as if they had read its files)
    # (h393: the points record the digest of the files they read, the first contents: no longer "of its files now")
    assert "b:" not in points[0] and f"inputs {first} (runs sw #0 and sw #1)" in points[0], points


def test_a_side_records_size_is_the_size_read(tmp_path):
    p = _project(tmp_path / "p")
    before = scene_identity(p / "s.yaml")
    with noting_reads() as reads:
        load_scene(str(p / "s.yaml"))
    sides = [r for r in reads if r[0] == "side"]
    assert [Path(r[1]).name for r in sides] == ["m.mtl"]
    assert [r[3] for r in sides] == [(p / "m.mtl").stat().st_size]  # (the load records the size it read)
    (p / "m.mtl").write_text("newmtl g\nKd 0.55 0.5 0.5\n")  # (saved after the load: another size)
    after = scene_identity(p / "s.yaml")
    assert scene_identity(p / "s.yaml", reads) == before != after  # (was neither: the old sha256, the new size)
