"""h433: a thesis study works out its scenes' keys once (:func:`tlm.experiments.thesis_setting.scene_keys`, which
reads every scene file to judge its table by its bytes). ``tlm thesis`` ran it three times (``load_study``'s check,
the rows' keys, the report's names: ``scene_names``) and ``tlm calibrate`` twice; now the study's load gives the
keys it worked out to the rows, the names and the fit."""

from __future__ import annotations

import shutil

import pytest
import yaml

from tlm.experiments import thesis
from tlm.scenes.loader import scenes_dir

TINY = {"seed": 0, "resolution": [8, 8], "render": {"light_samples": 1, "spp": 1}, "photons": {"count": 500},
        "arch": {"frames": 2, "trace": False}}


@pytest.fixture
def counted(monkeypatch) -> list:
    """The calls of scene_keys from tlm.experiments.thesis from now on, one item each (its arguments)."""
    calls, real = [], thesis.scene_keys

    def counting(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(thesis, "scene_keys", counting)
    return calls


def _study(tmp_path, scenes: list[str]):
    shutil.copy(scenes_dir() / "thesis" / "ring.yaml", tmp_path / "myring.yaml")  # (Table I's scene, by its bytes)
    shutil.copy(scenes_dir() / "ring.yaml", tmp_path / "mine.yaml")  # (no table's, its scene named ring)
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump({"base": TINY, "scenes": scenes, "modes": ["rcast"]}), encoding="utf-8")
    return path


def test_a_thesis_study_works_out_its_scene_keys_once(tmp_path, cache, counted):
    path = _study(tmp_path, ["myring.yaml", "mine.yaml", "cornell"])
    done = thesis.run_thesis(path, tmp_path / "out")
    assert len(counted) == 1, counted  # (was 3: load_study's, run_thesis's and scene_names')
    # (what the keys give, as they gave it: the copy is Table I's, named ring; the user's ring has none)
    assert done["names"] == {"ring": "myring.yaml", "mine": "mine.yaml", "cornell": "cornell"}
    assert done["summary"]["scenes"] == done["names"] and list(done["summary"]["no_table"]) == ["mine"]
    assert {r["scene"] for r in done["rows"]} == {"ring", "mine", "cornell"}
    assert all(r["thesis"] is None for r in done["rows"] if r["scene"] == "mine")
    assert all((tmp_path / "out" / key / "rcast" / "results.json").is_file() for key in done["names"])


class _Stop(Exception):
    pass


def test_calibrate_works_out_its_scene_keys_once(tmp_path, counted, monkeypatch):
    def stop(*args, **kwargs):  # (the first step after the keys: no render needed to count them)
        raise _Stop

    monkeypatch.setattr(thesis, "programs_for", stop)
    with pytest.raises(_Stop):
        thesis.calibrate(_study(tmp_path, ["myring.yaml", "cornell"]))
    assert len(counted) == 1, counted  # (was 2: load_study's and calibrate's own)


def test_scene_names_work_out_the_keys_where_none_are_given(tmp_path, counted):
    path = _study(tmp_path, ["myring.yaml", "mine.yaml"])
    names = thesis.scene_names(["myring.yaml", "mine.yaml"], tmp_path, str(path))
    assert names == {"ring": "myring.yaml", "mine": "mine.yaml"} and len(counted) == 1
    keys = {"myring.yaml": ("ring", "ring"), "mine.yaml": ("mine", None)}
    assert thesis.scene_names(["myring.yaml", "mine.yaml"], tmp_path, str(path), keys) == names
    assert len(counted) == 1  # (given: not worked out again)
