"""A sweep's points that differ only in ``arch`` share one scene load and one programs table:
the scene's fingerprint (:func:`tlm.experiments.frames.scene_key`) and the table
(:func:`tlm.arch.costs.load_programs`) are remembered in the process, by every file they read,
and read again when one of those files changes (same size and modification time too)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
import yaml

import tlm.config
import tlm.experiments.frame_keys as frame_keys
import tlm.experiments.frames as frames
from tlm.arch import costs
from tlm.config import config_from_dict
from tlm.experiments.frames import render_key
from tlm.experiments.sweep import run_sweep
from tlm.scenes.loader import scenes_dir

HOST = ("seconds.functional", "seconds.simulate", "seconds.one_off", "seconds.write",
        "functional_cached")  # (the first sweep renders)
WHITE, WHITE_EDITED = "albedo: [0.73, 0.73, 0.73]", "albedo: [0.37, 0.73, 0.73]"
SCALE, SCALE_EDITED = "scale: 7.54193", "scale: 8.54193"


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


@pytest.fixture
def loads(monkeypatch):
    """The scene loads of frames.render_key (by scene reference) and the YAML texts parsed."""
    got = {"scenes": [], "texts": []}
    load, parse = frames.load_scene, tlm.config.parse_yaml

    def counted_load(ref, *args, **kw):
        got["scenes"].append(os.fspath(ref))
        return load(ref, *args, **kw)

    def counted_parse(text):
        got["texts"].append(text)
        return parse(text)

    monkeypatch.setattr(frame_keys, "load_scene", counted_load)  # (the key's: frame_keys, h487)
    monkeypatch.setattr(frames, "load_scene", counted_load)
    monkeypatch.setattr(tlm.config, "parse_yaml", counted_parse)
    return got


def edit_in_place(path: Path, old: str, new: str) -> None:
    """Replace ``old`` by ``new`` (the same length), keeping the file's size and modification time."""
    assert len(old) == len(new)
    st = path.stat()
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert path.stat().st_size == st.st_size and path.stat().st_mtime_ns == st.st_mtime_ns


def cfg(scene: str, **more):
    return config_from_dict({"scene": scene, "mode": "rcast", "resolution": [16, 16], **more})


def test_sweep_loads_its_scene_and_table_once_and_again_after_an_edit(tmp_path, loads):
    shutil.copy(scenes_dir() / "cornell.yaml", tmp_path / "box.yaml")
    shutil.copy(costs.DEFAULT_PATH, tmp_path / "table.yaml")
    table_text = (tmp_path / "table.yaml").read_text()
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump({
        "base": {"scene": "box.yaml", "mode": "rcast", "resolution": [16, 16],
                 "render": {"spp": 1, "light_samples": 1}, "arch": {"trace": False, "programs": "table.yaml"}},
        "grid": {"arch.page_miss_cycles": [0, 12, 24]}}, sort_keys=False))

    def sweep(out: str):
        rows = run_sweep(tmp_path / "sweep.yaml", tmp_path / out, jobs=1).table
        assert (rows["status"] == "ok").all()
        return rows.drop(columns=[c for c in HOST if c in rows])

    first = sweep("a")
    # three points of one frame: the scene loaded once for its key, the table parsed once
    box = str((tmp_path / "box.yaml").resolve())  # (the sweep's config names it by its absolute path)
    assert loads["scenes"].count(box) == 1
    assert loads["texts"].count(table_text) == 1
    again = sweep("b")  # a second sweep in this process: nothing read again, the same rows
    assert loads["scenes"].count(box) == 1
    assert loads["texts"].count(table_text) == 1
    assert first.equals(again)

    edit_in_place(tmp_path / "box.yaml", WHITE, WHITE_EDITED)
    edit_in_place(tmp_path / "table.yaml", SCALE, SCALE_EDITED)
    edited = sweep("c")
    assert loads["scenes"].count(box) == 2
    assert loads["texts"].count(table_text.replace(SCALE, SCALE_EDITED, 1)) == 1
    assert (edited["hash"] != first["hash"]).all()
    assert (edited["cycles.vertex"] != first["cycles.vertex"]).all()  # (the table's edited scale)
    cold = frames.functional_key(tlm.config.to_dict(cfg("box.yaml")), frames.scene_fingerprint(
        frames.load_scene("box.yaml", tmp_path, [16, 16], None)), frames.code_fingerprint())
    assert render_key(cfg("box.yaml"), tmp_path) == cold  # (the key of the file as it is now)


def test_scene_key_reads_an_edited_scene_file_again(tmp_path, loads):
    scene = tmp_path / "box.yaml"
    shutil.copy(scenes_dir() / "cornell.yaml", scene)
    key = render_key(cfg("box.yaml"), tmp_path)
    assert render_key(cfg("box.yaml"), tmp_path) == key
    assert loads["scenes"] == ["box.yaml"]
    edit_in_place(scene, WHITE, WHITE_EDITED)
    edited = render_key(cfg("box.yaml"), tmp_path)
    assert edited != key and loads["scenes"] == ["box.yaml"] * 2
    assert render_key(cfg("box.yaml"), tmp_path) == edited and len(loads["scenes"]) == 2
    # another resolution is another load (and another key)
    assert render_key(cfg("box.yaml", resolution=[8, 8]), tmp_path) != edited and len(loads["scenes"]) == 3
    edit_in_place(scene, WHITE_EDITED, WHITE)
    assert render_key(cfg("box.yaml"), tmp_path) == key and len(loads["scenes"]) == 4


