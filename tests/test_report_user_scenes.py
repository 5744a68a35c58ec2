"""A user's own scene file named like a built-in one is not named as the built-in in the report.

A user exports the built-in ``cornell`` into their project's ``scenes/`` folder and edits it
(``scenes/cornell.yaml``, named ``cornell.yaml`` by a config beside it). The report named it
``cornell``, exactly as the built-in, because it took any file under a folder called
``scenes`` for the built-in file of another checkout: two scenes under one name, no note
that they share it, one set of rows in the tables for both. Such a file on this machine is
the built-in now only where its content is; and a name that stands for two scene files of
different content on this machine is split, the other file named by its path.

The run folders are made by hand (the files and keys the report reads, at 16x16).
"""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from tlm.report import scenes_note
from tlm.report.collect import read
from tlm.report.tables import tables_section
from tlm.scenes.loader import scenes_dir

PMS = ("vertex", "traversal", "intersection", "fragment")


def _run(folder: Path, source: Path | str, ref: str) -> Path:
    """A run folder of the scene file ``source`` (its ``name: cornell``), its config naming it ``ref``."""
    unit = {"T_norm": 1000, "T_ms": 0, "T_ps": 0, "idle": 0, "elapsed": 1000, "stall": {},
            "fractions": {"busy": 1.0}}
    cycles = {"vertex": 10, "traversal": 1000, "intersection": 900, "fragment": 100, "throughput": 1000,
              "latency": 2000}
    results = {"scene": {"name": "cornell", "source": str(source), "resolution": [16, 16], "triangles": 2604},
               "mode": "rcast", "fps": 10.0, "cycles": cycles,
               "timing": {"frames": 1, "units": {f"pipe0.{pm}": dict(unit) for pm in PMS}}}
    folder.mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps(results))
    (folder / "config.resolved.yaml").write_text(yaml.safe_dump({"scene": ref, "mode": "rcast"}))
    return folder


def _scene_copy(folder: Path, edit: bool) -> Path:
    """The built-in cornell.yaml copied into ``folder``, its light's power doubled if ``edit``."""
    text = (scenes_dir() / "cornell.yaml").read_text()
    if edit:
        assert "power: [1100000.0," in text
        text = text.replace("power: [1100000.0,", "power: [2200000.0,", 1)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "cornell.yaml").write_text(text)
    return folder / "cornell.yaml"


def test_a_users_edited_scenes_cornell_is_not_the_builtin_cornell(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    edited = _scene_copy(tmp_path / "proj" / "scenes", edit=True)
    copied = _scene_copy(tmp_path / "other" / "scenes", edit=False)
    runs = tmp_path / "runs"
    _run(runs / "builtin", scenes_dir() / "cornell.yaml", "cornell")
    _run(runs / "mine", edited, "cornell.yaml")  # (scenes/mine.yaml says scene: cornell.yaml)
    _run(runs / "copy", copied, "cornell.yaml")  # the built-in's bytes: the built-in scene
    _run(runs / "elsewhere", "/tmp/someone-elses-checkout/scenes/cornell.yaml", "cornell.yaml")  # not on this machine
    inputs = read([runs])
    labels = {r.path.name: r.scene_label for r in inputs.runs}
    assert labels == {"builtin": "cornell", "mine": "cornell.yaml", "copy": "cornell", "elsewhere": "cornell"}
    assert {r.label for r in inputs.runs} == {"builtin: cornell/rcast", "mine: cornell.yaml/rcast",
                                              "copy: cornell/rcast", "elsewhere: cornell/rcast"}
    # the report says that two scenes here share the name in their files
    assert inputs.shared_names() == [("cornell", ["cornell", "cornell.yaml"])]
    assert "the name in the files of cornell and cornell.yaml" in scenes_note(inputs)
    # Table III is of the built-in file's runs alone: the edited one is not the thesis's scene (h389: by its
    # file, it has no table in the thesis), not one "cornell" for two files
    section = tables_section(inputs, tmp_path)
    assert [f.title for f in section.figures] == ["Table III (Cornell Box scene): ours (cornell) against the thesis"]
    assert ("mine: cornell.yaml/rcast: scene 'cornell' has no table in the thesis (cornell.yaml is not the thesis's "
            "Cornell Box scene, cornell), left out of the tables") in section.notes


def test_a_builtin_name_for_two_different_files_here_is_split(tmp_path, monkeypatch):
    """``scene: cornell`` loaded from two scenes folders on this machine (this installation's,
    and another checkout's, edited, where a Dask worker ran a point): one name for two scenes.
    This installation's file keeps the name; the other is named by its path. A file that is not
    on this machine cannot be compared: it keeps the built-in name."""
    monkeypatch.chdir(tmp_path)
    other = _scene_copy(tmp_path / "worker" / "scenes", edit=True)
    runs = tmp_path / "runs"
    _run(runs / "here", scenes_dir() / "cornell.yaml", "cornell")
    _run(runs / "worker", other, "cornell")
    _run(runs / "elsewhere", "/tmp/someone-elses-checkout/scenes/cornell.yaml", "cornell")
    inputs = read([runs])
    labels = {r.path.name: r.scene_label for r in inputs.runs}
    assert labels == {"here": "cornell", "worker": "worker/scenes/cornell.yaml", "elsewhere": "cornell"}
    assert inputs.shared_names() == [("cornell", ["cornell", "worker/scenes/cornell.yaml"])]
    # the same file twice, or a byte copy of the built-in one, is one scene: nothing split
    (tmp_path / "worker" / "scenes" / "cornell.yaml").write_text((scenes_dir() / "cornell.yaml").read_text())
    inputs = read([runs])
    assert {r.scene_label for r in inputs.runs} == {"cornell"} and inputs.shared_names() == []
