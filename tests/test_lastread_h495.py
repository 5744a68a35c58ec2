"""h495: last read of the session's change to tlm/.

* written.own_runs took a found run folder's study as ``folder.parent.parent``, a pure path: a search given a
  relative folder that is the scene's (``tlm report .`` in ``T/cornell``) found ``reflect``, whose parents are
  ``.`` and ``.``, so the study was never seen and a cell a rerun kept (h486) was drawn as the study's own again.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from tests.test_review_h486 import _run
from tlm.report.collect import read
from tlm.storage_carry import LISTING


def test_a_search_from_inside_a_thesis_study_leaves_out_a_kept_cell(tmp_path, cache, monkeypatch):
    study = tmp_path / "T"
    _run(study / "cornell" / "rcast", "--set", "mode=rcast")
    shutil.copytree(study / "cornell" / "rcast", study / "cornell" / "reflect")  # (an earlier study's, kept)
    (study / "thesis_comparison.csv").write_text("scene,mode\n")
    (study / LISTING).write_text("cornell\ncornell/rcast\ncornell/rcast/results.json\t1\t1\n")
    monkeypatch.chdir(study / "cornell")
    inputs = read([Path(".")])
    assert [r.path.name for r in inputs.runs] == ["rcast"]
    assert any("reflect: a thesis cell that the study" in n and str(study) in n for n in inputs.notes), inputs.notes
    monkeypatch.chdir(study)  # (the scene's folder given by a relative name: as before)
    assert [r.path.name for r in read([Path("cornell")]).runs] == ["rcast"]
