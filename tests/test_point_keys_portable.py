"""A sweep point's key (:func:`tlm.experiments.sweep_file.config_hash`) and a frame's cache key
(:func:`tlm.experiments.frames.functional_key`) do not depend on where the project lies: a
config holds its scene file and programs table as absolute paths (so that a worker and a rerun
from anywhere read the same files), but the keys hold the files' content and, for the points,
their paths from the sweep file's folder. The same project in two folders (moved, copied,
another user's checkout) reuses its finished points and its rendered frames; two files still
differ, and two files of one content that a sweep lists stay two points."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml

from tlm.api import load_config
from tlm.errors import InputError
from tlm.experiments.frames import render_key
from tlm.experiments.sweep_file import config_hash, load_sweep, point_inputs
from tlm.scenes.loader import scenes_dir

TINY = {"mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1}, "arch": {"trace": False}}
PROGRAMS = Path(__file__).resolve().parents[1] / "tlm" / "arch" / "programs.yaml"


def _box(path: Path, wall_div: int = 1) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    text = (scenes_dir() / "cornell.yaml").read_text()
    path.write_text(text.replace("params: {}", f"params: {{wall_div: {wall_div}}}") if wall_div > 1 else text)
    return path


@pytest.fixture
def two_copies(tmp_path, monkeypatch):
    """``a/proj`` and ``b/elsewhere/proj``, one project: a config naming its scene and its
    programs table by relative paths, a sweep over it and over a scene beside the sweep file,
    and a working folder that is neither."""
    proj = tmp_path / "a" / "proj"
    _box(proj / "myscenes" / "box.yaml")
    _box(proj / "study" / "box2.yaml", wall_div=2)
    (proj / "configs").mkdir()
    shutil.copy(PROGRAMS, proj / "configs" / "table.yaml")
    (proj / "configs" / "x.yaml").write_text(yaml.safe_dump(
        {**TINY, "scene": "../myscenes/box.yaml", "arch": {**TINY["arch"], "programs": "table.yaml"}}))
    (proj / "study" / "sw.yaml").write_text(yaml.safe_dump(
        {"base": "../configs/x.yaml", "grid": {"scene": ["../myscenes/box.yaml", "box2.yaml", "cornell"],
                                                "arch.fifo_depth": [1, 2]}}, sort_keys=False))
    other = tmp_path / "b" / "elsewhere" / "proj"
    shutil.copytree(proj, other)
    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    return proj, other


def test_the_same_sweep_in_two_folders_has_the_same_point_keys(two_copies):
    """It failed: the keys held the absolute paths (``817d44...`` in one folder, ``be9862...`` in
    the other), so a moved project ran every finished point again."""
    one, two = (load_sweep(p / "study" / "sw.yaml") for p in two_copies)
    assert [p.config["scene"] for p in one.points[:2]] == [str(two_copies[0] / "myscenes" / "box.yaml")] * 2
    assert one.points[0].config["arch"]["programs"] == str(two_copies[0] / "configs" / "table.yaml")
    assert [p.config["scene"] for p in two.points[:2]] == [str(two_copies[1] / "myscenes" / "box.yaml")] * 2
    assert [p.hash for p in one.points] == [p.hash for p in two.points]
    assert [p.functional for p in one.points] == [p.functional for p in two.points]
    assert len({p.hash for p in one.points}) == 6  # (three scenes, two depths: six points)
    for sweep in (one, two):  # (config_hash of a point's config, from the sweep file's folder, is its key:
        p = sweep.points[2]  # with arch.trace as true, as a point's key holds it where no factor gives it)
        inputs = point_inputs(load_config(p.config).settings, sweep.folder, "test")
        keyed = {**p.config, "arch": {**p.config["arch"], "trace": True}}
        assert p.config["arch"]["trace"] is False
        assert config_hash(keyed, inputs, sweep.path.resolve().parent) == p.hash


def test_the_same_config_in_two_folders_shares_its_frame(two_copies):
    """It failed: ``render_key`` held the absolute scene path (the frame cache missed)."""
    a, b = (load_config(str(p / "configs" / "x.yaml")) for p in two_copies)
    assert a.settings.scene != b.settings.scene
    assert render_key(a.settings, a.base) == render_key(b.settings, b.base)


def test_two_files_still_differ(two_copies, tmp_path):
    """Other content: other keys. One content in two files a sweep lists: two points (the
    user asked for both, and each result names its own file), and two frame keys where the
    files' names differ (a result names the scene by its file); each the same in both copies."""
    for proj in two_copies:
        shutil.copy(proj / "myscenes" / "box.yaml", proj / "study" / "same.yaml")
        (proj / "study" / "sw2.yaml").write_text(yaml.safe_dump(
            {"base": "../configs/x.yaml", "grid": {"scene": ["../myscenes/box.yaml", "same.yaml"]}}))
    sweeps = [load_sweep(proj / "study" / "sw.yaml") for proj in two_copies]
    assert sweeps[0].points[0].functional != sweeps[0].points[2].functional  # (box.yaml, box2.yaml: other meshes)
    same = [load_sweep(proj / "study" / "sw2.yaml") for proj in two_copies]
    assert len(same[0].points) == 2 and same[0].points[0].hash != same[0].points[1].hash
    assert same[0].points[0].functional != same[0].points[1].functional
    assert [p.hash for p in same[0].points] == [p.hash for p in same[1].points]
    # a built-in scene keeps its name in both keys: the same key wherever its config lies
    for name in ("c1", "c2"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "run.yaml").write_text(yaml.safe_dump({**TINY, "scene": "cornell"}))
    c1, c2 = (load_config(str(tmp_path / n / "run.yaml")) for n in ("c1", "c2"))
    assert c1.settings.scene == "cornell" and render_key(c1.settings, c1.base) == render_key(c2.settings, c2.base)


