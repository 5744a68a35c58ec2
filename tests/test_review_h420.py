"""h420: the report matches a thesis study's cells to its rows by their folder, not the name in the scene file.

Since h412 a study may list two scenes whose files name them alike: the built-in ``ring`` beside
``thesis/ring`` (rows and folders ``ring-2`` and ``ring``, both scenes named ``ring`` in their files), or a
user's ``mine.yaml`` whose scene is named ``ring``. The report took a row's cells by that name
(``tlm/report/tables.py``, :meth:`tlm.report.collect.Inputs.study_scene`): Table I took the other scene's
cell too (its caption listing both, its not-comparable words the other's), or, with the other's folder
first, was dropped as "no table". Now a row's cells are those of its folder ``DIR/<row>/<mode>``, as every
tlm has written them; a cell in a folder no row names is still found by its scene's name.

Reviewing h412's naming rule (:func:`tlm.experiments.thesis.scene_keys`): a scene ``report.yaml`` wrote its cells
to ``DIR/report``, the study's report folder, so ``tlm thesis`` wrote the study and then refused its report, exit 2.
Its key is now ``report-2``, as a stem another scene has is numbered.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.report.collect import read
from tlm.report.tables import collect_sources, study_summaries
from tlm.scenes.loader import scenes_dir

TINY = {"seed": 0, "resolution": [8, 8], "render": {"light_samples": 1, "spp": 1}, "photons": {"count": 500},
        "arch": {"trace": False}}


def _thesis(tmp_path: Path, scenes: list[str]) -> Path:
    """A thesis study of ``scenes`` (rcast) run into ``tmp_path/out``, without its report."""
    shutil.copy(scenes_dir() / "ring.yaml", tmp_path / "mine.yaml")  # (another file whose scene is named ring)
    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump({"base": TINY, "scenes": scenes, "modes": ["rcast"]}), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["thesis", str(study), "--out", str(out), "--no-progress", "--no-report"]) == 0
    return out


@pytest.mark.parametrize("scenes, other, folder", [
    (["ring", "thesis/ring"], "ring", "ring-2"),  # (the built-in ring's folder sorts after thesis/ring's)
    (["mine.yaml", "thesis/ring"], "mine.yaml", "mine"),  # (its folder sorts first: Table I was dropped)
])
def test_table_i_takes_its_own_cells_only(tmp_path, cache, scenes, other, folder):
    out = _thesis(tmp_path, scenes)
    assert (out / folder / "rcast" / "results.json").is_file() and (out / "ring" / "rcast").is_dir()
    inputs = read([out])
    notes: list[str] = []
    sources = collect_sources(inputs, notes)
    assert set(sources) == {"ring"}, notes
    (src,) = sources["ring"]
    assert [r.path.parent.name for r in src.runs] == ["ring"] and src.scene_label == "thesis/ring"
    assert not any("the scene" in w for w in src.not_comparable), src.not_comparable  # (not the other's words)
    (study,) = inputs.of_kind("thesis")
    assert inputs.study_scene(study, "ring") == "thesis/ring" and inputs.study_scene(study, folder) == other
    assert f"out: scene '{other}' has no table in the thesis (not the thesis's Scene with ring, thesis/ring), " \
           "left out of the tables" in notes, notes
    ((_, summary),) = study_summaries(inputs, sources)
    assert set(summary["not_comparable"]) == {"thesis/ring"}


def test_a_cell_in_a_folder_no_row_names_is_found_by_its_scene_s_name(tmp_path, cache):
    out = _thesis(tmp_path, ["thesis/ring"])
    (out / "ring").rename(out / "renamed")  # (a folder renamed by hand: found as before, by the name in its file)
    inputs = read([out])
    (src,) = collect_sources(inputs, [])["ring"]
    assert [r.path.parent.name for r in src.runs] == ["renamed"]
    assert inputs.study_scene(inputs.of_kind("thesis")[0], "ring") == "thesis/ring"


def test_a_scene_named_report_is_not_written_where_the_study_s_report_goes(tmp_path, cache, capsys):
    (tmp_path / "report.yaml").write_text((scenes_dir() / "ring.yaml").read_text(encoding="utf-8"), encoding="utf-8")
    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump({"base": TINY, "scenes": ["report.yaml"], "modes": ["rcast"]}), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["thesis", str(study), "--out", str(out), "--no-progress"]) == 0, capsys.readouterr().err
    assert (out / "report-2" / "rcast" / "results.json").is_file() and (out / "report" / "report.html").is_file()
    assert not (out / "report" / "rcast").exists()
    summary = json.loads((out / "thesis_summary.json").read_text())
    assert summary["scenes"] == {"report-2": "report.yaml"}
    assert inputs_scene(out, "report-2") == "report.yaml"


def inputs_scene(out: Path, scene: str) -> str:
    inputs = read([out])
    return inputs.study_scene(inputs.of_kind("thesis")[0], scene)
