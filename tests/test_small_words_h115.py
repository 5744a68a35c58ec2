"""Small wording: a missing path under scenes/ names the built-in scene it is; 'tlm config export'
names an unknown experiment as given, says a copy already there is kept, and its copy's comment
names the copy; 'tlm scene export' over a foreign file names it once; 'tlm thesis' names a scene
not comparable as its table does."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

import tlm.builtin
from tests.helpers_packaged import installed_configs, one_error
from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.thesis import summarize

REPO = Path(__file__).resolve().parents[1]
TINY = ["--set", "resolution=[16,16]", "--mode", "rcast", "--no-progress", "--no-report"]


_one_error = one_error


@pytest.fixture
def packaged(tmp_path, monkeypatch):
    """The built-in experiments as an installed copy has them, and a working folder without
    configs/ or scenes/."""
    return installed_configs(tmp_path, monkeypatch)


# ---------------------------------------------------------------- a checkout's scene path outside one


def test_a_missing_scene_path_names_the_built_in_scene(packaged, capsys):
    """``scenes/examples/mesh_on_floor.yaml`` outside a checkout was a bare "file not found"."""
    assert main(["run", "scenes/examples/mesh_on_floor.yaml", *TINY]) == 2
    assert _one_error(capsys) == (
        "tlm: error: scenes/examples/mesh_on_floor.yaml: not found here; the built-in scene of that name: "
        "examples/mesh_on_floor ('tlm scene export examples/mesh_on_floor FILE.yaml' copies it out to edit and "
        "run; a config names it: scene: examples/mesh_on_floor)")
    # under scenes/ a name that is an experiment's too is the scene (it was the experiment cornell's)
    assert main(["run", "scenes/cornell.yaml", *TINY]) == 2
    assert "the built-in scene of that name: cornell ('tlm scene export cornell FILE.yaml'" in _one_error(capsys)
    # a scene's name with its folder (thesis/ring, not the experiment ring, which renders the scene ring)
    assert main(["run", "thesis/ring.yaml", *TINY]) == 2
    assert "the built-in scene of that name: thesis/ring (" in _one_error(capsys)
    # as before: configs/ and a bare file name are the experiment's, other paths not found
    assert main(["run", "configs/cornell.yaml", *TINY]) == 2
    assert "the built-in experiment of that name: tlm run cornell" in _one_error(capsys)
    assert main(["run", "scenes/nosuch.yaml", *TINY]) == 2
    assert _one_error(capsys) == "tlm: error: scenes/nosuch.yaml: file not found"
    assert not Path("runs").exists()
    # the hint's command copies the scene out
    assert main(["scene", "export", "examples/mesh_on_floor", "m.yaml"]) == 0
    assert "wrote m.yaml" in capsys.readouterr().out
    assert yaml.safe_load(Path("m.yaml").read_text())["geometry"] == {"mesh": "m.obj"}


# ---------------------------------------------------------------- tlm config export


def test_an_unknown_experiment_is_named_as_given(packaged, capsys):
    assert main(["config", "export", "nosuch", "y.yaml"]) == 2
    line = _one_error(capsys)
    assert line.startswith("tlm: error: 'nosuch' is not a built-in experiment (bsp_levels, "), line  # (was "name: ")
    assert not Path("y.yaml").exists()
    with pytest.raises(InputError, match=r"^'scaling_rng' is not a built-in experiment .*did you mean 'scaling_ring'"):
        tlm.builtin.export_experiment("scaling_rng", "y.yaml")


def test_a_second_identical_export_says_it_kept_the_copy(packaged, capsys):
    assert main(["config", "export", "scaling_ring", "sr.yaml"]) == 0
    assert capsys.readouterr().out == ("wrote sr.yaml (a copy of the built-in experiment scaling_ring) and ring.yaml "
                                       "(its base config, which it names); run it: tlm sweep sr.yaml\n")
    before = Path("sr.yaml").stat().st_mtime_ns
    assert main(["config", "export", "scaling_ring", "sr.yaml"]) == 0  # (it said "wrote sr.yaml")
    assert capsys.readouterr().out == ("sr.yaml is already a copy of the built-in experiment scaling_ring: kept; "
                                       "run it: tlm sweep sr.yaml\n")
    assert Path("sr.yaml").stat().st_mtime_ns == before
    assert tlm.builtin.export_experiment("scaling_ring", "sr.yaml") == []  # (nothing written)
    Path("ring.yaml").unlink()  # the base alone is written again
    assert main(["config", "export", "scaling_ring", "sr.yaml"]) == 0
    assert capsys.readouterr().out == ("sr.yaml is already a copy of the built-in experiment scaling_ring: kept; "
                                       "wrote ring.yaml (its base config, which it names); run it: tlm sweep "
                                       "sr.yaml\n")


def test_the_copy_s_comment_names_the_copy(packaged):
    """The comment's command was ``tlm sweep configs/scaling_ring.yaml``, a file not there."""
    source = (packaged / "scaling_ring.yaml").read_text()
    assert "tlm sweep configs/scaling_ring.yaml --out" in source
    assert tlm.builtin.export_experiment("scaling_ring", "sr.yaml") == [Path("sr.yaml"), Path("ring.yaml")]
    copy = Path("sr.yaml").read_text()
    assert "configs/scaling_ring.yaml" not in copy and "#   tlm sweep sr.yaml --out runs/scaling_ring\n" in copy
    # only that: the rest byte for byte (another file's name kept), and the data the same
    assert copy == source.replace("configs/scaling_ring.yaml", "sr.yaml")
    assert "as configs/thesis.yaml" in copy
    assert yaml.safe_load(copy) == yaml.safe_load(source)
    Path("sub").mkdir()
    tlm.builtin.export_experiment("thesis", "sub/t.yaml")
    text = Path("sub/t.yaml").read_text()
    assert "#   tlm thesis sub/t.yaml --out runs/thesis" in text and "tlm calibrate sub/t.yaml " in text


