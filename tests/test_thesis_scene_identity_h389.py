"""h389: a scene is a thesis table's by its file, not by its name.

A user's ``room.yaml`` (no ``name:``: named ``room`` by its file's stem) was drawn in the report as
"Table II (Room scene)" beside the thesis's numbers, its cells marked "n/c": the report chose the
table by the scene's name. It now leaves such a run out of the tables with the note a scene without
a thesis table gets, saying it is not the thesis's Room; a run of the built-in thesis scene is tabled
as before, whether its ``results.json`` is as tlm writes it now (``scene_digest``) or as an older
tlm wrote it (no digest). Also: ``tlm scene export``'s summary says "besides emitting materials"
only for a scene that has some, and an MTL statement given twice points to a scene file's
``materials:`` entry rather than asking to edit the (published) MTL file.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tlm.config import config_from_dict
from tlm.experiments.run import run as run_experiment
from tlm.experiments.thesis import PM_METRICS
from tlm.report.collect import Inputs, Run, Study, read
from tlm.report.tables import collect_sources, study_summaries, tables_section, thesis_table
from tlm.scenes.loader import scenes_dir
from tlm.scenes.materials import parse_mtl

TINY = {"seed": 0, "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1}, "photons": {"count": 2000},
        "arch": {"trace": False}}
USER_ROOM = ("geometry: [{shape: plane, params: {size: [4, 4]}}]\n"
             "materials: {g: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\ndefault_material: g\n"
             "lights: [{type: point, position: [0, 2, 0], power: [10, 10, 10]}]\n"
             "camera: {eye: [0, 1, -5], target: [0, 0, 0], vfov: 40}\nresolution: [16, 16]\n")
NOTE = "has no table in the thesis ({} is not the thesis's Room scene, thesis/room), left out of the tables"


def _run(scene: str, out: Path) -> Run:
    run_experiment(config_from_dict({**TINY, "scene": scene, "mode": "rcast"}, "test"), out)
    (run,) = read([out]).runs
    return run


def _older(run: Run) -> Run:
    """The run as an older tlm wrote it: no ``scene_digest`` in its results.json."""
    results = {k: v for k, v in run.results.items() if k != "scene_digest"}
    return Run(run.path, run.label, run.kind, results, run.config)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("h389")
    mine = root / "proj"
    mine.mkdir()
    (mine / "room.yaml").write_text(USER_ROOM)  # (no name: it is named room by its stem)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        got = {"user": _run(str(mine / "room.yaml"), root / "user"), "ring": _run("thesis/ring", root / "ring"),
               "builtin-room": _run("room", root / "builtin-room")}
    return got


def test_a_users_room_yaml_is_not_table_ii(runs, tmp_path):
    user = runs["user"]
    assert user.scene == "room" and user.results.get("scene_digest")  # (named room; as tlm writes it now)
    for run in (user, _older(user)):  # (and as an older tlm wrote it: judged by its file, here on this machine)
        assert thesis_table(run) is None
        section = tables_section(Inputs([], runs=[run]), tmp_path)
        assert section.absent and not section.figures and not section.html
        assert f"{run.label}: scene 'room' {NOTE.format(run.scene_label)}" in section.notes, section.notes


def test_the_built_in_room_is_not_the_thesis_s_room_either(runs, tmp_path):
    room = runs["builtin-room"]
    assert room.scene == "room" and thesis_table(room) is None
    section = tables_section(Inputs([], runs=[room]), tmp_path)
    assert section.absent and f"{room.label}: scene 'room' {NOTE.format('room')}" in section.notes


def test_the_thesis_s_own_scene_is_tabled_from_new_and_older_results(runs, tmp_path):
    ring = runs["ring"]
    for run in (ring, _older(ring)):
        assert thesis_table(run) == "ring"
        section = tables_section(Inputs([], runs=[run]), tmp_path)
        assert not section.absent and [f.title for f in section.figures] == [
            "Table I (Scene with ring): ours (thesis/ring) against the thesis"]
        assert not any("has no table" in n for n in section.notes)


def test_a_run_made_elsewhere_is_judged_by_its_recorded_digest_else_its_place(runs, tmp_path):
    """Its scene file not on this machine: the digest it recorded, where that is the built-in's, makes it
    the thesis's scene; an older run of the built-in scene (no digest) by its place under ``scenes/``; a
    user's room by neither."""
    ring, user = runs["ring"], runs["user"]

    def moved(run: Run, source: str, digest: bool) -> Run:
        results = {**run.results, "scene": {**run.results["scene"], "source": source}}
        if not digest:
            results.pop("scene_digest", None)
        return Run(run.path, run.label, run.kind, results, run.config)

    assert thesis_table(moved(ring, "/elsewhere/copy-of-ring.yaml", digest=True)) == "ring"
    assert thesis_table(moved(ring, "/elsewhere/tlm/scenes/thesis/ring.yaml", digest=False)) == "ring"
    assert thesis_table(moved(user, "/elsewhere/proj/room.yaml", digest=True)) is None
    assert thesis_table(moved(user, "/elsewhere/proj/room.yaml", digest=False)) is None