def test_scene_key_sees_the_file_an_extends_finds_now(tmp_path, monkeypatch, loads):
    """``extends: base.yaml`` looks beside the file first, then in the working folder: a base
    that appears beside it later is the one a load reads."""
    here, there = tmp_path / "cwd", tmp_path / "scenes"
    here.mkdir()
    there.mkdir()
    shutil.copy(scenes_dir() / "cornell.yaml", here / "base.yaml")
    (there / "top.yaml").write_text("extends: base.yaml\nname: top\n")
    monkeypatch.chdir(here)
    key = render_key(cfg("top.yaml"), there)
    assert render_key(cfg("top.yaml"), there) == key and loads["scenes"] == ["top.yaml"]
    (there / "base.yaml").write_text((here / "base.yaml").read_text().replace(WHITE, WHITE_EDITED))
    assert render_key(cfg("top.yaml"), there) != key and len(loads["scenes"]) == 2
    # the base itself edited in place is read again too (the first base's content, but another file gives its
    # materials, which the frame's results.json names: another frame, remembered)
    edit_in_place(there / "base.yaml", WHITE_EDITED, WHITE)
    again = render_key(cfg("top.yaml"), there)
    assert again != key and len(loads["scenes"]) == 3
    assert render_key(cfg("top.yaml"), there) == again and len(loads["scenes"]) == 3


OBJ = "mtllib part.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nusemtl paint\nf 1 2 3\nf 2 4 3\n"
MTL = "newmtl paint\nKd 0.50 0.50 0.50\n"
SCENE = """geometry:
  - mesh: part.obj
lights:
  - {type: point, position: [0.5, 0.5, 2.0], power: [10.0, 10.0, 10.0]}
camera: {eye: [0.5, 0.5, 3.0], target: [0.5, 0.5, 0.0], vfov: 40}
"""


def test_scene_key_reads_an_edited_mesh_or_material_library_again(tmp_path, loads):
    (tmp_path / "part.obj").write_text(OBJ)
    (tmp_path / "part.mtl").write_text(MTL)
    (tmp_path / "mesh.yaml").write_text(SCENE)
    key = render_key(cfg("mesh.yaml"), tmp_path)
    assert render_key(cfg("mesh.yaml"), tmp_path) == key and len(loads["scenes"]) == 1
    edit_in_place(tmp_path / "part.mtl", "Kd 0.50", "Kd 0.25")
    by_library = render_key(cfg("mesh.yaml"), tmp_path)
    assert by_library != key and len(loads["scenes"]) == 2
    edit_in_place(tmp_path / "part.obj", "v 1 1 0", "v 1 2 0")
    assert render_key(cfg("mesh.yaml"), tmp_path) not in (key, by_library) and len(loads["scenes"]) == 3
    assert render_key(cfg("mesh.yaml"), tmp_path) is not None and len(loads["scenes"]) == 3


def test_scene_memo_keeps_a_few_scenes(tmp_path, loads):
    for i in range(frames.MEMO_SIZE + 2):
        (tmp_path / f"s{i}.yaml").write_text(f"extends: cornell\nname: s{i}\n")
        render_key(cfg(f"s{i}.yaml"), tmp_path)
    assert len(frame_keys._SCENE_KEYS) == frames.MEMO_SIZE
    n = len(loads["scenes"])
    render_key(cfg(f"s{frames.MEMO_SIZE + 1}.yaml"), tmp_path)  # the last: remembered
    assert len(loads["scenes"]) == n
    render_key(cfg("s0.yaml"), tmp_path)  # the first: forgotten, loaded again
    assert len(loads["scenes"]) == n + 1


def test_a_caller_cannot_change_the_remembered_table(tmp_path, loads):
    table = tmp_path / "table.yaml"
    shutil.copy(costs.DEFAULT_PATH, table)
    text = table.read_text()
    first = costs.load_programs(table)
    scale = first.scale["vertex"]
    first.scale["vertex"] = 99.0
    first.jobs["vertex", "geometry_bsp"].instructions.clear()
    first.calibration["changed"] = True
    second = costs.load_programs(table)
    assert loads["texts"].count(text) == 1  # (remembered: not parsed again)
    assert second.scale["vertex"] == scale and second.jobs["vertex", "geometry_bsp"].instructions
    assert "changed" not in second.calibration
    assert second is not first and second == costs.load_programs(table)


def test_an_edited_table_is_read_again_and_its_errors_still_name_it(tmp_path, loads):
    table = tmp_path / "table.yaml"
    shutil.copy(costs.DEFAULT_PATH, table)
    scale = costs.load_programs(table).scale["vertex"]
    costs.load_programs(table)
    assert len([t for t in loads["texts"] if SCALE in t]) == 1
    edit_in_place(table, SCALE, SCALE_EDITED)
    assert costs.load_programs(table).scale["vertex"] == pytest.approx(scale + 1.0)
    assert len([t for t in loads["texts"] if SCALE_EDITED in t]) == 1
    edit_in_place(table, SCALE_EDITED, "scale: -7.5419")  # a bad table after a good one: its error
    with pytest.raises(tlm.config.InputError, match=r"table\.yaml.*vertex\.scale"):
        costs.load_programs(table)
