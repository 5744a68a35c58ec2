"""Leftovers of the morning's reviews (h298).

1. A copy of a project in another folder shares its frames where the scene's mesh lies outside the
   scene's folder (``mesh: ../m/x.obj``) and its load writes a note naming the mesh: the fingerprint
   (tlm.experiments.frame_scenes.scene_fingerprint, re-exported by tlm.experiments.frames) left only the
   scene's own folder out of the notes; now every path in a note under the scene's folder or one above it
   is said relative to the scene's folder (marked_line), and a cached frame's warnings are moved to the
   copy's folders (moved_line, frames._here). Two meshes at other places still give two fingerprints.
2. tlm.scenes.compose.mesh_path and tlm.scenes.meshes.shown_path are one rule (a missing file named
   plainly; a NUL in a name is no ValueError).
3. A glTF item's transform is judged singular once (tlm.scenes.meshes._load_trimesh).
4. A study file given as a pipe (``tlm thesis <(cat ...)``) takes its relative paths from the working
   folder (tlm.config.file_folder), not from /proc/PID/fd.
5. A programs table given as a pipe (``--set arch.programs=<(cat ...)``) is read (tlm.arch.costs.load_programs),
   and what is no file to read is said as what it is, never "file not found".
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tests.test_review_h244 import _write as _gltf_with_nodes
from tlm.arch.costs import DEFAULT_PATH, load_programs
from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.experiments import frames
from tlm.experiments.frame_scenes import marked_line, moved_line, scene_fingerprint
from tlm.scenes import meshes
from tlm.scenes.compose import mesh_path
from tlm.scenes.loader import load_scene

# an L-shaped (concave) hexagon: its load notes it, naming the mesh file
ELL = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nf 2 3 4 5 6 1\n"


def _project(root: Path, mesh: str = "../m/ell.obj") -> Path:
    """A scene file ``root/a/s.yaml`` whose mesh is ``mesh`` (relative to it: outside its folder)."""
    (root / "a").mkdir(parents=True)
    file = (root / "a" / mesh).resolve()
    file.parent.mkdir(parents=True, exist_ok=True)
    file.write_text(ELL)
    (root / "a" / "s.yaml").write_text(yaml.safe_dump({
        "geometry": [{"mesh": mesh}], "default_material": "grey",
        "materials": {"grey": {"type": "lambertian", "albedo": [0.5] * 3}},
        "lights": [{"type": "point", "position": [0.3, 0.3, 2.0], "power": [1.0] * 3}],
        "camera": {"eye": [0.3, 0.3, 3.0], "target": [0.3, 0.3, 0.0], "up": [0, 1, 0], "vfov": 40.0},
        "resolution": [8, 8]}))
    return root / "a" / "s.yaml"


# ------------------------------------------------------------------ 1. the fingerprint of a copy


def test_a_copy_of_a_project_with_its_mesh_outside_the_scenes_folder_has_the_same_fingerprint(tmp_path, cache):
    """HEAD: 6aad1ebc... and 1933c322... for /tmp/h295/fp/p1 and p2 (the note's /p1/m/ell.obj kept whole).
    Two meshes of the same content at other places (``../m``, ``../n``; ``../ab``, a folder whose name
    begins with the scene folder's) stay two fingerprints: their notes name other files."""
    one, two = (load_scene(str(_project(tmp_path / p))) for p in ("p1", "deeper/p2"))
    assert any("not convex" in n for n in one.extra["notes"]), one.extra["notes"]
    assert str(tmp_path / "p1" / "m" / "ell.obj") in one.extra["notes"][0]
    assert scene_fingerprint(one) == scene_fingerprint(two)
    assert frames.scene_fingerprint is scene_fingerprint  # (the old name)
    others = [load_scene(str(_project(tmp_path / p, mesh))) for p, mesh in (("q", "../n/ell.obj"),
                                                                            ("r", "../ab/ell.obj"),
                                                                            ("s", "b/ell.obj"))]
    prints = {scene_fingerprint(s) for s in [one, *others]}
    assert len(prints) == 4, prints


def test_a_note_s_paths_are_marked_by_the_folder_they_lie_under_and_moved_to_a_copy_s():
    """The deepest folder first; a folder's name that only begins as another's is no path under it; a
    path under no folder but the root is left as it is; a path shown as a note shows it (a tab as \\t)
    is moved in that form."""
    line = "/x/p/a/s.yaml: see /x/p/m/ell.obj and /x/p/ab/c.obj, /y/z.obj, /x/p/t\\tb/u.obj"
    assert marked_line(line, "/x/p/a", tagged=False) == \
        "\0000\0s.yaml: see \0001\0m/ell.obj and \0001\0ab/c.obj, /y/z.obj, \0001\0t\\tb/u.obj"
    assert marked_line(line, "/x/p/a") == marked_line(line.replace("/x/p/", "/w/v/u/q/"), "/w/v/u/q/a")
    assert moved_line(line, "/x/p/a", "/w/q/a") == line.replace("/x/p/", "/w/q/")
    tab = "/k/t\tb/a"  # (a folder with a tab in its name, as given and as a note shows it)
    assert moved_line("/k/t\\tb/m/x.obj: n; /k/t\tb/m/x.obj", tab, "/j/a") == "/j/m/x.obj: n; /j/m/x.obj"
    assert moved_line("/k/t/a/x.obj", "/k/t/a", "/j/t\tb") == "/j/t\\tb/x.obj"
    assert moved_line("/k/t/x.obj", "/k/t/a", "/a") == "/k/t/x.obj"  # (no folder one above /a but the root)


def test_a_copy_of_a_project_reads_the_cached_frame_and_its_warning_names_the_copy_s_mesh(tmp_path, cache):
    """The copy (its mesh outside its scene's folder) renders nothing: HEAD rendered the frame again (another
    fingerprint); its warning names its own mesh file, not the first copy's."""
    got = []
    for p in ("p1", "deeper/p2"):
        cfg = config_from_dict({"scene": str(_project(tmp_path / p)), "mode": "rcast", "resolution": [8, 8]})
        got.append(frames.cached_render(cfg))
    assert [g.cached for g in got] == [False, True]
    assert got[0].key == got[1].key
    (line,) = [w for w in got[1].summary["warnings"] if "not convex" in w]
    assert line.startswith(f"{tmp_path}/deeper/p2/m/ell.obj: 1 polygon is not convex"), line
    assert got[1].summary["scene"]["source"] == str(tmp_path / "deeper" / "p2" / "a" / "s.yaml")


# ------------------------------------------------------------------ 2. one rule of a mesh's path


def test_a_mesh_path_has_one_rule_a_missing_file_named_plainly_and_a_nul_no_value_error(tmp_path):
    """shown_path kept a missing file's ``..`` (compose.plain_path, mesh_path's rule then, took it out) and raised
    a ValueError on a NUL."""
    (tmp_path / "a").mkdir()
    (tmp_path / "m.obj").write_text("v 0 0 0\n")
    (tmp_path / "link").symlink_to(tmp_path / "a")
    for given in (tmp_path / "a" / ".." / "m.obj", tmp_path / "a" / ".." / "gone.obj",
                  tmp_path / "link" / ".." / "m.obj", tmp_path / "x" / ".." / "m.obj", Path(f"{tmp_path}/./m.obj"),
                  tmp_path / "a" / "..", Path(f"{tmp_path}/a\0b/../m.obj")):
        assert meshes.shown_path(given) == mesh_path(str(given), tmp_path / "s.yaml"), given
    assert meshes.shown_path(tmp_path / "a" / ".." / "gone.obj") == tmp_path / "gone.obj"
    assert meshes.shown_path(Path(f"{tmp_path}/a\0b/../m.obj")) == Path(f"{tmp_path}/a\0b/../m.obj")
    with pytest.raises(InputError, match="mesh file not found") as info:
        meshes.load_mesh(tmp_path / "a" / ".." / "gone.obj")
    assert info.value.source == str(tmp_path / "gone.obj")


# ------------------------------------------------------------------ 3. singular() once an item


def test_an_items_transform_is_judged_singular_once(tmp_path, cache, monkeypatch):
    """A flat triangle under its node's zero scale (kept: the transform keeps it a triangle): judged twice by HEAD,
    once for the nodes to check and again as the item was placed."""
    calls = []

    def counted(m):
        calls.append(1)
        return singular(m)

    singular = meshes.singular
    monkeypatch.setattr(meshes, "singular", counted)
    g = meshes.load_mesh(_gltf_with_nodes(tmp_path, [{"mesh": 0, "scale": [1.0, 1.0, 0.0]}]))
    assert g.triangles.shape == (1, 3, 3)
    assert len(calls) == 1, calls


# ------------------------------------------------------------------ 4. a study file from a pipe


def test_a_thesis_study_from_a_pipe_looks_for_its_scenes_in_the_working_folder(tmp_path, monkeypatch, pipes):
    """HEAD looked in /proc/PID/fd (where the pipe's path leads) first, and named it."""
    from tlm.experiments.thesis import load_study

    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError) as info:
        load_study(pipes("scenes: [nope.yaml]\nmodes: [rcast]\n"))
    assert f"not found (looked in {tmp_path} and among the built-in scenes)" in str(info.value), str(info.value)
    _, scenes, _, folder = load_study(pipes("scenes: [cornell]\nmodes: [rcast]\n"), ("render.spp=1",))
    assert folder == tmp_path and scenes == ["cornell"]


def test_an_extreme_study_from_a_pipe_starts_its_paths_at_the_working_folder(tmp_path, monkeypatch, pipes):
    from tlm.experiments.extreme import load_cases

    monkeypatch.chdir(tmp_path)
    text = ("cases:\n  - {name: a, category: geometry, expect: x, config: {scene: cornell, mode: rcast}, "
            "checks: [finite]}\n")
    assert load_cases(pipes(text))[2] == tmp_path
    assert load_cases(pipes(text), ("render.spp=1",))[2] == tmp_path


# ------------------------------------------------------------------ 5. a programs table from a pipe


def test_a_programs_table_from_a_pipe_is_read_and_no_file_is_said_as_what_it_is(tmp_path, pipes):
    """HEAD: "file not found" for the pipe (not a regular file), and for a folder."""
    given = pipes(DEFAULT_PATH.read_text())
    table, default = load_programs(given), load_programs()
    assert table.source == str(given) and (table.jobs, table.scale) == (default.jobs, default.scale)
    for given, said in ((tmp_path, "is a folder, not a file"), (tmp_path / "nope.yaml", "file not found"),
                        (Path("/dev/zero"), "is a device, not a file to read")):
        with pytest.raises(InputError) as info:
            load_programs(given)
        assert str(info.value).startswith(f"{given}: arch.programs: {said}"), str(info.value)


def test_a_run_with_a_programs_table_from_a_pipe_runs(tmp_path, monkeypatch, cache, pipes):
    from tlm.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "q.yaml").write_text("scene: cornell\nmode: rcast\nresolution: [8, 8]\n")
    assert main(["run", "q.yaml", "--set", f"arch.programs={pipes(DEFAULT_PATH.read_text())}", "--out", "o",
                 "--no-progress", "--no-report"]) == 0
    assert json.loads((tmp_path / "o" / "results.json").read_text())["timing"]


