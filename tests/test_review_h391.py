"""h391, a review of 4d2499c (the report tables a run by its scene file, not its name).

A run's ``results.json`` records the digest of the scene file as the run read it (``scene_digest``).
Where that is not the thesis scene's, the run was not of the thesis's scene, whatever its file holds
now or wherever it is: a user's ``scenes/cornell.yaml``, edited, was still drawn as Table III beside
the thesis's numbers (comparable, at the thesis's setting) once its project folder was moved off this
machine (``table_of``'s fallback: the place under any folder named ``scenes``) or once the user put
the file back as the thesis has it (the file as it is now). The built-in thesis file itself, edited
since the run, is still its table's, as before. And a run tabled as the thesis's scene by the digest
it recorded (a copy of the thesis's file) was marked not comparable as "the scene /elsewhere/copy.yaml
(the thesis's is cornell)": its file was judged again as it is now, where it is not.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tlm.config import config_from_dict
from tlm.experiments.provenance import scene_identity
from tlm.experiments.run import run as run_experiment
from tlm.report.collect import Inputs, Run, read
from tlm.report.tables import mismatches, tables_section, thesis_table
from tlm.scenes.loader import scenes_dir

TINY = {"seed": 0, "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1}, "arch": {"trace": False},
        "mode": "rcast"}


def _with(run: Run, **results) -> Run:
    return Run(run.path, run.label, run.kind, {**run.results, **results}, run.config)


def _source(run: Run, source: str) -> Run:
    return _with(run, scene={**run.results["scene"], "source": source})


@pytest.fixture(scope="module")
def edited(tmp_path_factory):
    """A run of a user's project's ``scenes/cornell.yaml``: the thesis's Cornell box with an edit."""
    root = tmp_path_factory.mktemp("h391")
    mine = root / "proj" / "scenes" / "cornell.yaml"
    mine.parent.mkdir(parents=True)
    thesis = (scenes_dir() / "cornell.yaml").read_text(encoding="utf-8")
    assert "power: [1100000.0, 950000.0, 750000.0]" in thesis
    mine.write_text(thesis.replace("power: [1100000.0, 950000.0, 750000.0]", "power: [2e6, 2e6, 2e6]  # (my edit)"),
                    encoding="utf-8")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        run_experiment(config_from_dict({**TINY, "scene": str(mine)}, "test"), root / "run")
    (run,) = read([root / "run"]).runs
    assert run.scene == "cornell" and run.results["scene"]["source"] == str(mine)
    assert run.results.get("scene_digest")
    return run, mine, thesis


def test_a_users_edited_scenes_cornell_is_not_table_iii_when_moved_or_reverted(edited, tmp_path):
    run, mine, thesis = edited
    assert thesis_table(run) is None  # (here, as it ran: 4d2499c judged it so too)
    moved = _source(run, "/elsewhere/proj/scenes/cornell.yaml")  # (its folder read on another machine)
    assert thesis_table(moved) is None
    section = tables_section(Inputs([], runs=[moved]), tmp_path)
    assert section.absent and not section.figures
    assert any("scene 'cornell' has no table in the thesis (" in n and "is not the thesis's Cornell Box scene" in n
               for n in section.notes), section.notes
    edit = mine.read_text(encoding="utf-8")
    try:
        mine.write_text(thesis, encoding="utf-8")  # (the user puts the file back: the run was of the edit)
        assert thesis_table(run) is None
    finally:
        mine.write_text(edit, encoding="utf-8")


def test_the_built_in_thesis_file_edited_since_the_run_is_still_its_table_s(edited):
    run, _, _ = edited
    builtin = str(scenes_dir() / "cornell.yaml")
    assert thesis_table(_source(run, builtin)) == "cornell"  # (the digest of the file before its edit)
    older = _source(run, builtin)
    older.results.pop("scene_digest")  # (a run of an older tlm: by the file as it is now)
    assert thesis_table(older) == "cornell"
    gone = _source(run, "/elsewhere/tlm/scenes/cornell.yaml")
    gone.results.pop("scene_digest")  # (no digest, not here: by its place, as before)
    assert thesis_table(gone) == "cornell"
    assert thesis_table(_source(run, str(Path("/elsewhere/tlm/scenes/cornell.yaml")))) is None


def test_a_copy_tabled_by_its_recorded_digest_is_not_called_another_scene(edited, tmp_path):
    run, _, _ = edited
    copy = _with(_source(run, "/elsewhere/copy-of-cornell.yaml"),  # (a copy of the thesis's file, read elsewhere)
                 scene_digest=scene_identity(scenes_dir() / "cornell.yaml"))
    assert thesis_table(copy) == "cornell"
    said = mismatches(copy, "cornell")
    assert said and not any(m.startswith("the scene ") for m in said), said  # (its size and sampling only)
    section = tables_section(Inputs([], runs=[copy]), tmp_path)
    (figure,) = section.figures
    assert figure.title.startswith("Table III (Cornell Box scene): ours (")
    assert "copy-of-cornell" not in section.html and not any("copy-of-cornell" in n for n in section.notes)
