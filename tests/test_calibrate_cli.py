"""`tlm calibrate` writes only a fit it can stand behind, where it was asked to; `tlm
reference` says with its exit status when its reference did not converge.

Every test here runs with the packaged table replaced by a copy of its own (the fixture
``packaged``): nothing can reach ``tlm/arch/programs.yaml``, and the test checks that."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import pytest
import yaml

import tlm.arch.costs as costs
import tlm.experiments.thesis as thesis_mod
from tlm.cli import main

from .scenes import sphere_scene

TINY = {"seed": 0, "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1}, "photons": {"count": 2000},
        "arch": {"frames": 2, "packet_size": 64, "trace": False}}
REAL_TABLE = costs.DEFAULT_PATH


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def packaged(tmp_path, monkeypatch, cache):
    """The packaged table as calibrate sees it: a copy in tmp_path (the real one is left alone)."""
    before = _digest(REAL_TABLE)
    copy = tmp_path / "packaged" / "programs.yaml"
    copy.parent.mkdir()
    shutil.copy(REAL_TABLE, copy)
    monkeypatch.setattr(costs, "DEFAULT_PATH", copy)
    yield copy
    assert _digest(REAL_TABLE) == before, "the packaged tlm/arch/programs.yaml was written"


def _study(tmp_path: Path, scenes=("thesis/ring", "cornell"), modes=("rcast",), **base) -> Path:
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump({"base": {**TINY, **base}, "scenes": list(scenes), "modes": list(modes)}))
    return path


def _no_render(monkeypatch):
    """What must be refused before the fit: a render would fail the test."""
    def render(*args, **kwargs):
        raise AssertionError("rendered: the refusal came after the fit")
    monkeypatch.setattr(thesis_mod, "render", render)


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_the_packaged_table_is_never_written_from_another_setting(tmp_path, packaged, capsys):
    """16x16 pixels is not the thesis's setting: the fit is refused over the packaged table
    (by default and by name), written elsewhere with a warning."""
    before = packaged.read_text()
    study = _study(tmp_path)
    assert main(["calibrate", str(study)]) == 2
    line = _one_line(capsys)
    assert line.startswith(f"tlm: error: {packaged}: not written") and "16×16 pixels (thesis 320×240)" in line
    assert main(["calibrate", str(study), "--write", str(packaged)]) == 2
    assert "not written" in _one_line(capsys)
    assert packaged.read_text() == before and not list(packaged.parent.glob("*.tmp"))
    other = tmp_path / "fit.yaml"
    assert main(["calibrate", str(study), "--write", str(other)]) == 0
    out, err = capsys.readouterr()
    assert f"wrote {other}" in out and other.is_file()
    (warning,) = err.strip().splitlines()
    assert warning.startswith("tlm: warning: ") and "cornell is 16×16 pixels (thesis 320×320)" in warning


def test_the_default_target_is_the_table_the_study_uses(tmp_path, packaged, capsys):
    mine = tmp_path / "myprog.yaml"
    mine.write_text("# my own table\n" + packaged.read_text())
    before = packaged.read_text()
    study = _study(tmp_path, arch={**TINY["arch"], "programs": "myprog.yaml"})
    assert main(["calibrate", str(study)]) == 0
    assert f"wrote {mine}" in capsys.readouterr().out
    text = mine.read_text()
    assert text.startswith("# my own table\n") and "tlm calibrate" in text.split("calibration:", 1)[1]
    assert packaged.read_text() == before


@pytest.mark.parametrize("write, said", [("", "an empty path names no table"),
                                         ("missing/fit.yaml", "does not exist"),
                                         (".", "is a folder")])
def test_a_bad_write_path_is_refused_before_the_fit(tmp_path, packaged, capsys, monkeypatch, write, said):
    _no_render(monkeypatch)
    before = packaged.read_text()
    target = write if write == "" else str(tmp_path / write)
    assert main(["calibrate", str(_study(tmp_path)), "--write", target]) == 2
    line = _one_line(capsys)
    assert line.startswith("tlm: error: tlm calibrate: argument --write: ") and said in line
    assert packaged.read_text() == before


@pytest.mark.parametrize("scenes, modes, said", [
    (["cornell"], ["rcast"], "one scene gives one RCast cell per PM"),  # 2 parameters per PM from 1 cell
    (["thesis/ring", "cornell"], ["pmap"], "has no rcast"),  # the one column the fit reads is not asked for
])
def test_a_fit_that_cannot_be_the_one_asked_for_is_refused(tmp_path, packaged, capsys, monkeypatch, scenes, modes,
                                                           said):
    _no_render(monkeypatch)
    before = packaged.read_text()
    study = _study(tmp_path, scenes, modes)
    assert main(["calibrate", str(study), "--dry-run"]) == 2
    line = _one_line(capsys)
    assert line.startswith(f"tlm: error: {study}: ") and said in line
    assert packaged.read_text() == before


def test_a_reference_that_did_not_converge_exits_1(tmp_path, cache, capsys):
    sphere_scene(tmp_path, n_seg=12, n_rings=6)
    cfg = tmp_path / "run.yaml"
    cfg.write_text(yaml.safe_dump({
        "scene": "furnace.yaml", "mode": "pmap", "resolution": [8, 8], "photons": {"count": 500},
        "reference": {"photons": 300, "k_nearest": 10, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 2,
                      "spp": 1}}))
    assert main(["reference", str(cfg), "--no-progress"]) == 1
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith("NOT converged (max_rounds reached) after 2 rounds") and "exit status 1" in last
    assert any((cache / "references").iterdir())  # written all the same
    assert main(["reference", "--help"]) == 0
    assert "1 when it stopped at reference.max_rounds" in " ".join(capsys.readouterr().out.split())