# ---------------------------------------------------------------- tlm scene export


def test_a_foreign_file_of_the_target_s_name_is_named_once(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    Path("j.obj").write_text("# my own mesh\nv 0 0 0\n")
    assert main(["scene", "export", "cornell", "j.obj"]) == 2
    assert _one_error(capsys) == ("tlm: error: j.obj: exists and is not a mesh tlm wrote; the export would replace "
                                  "it: name another .obj file")  # (was "j.obj: j.obj exists ...")
    # the mesh beside a scene file is another file: named
    Path("k.obj").write_text("# my own mesh\nv 0 0 0\n")
    assert main(["scene", "export", "cornell", "k.yaml"]) == 2
    assert _one_error(capsys) == ("tlm: error: k.yaml: k.obj exists and is not a mesh tlm wrote; the export would "
                                  "replace it: name another .yaml file")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["j.obj", "k.obj"]


# ---------------------------------------------------------------- tlm thesis: one name for a scene


def test_summarize_names_a_scene_not_comparable_as_the_table_does():
    rows = [{"scene": "ring", "mode": "rcast", "metric": m, "thesis": 10.0, "ours": 11.0, "rel_error": 0.1,
             "calibrated": False} for m in ("TVert", "TTrav", "Tisct", "TFrag")]
    differ = {"ring": ["32×32 pixels (thesis 320×240)"]}
    said = summarize(rows, differ, {"ring": "thesis/ring"})["median_withheld"]
    assert said == "not comparable with the thesis: thesis/ring is 32×32 pixels (thesis 320×240)"
    assert summarize(rows, differ)["median_withheld"] == "not comparable with the thesis: ring is 32×32 pixels " \
                                                         "(thesis 320×240)"


def test_tlm_thesis_names_thesis_ring_once(tmp_path, monkeypatch, capsys):
    """The printed table said thesis/ring and the line under it "ring is 16×16 pixels"."""
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump({
        "base": {"seed": 0, "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
                 "arch": {"trace": False}},  # (the thesis's stream and packets: only the size is not)
        "scenes": ["thesis/ring"], "modes": ["rcast"]}))
    out = tmp_path / "out"
    assert main(["thesis", str(study), "--out", str(out), "--no-progress", "--no-report"]) == 0
    printed = capsys.readouterr().out
    assert "\nthesis/ring rcast " in printed
    assert ("no median |relative error| (not comparable with the thesis: thesis/ring is 16×16 pixels "
            "(thesis 320×240))") in printed
    summary = json.loads((out / "thesis_summary.json").read_text())
    assert summary["median_withheld"] == "not comparable with the thesis: thesis/ring is 16×16 pixels (thesis 320×240)"
    assert list(summary["not_comparable"]) == ["ring"]  # (the rows' key, as the CSV's scene column)