# ------------------------------------------------------------------ 4. (with /tmp/h298/study.patch, error_cost.patch)


def test_a_study_file_from_a_pipe_makes_its_base_files_absolute_from_the_working_folder(tmp_path, monkeypatch,
                                                                                       pipes):
    """tlm.experiments.study.read_study made them absolute from /proc/PID/fd."""
    from tlm.experiments.study import read_study

    monkeypatch.chdir(tmp_path)
    _, base, _ = read_study(pipes("base: {arch: {programs: p.yaml}}\nscenes: [cornell]\n"), ("scenes",))
    assert base["arch"]["programs"] == str(tmp_path / "p.yaml")


def test_a_granularity_study_from_a_pipe_starts_its_paths_at_the_working_folder(tmp_path, monkeypatch, pipes):
    from tlm.experiments.granularity import load_granularity

    monkeypatch.chdir(tmp_path)
    text = "base: {scene: cornell, mode: rcast}\npacket_sizes: [16]\n"
    assert load_granularity(pipes(text))[2] == tmp_path
    assert load_granularity(pipes(text), ("render.spp=1",))[2] == tmp_path


def test_an_error_vs_cost_study_from_a_pipe_starts_its_paths_at_the_working_folder(tmp_path, monkeypatch, pipes):
    from tlm.experiments.error_cost import load_experiment

    monkeypatch.chdir(tmp_path)
    text = "base: {scene: cornell}\npoints:\n  - {photons.count: [3000]}\n"
    assert load_experiment(pipes(text))[2] == tmp_path
    assert load_experiment(pipes(text), ("render.spp=1",))[2] == tmp_path