def test_one_file_named_two_ways_is_one_run(two_copies):
    """``box2.yaml`` and ``./box2.yaml`` are one file once read (one absolute path, one key):
    said so, not blamed on render.threads (it said ``differ only in scene (render.threads
    changes no result ...)``)."""
    proj = two_copies[0]
    (proj / "study" / "sw3.yaml").write_text(yaml.safe_dump(
        {"base": "../configs/x.yaml", "grid": {"scene": ["box2.yaml", "./box2.yaml"]}}))
    with pytest.raises(InputError) as e:
        load_sweep(proj / "study" / "sw3.yaml")
    assert str(e.value) == (f"{proj / 'study' / 'sw3.yaml'}: scene: points 0 and 1 are one run: box2.yaml and "
                            "./box2.yaml name one file, given twice")


def test_a_frame_shared_by_two_copies_names_each_copys_own_scene_file(two_copies, cache):
    """The second copy's config finds the first copy's cached frame; its summary (what its
    results.json and a sweep's row say) names the second copy's scene file, not the first's."""
    from tlm.experiments.frames import cached_render

    a, b = (load_config(str(p / "configs" / "x.yaml")) for p in two_copies)
    first = cached_render(a.settings, a.base)
    second = cached_render(b.settings, b.base)
    assert not first.cached and second.cached
    assert first.summary["scene"]["source"] == str(two_copies[0] / "myscenes" / "box.yaml")
    assert second.summary["scene"]["source"] == str(two_copies[1] / "myscenes" / "box.yaml")


def test_two_scenes_of_one_file_name_differing_in_their_name_do_not_share_a_frame(tmp_path, monkeypatch):
    """A/box.yaml and B/box.yaml differ in ``name:`` alone: a frame key holds the file's name and
    the scene's content, so the name is in the content (a shared frame said the first one's name)."""
    for sub, name in (("A", "box_A"), ("B", "box_B")):
        path = _box(tmp_path / sub / "box.yaml")
        path.write_text(f"name: {name}\n" + "\n".join(line for line in path.read_text().splitlines()
                                                       if not line.startswith("name:")) + "\n")
        (tmp_path / sub / "run.yaml").write_text(yaml.safe_dump({**TINY, "scene": "box.yaml"}))
    monkeypatch.chdir(tmp_path)
    a, b = (load_config(str(tmp_path / sub / "run.yaml")) for sub in ("A", "B"))
    assert render_key(a.settings, a.base) != render_key(b.settings, b.base)


def test_a_copys_shared_frame_warns_of_its_own_files(tmp_path, monkeypatch, cache):
    """An OBJ's note names its file; the copy that finds the first copy's frame says its own."""
    from tlm.experiments.frames import cached_render

    for sub in ("one", "two"):
        (tmp_path / sub).mkdir()
        (tmp_path / sub / "tri.obj").write_text("v -1 0 -1 0.8 0.1 0.1\nv 1 0 -1 0.8 0.1 0.1\nv 0 0 1 0.8 0.1 0.1\n"
                                                "f 1 2 3\n")
        (tmp_path / sub / "s.yaml").write_text(
            "geometry: {mesh: tri.obj}\ndefault_material: m\n"
            "materials: {m: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n"
            "lights: [{type: point, position: [0, 3, 0], power: [50, 50, 50]}]\n"
            "camera: {eye: [0, 3, -3], target: [0, 0, 0], vfov: 40}\nresolution: [8, 8]\n")
        (tmp_path / sub / "run.yaml").write_text(yaml.safe_dump({**TINY, "scene": "s.yaml"}))
    monkeypatch.chdir(tmp_path)
    a, b = (load_config(str(tmp_path / sub / "run.yaml")) for sub in ("one", "two"))
    first, second = cached_render(a.settings, a.base), cached_render(b.settings, b.base)
    assert second.cached and first.key == second.key
    said = [w for w in second.summary["warnings"] if "tri.obj" in w]
    assert said and all(str(tmp_path / "two") in w and str(tmp_path / "one") not in w for w in said), said