def _study_inputs(root: Path, sources: dict[str, Path], cells: bool = True, meta: dict | None = None) -> Inputs:
    """A thesis study (rows named by the scene files' stems, as ``tlm thesis`` names them), with its cells."""
    runs, rows = [], []
    for name, source in sources.items():
        for mode in ("rcast", "reflect"):
            scene = {"name": name, "source": str(source), "resolution": [16, 16]}
            runs.append(Run(root / name / mode, f"{name}/{mode}", "thesis", {"scene": scene, "mode": mode}, {}))
            rows += [{"scene": name, "mode": mode, "metric": m, "thesis": 10.0, "ours": 11.0, "rel_error": 0.1,
                      "calibrated": False} for m in (*PM_METRICS, "TThru", "FPS")]
    return Inputs([root], runs=runs if cells else [], studies=[Study("thesis", root, rows, meta or {})])


def test_a_thesis_study_of_a_users_room_tables_only_the_thesis_s_scenes(tmp_path):
    user = tmp_path / "proj" / "room.yaml"
    user.parent.mkdir()
    user.write_text(USER_ROOM)
    copy = tmp_path / "copy" / "ring.yaml"
    copy.parent.mkdir()
    shutil.copy(scenes_dir() / "thesis" / "ring.yaml", copy)  # (the thesis's ring, by its bytes)
    root = tmp_path / "study"
    inputs = _study_inputs(root, {"ring": copy, "room": user})
    notes: list[str] = []
    sources = collect_sources(inputs, notes)
    assert set(sources) == {"ring"}
    assert any("scene" in n and "has no table in the thesis (not the thesis's Room scene, thesis/room)" in n
               for n in notes), notes
    ((_, summary),) = study_summaries(inputs, sources)
    # (the user's room's rows count in none of the study's figures: they are not the thesis's Table II)
    assert summary["held_out_cells"] == 12 and set(summary["slowest_pm"]) == {f"{copy}/rcast", f"{copy}/reflect"}
    assert str(user) not in json.dumps(summary)
    # its cell folders gone: what the study said when it ran (the scene file not the thesis's) decides
    said = {"not_comparable": {"room": [f"the scene {user} (the thesis's is thesis/room)"]}}
    gone = _study_inputs(root, {"ring": copy, "room": user}, cells=False, meta=said)
    assert set(collect_sources(gone, [])) == {"ring"}


def test_scene_export_says_emitting_materials_only_where_some_emit(tmp_path, capsys):
    from tlm.cli import main

    assert main(["scene", "export", "cornell", str(tmp_path / "c.yaml")]) == 0  # (a quad light, nothing emits)
    out = capsys.readouterr().out
    assert "(the scene file: 1 light, the camera, " in out and "emitting" not in out
    assert main(["scene", "export", "cornell-box", str(tmp_path / "b.yaml")]) == 0  # (its light is a material)
    assert "(the scene file: 0 lights besides emitting materials, the camera, " in capsys.readouterr().out


def test_a_statement_given_twice_points_to_a_scene_file_s_materials_entry():
    notes: list[str] = []
    parse_mtl("newmtl mesh29_SG\nKd 0.286275 0.149020 0.129412\nKd 1 1 1\n", "conference.mtl", notes)
    (note,) = notes
    assert note.endswith("the last is used, as OBJ readers (trimesh, tinyobjloader) take it (another value: a scene "
                         "file's `materials: {mesh29_SG: ...}` entry, the MTL file left as it is)")
    assert "give it once" not in note
