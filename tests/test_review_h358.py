"""Review h358 of eb88e56 and 785e44f.

- A file of an ``extends:`` chain whose ``geometry:`` only merges a ``transform`` into the base's keeps
  the parts: an entry an earlier file gave for a part its own geometry lacks (a typo) stays that file's
  error, not a note (eb88e56 made it a note whenever a later file gave any ``geometry`` key).
- The report shows a user's own, edited scene file that lies in a folder named ``scenes`` under its own
  path, not as the built-in ``scenes/cornell.yaml`` (785e44f showed the materials' and lights' ``from``
  cells through :func:`tlm.report.names.shown_paths`, which so renamed any ``.../scenes/cornell.yaml``).
- ``tlm calibrate``'s refusal on an installed copy names commands that run as printed for a study whose
  name starts with ``-`` too (``./-th.yaml``: argparse took ``-th.yaml`` for a flag; 785e44f).
"""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

import tlm.api
import tlm.api_studies
from tlm.arch import costs
from tlm.cli import main
from tlm.report.names import shown_path, shown_paths
from tlm.report.provenance import _materials_table
from tlm.scenes.loader import scenes_dir


def test_a_middle_file_s_typo_stays_its_error_under_a_file_that_only_scales_the_geometry(tmp_path, capsys):
    mid = tmp_path / "mid.yaml"
    mid.write_text("extends: examples/mesh_on_floor\ngeometry: {shape: plane, name: floor, params: {size: [4.0, 4.0]}}"
                   "\nparts: {flor: floor}\n", encoding="utf-8")
    top = tmp_path / "top.yaml"
    top.write_text("extends: mid.yaml\ngeometry: {transform: {scale: 2.0}}\n", encoding="utf-8")
    capsys.readouterr()
    assert main(["scene", "show", str(top)]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == (
        f"tlm: error: {mid}: parts.flor: the geometry has no part 'flor' (parts: floor) (did you mean 'floor'?)\n")


def test_a_user_s_edited_scenes_cornell_yaml_is_not_shown_as_the_built_in_file(tmp_path, monkeypatch):
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")  # (the copy not under the current folder: shown as it is)
    copy = tmp_path / "scenes" / "cornell.yaml"
    copy.parent.mkdir()
    shutil.copy(scenes_dir() / "cornell.yaml", copy)
    assert shown_path(str(copy)) == "scenes/cornell.yaml"  # (the same scene: the built-in's name)
    copy.write_text(copy.read_text(encoding="utf-8").replace("[0.73, 0.73, 0.73]", "[0.5, 0.5, 0.5]"),
                    encoding="utf-8")
    assert shown_paths(f"{copy}: materials.white") == f"{copy}: materials.white"
    table = _materials_table({"white": {"kind": "lambertian", "triangles": 2, "albedo": [0.5, 0.5, 0.5],
                                        "from": f"{copy}: materials.white"}})
    assert f"{copy}: materials.white" in table and "scenes/cornell.yaml" not in table.replace(str(copy), "")
    assert shown_path("/elsewhere/scenes/cornell.yaml") == "scenes/cornell.yaml"  # (a run made elsewhere: as before)


def test_the_calibrate_refusal_s_commands_run_for_a_study_named_with_a_leading_dash(tmp_path, monkeypatch, capsys):
    package = tmp_path / "venv" / "lib" / "site-packages" / "tlm"  # (an installed copy: h357's fixture)
    table = package / "arch" / "programs.yaml"
    table.parent.mkdir(parents=True)
    shutil.copy(costs.DEFAULT_PATH, table)
    monkeypatch.setattr(tlm.api_studies, "_package_dir", lambda: package)
    monkeypatch.setattr(costs, "DEFAULT_PATH", table)
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))  # (the fit's internal error's traceback file)

    def fit(*args, **kw):
        raise RuntimeError("the fit ran")

    monkeypatch.setattr(tlm.api, "calibrate", fit)
    monkeypatch.chdir(tmp_path)
    shutil.copy(Path(__file__).resolve().parents[1] / "configs" / "thesis.yaml", tmp_path / "-th.yaml")
    assert main(["calibrate", "--", "-th.yaml"]) == 2
    line = capsys.readouterr().err
    ways = re.findall(r"\((tlm calibrate .*?), or tlm\.", line)
    assert ways == ["tlm calibrate --write FILE ./-th.yaml", "tlm calibrate --dry-run ./-th.yaml"], line
    for way in ways:
        assert main(["mine.yaml" if w == "FILE" else w for w in shlex.split(way)][1:]) == 1, way
        assert "the fit ran" in capsys.readouterr().err, way
