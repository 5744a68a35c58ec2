"""The pmap check of a scene that nothing gives photons (7b4f745, h474) refuses a run and a reference of no
photons, not an error-vs-cost study whose base gives no count but whose points do (h476: it was refused, its line
saying the config's photons.count is null)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tlm.cli import main

REPO = Path(__file__).resolve().parents[1]


def _scene(tmp_path: Path) -> Path:
    text = (REPO / "scenes" / "cornell.yaml").read_text()
    kept = "\n".join(line for line in text.splitlines() if not line.startswith("photons:"))
    (tmp_path / "nophot.yaml").write_text(kept + "\n")
    for extra in (REPO / "scenes").glob("cornell*"):
        if extra.is_dir():
            shutil.copytree(extra, tmp_path / extra.name)
    return tmp_path / "nophot.yaml"


@pytest.mark.slow
def test_an_error_vs_cost_study_whose_points_give_the_count_runs(tmp_path, cache):
    _scene(tmp_path)
    study = tmp_path / "study.yaml"
    study.write_text("base:\n  scene: nophot.yaml\n  resolution: [8, 6]\n  reference: {photons: 2000, max_rounds: 4}\n"
                     "points:\n  - photons.count: [1000]\n")
    assert main(["error-vs-cost", str(study), "--out", str(tmp_path / "o"), "--no-report", "--no-progress"]) in (0, 1)
    assert (tmp_path / "o" / "rows.jsonl").is_file()


def test_a_pmap_run_of_that_scene_is_refused(tmp_path, cache, capsys):
    _scene(tmp_path)
    config = tmp_path / "c.yaml"
    config.write_text("scene: nophot.yaml\nmode: pmap\nresolution: [8, 6]\n")
    assert main(["run", str(config), "--out", str(tmp_path / "r"), "--no-report", "--no-progress"]) == 2
    assert "photons: mode 'pmap' asks for the photon-map pass" in capsys.readouterr().err
