"""h393: a sweep point's ``results.json`` records its scene's digest (``scene_digest``), as a run's does.

Before, a point recorded none, and the report judged it by its scene file as it is now (h391): a user's edited
``scenes/cornell.yaml`` swept, its folder then moved off this machine, was tabled as Table III by its place
under a ``scenes`` folder, and a point's scene file edited after the sweep was judged by its new bytes. Now a
point records :func:`~tlm.experiments.provenance.scene_identity` of the files the load that gave its frame's key
read (:func:`tlm.experiments.frames.cached_render`): a frame read from the cache too, remembered with the
scene's fingerprint (in the process and in the cache's ``scenes/key-*.json``), and a Dask worker's the files
that worker read.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml

from tlm.config import config_from_dict
from tlm.experiments import frame_keys, frames, sweep_point
from tlm.experiments.provenance import scene_identity
from tlm.experiments.run import run as run_experiment
from tlm.experiments.sweep import run_sweep
from tlm.report.collect import read
from tlm.report.tables import tables_section, thesis_table
from tlm.scenes.loader import scenes_dir

TINY = {"seed": 0, "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1},
        "arch": {"trace": False}}
BOX = Path(__file__).resolve().parents[1] / "scenes" / "meshes"
POWER = "power: [1100000.0, 950000.0, 750000.0]"


@pytest.fixture(autouse=True)
def _own_cache(cache, monkeypatch):  # (tests/conftest.py; this process's memo of scene keys, emptied)
    monkeypatch.setattr(frame_keys, "_SCENE_KEYS", type(frame_keys._SCENE_KEYS)())
    return cache


def _mesh_scene(folder: Path) -> Path:
    """A scene file of an OBJ with its MTL library (digested from its load's reads, kept on disk with its key)."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("CornellBox-Original.obj", "CornellBox-Original.mtl"):
        shutil.copyfile(BOX / name, folder / name)
    path = folder / "box.yaml"
    path.write_text("geometry: {mesh: CornellBox-Original.obj}\ncamera: {eye: [0.0, 1.0, 3.9], target: [0.0, 1.0, "
                    "0.0], up: [0.0, 1.0, 0.0], vfov: 39.3}\nresolution: [8, 8]\nphotons: 100\n", encoding="utf-8")
    return path


def _sweep(folder: Path, scene: str, out: Path, values=(1, 16)) -> list[dict]:
    """Each point's results.json of a sweep of ``scene`` over ``arch.fifo_depth`` (one frame: the first point
    renders it, the others read it from the cache)."""
    spec = folder / f"sweep-{out.name}.yaml"
    spec.write_text(yaml.safe_dump({"base": {**TINY, "scene": scene}, "grid": {"arch.fifo_depth": list(values)}}))
    done = run_sweep(spec, out, jobs=1)
    assert done.ok == len(values), done.rows
    return [json.loads((out / "points" / r["hash"] / "results.json").read_text(encoding="utf-8")) for r in done.rows]


def _run_digest(scene: str, out: Path) -> str:
    run_experiment(config_from_dict({**TINY, "scene": scene}, "test"), out)
    digest = json.loads((out / "results.json").read_text(encoding="utf-8"))["scene_digest"]
    assert isinstance(digest, str) and digest.startswith("sha256 ")
    return digest


@pytest.mark.parametrize("which", ["builtin", "mesh"])
def test_a_points_digest_is_that_of_a_run_of_its_scene_its_frame_cached_or_not(which, tmp_path):
    scene = "cornell" if which == "builtin" else str(_mesh_scene(tmp_path / "proj"))
    first = _sweep(tmp_path, scene, tmp_path / "a")
    assert [p["functional"]["cached"] for p in first] == [False, True]
    digest = _run_digest(scene, tmp_path / "run")
    assert [p["scene_digest"] for p in first] == [digest, digest]
    frame_keys._SCENE_KEYS.clear()  # (another process: its key remembered on disk for a mesh scene, else loaded)
    assert [p["scene_digest"] for p in _sweep(tmp_path, scene, tmp_path / "b")] == [digest, digest]
    if which == "mesh":  # (a key kept by a tlm before the digest: the files digested now, the same)
        kept = list((tmp_path / "cache" / "scenes").glob("key-*.json"))
        assert kept
        for path in kept:
            body = json.loads(path.read_text(encoding="utf-8"))
            assert body["digest"] == digest
            path.write_text(json.dumps({k: v for k, v in body.items() if k != "digest"}), encoding="utf-8")
        frame_keys._SCENE_KEYS.clear()
        assert [p["scene_digest"] for p in _sweep(tmp_path, scene, tmp_path / "c")] == [digest, digest]


def test_a_frame_from_the_cache_records_its_own_files_digest_not_the_renderers(tmp_path):
    """Two files of one scene (a comment apart) share a frame; the point that reads it records its own file's."""
    mine = _mesh_scene(tmp_path / "one")
    other = _mesh_scene(tmp_path / "two")
    other.write_text(other.read_text(encoding="utf-8") + "# a comment: the same scene, other bytes\n",
                     encoding="utf-8")
    (a,) = _sweep(tmp_path, str(mine), tmp_path / "a", values=[1])
    (b,) = _sweep(tmp_path, str(other), tmp_path / "b", values=[1])
    assert b["functional"]["cached"] and b["functional"]["key"] == a["functional"]["key"]
    assert a["scene_digest"] == scene_identity(mine) != b["scene_digest"] == scene_identity(other)


def test_a_dask_workers_point_records_the_digest_of_the_files_that_worker_read(tmp_path, monkeypatch):
    """A remote worker (``task.code``) whose scene file holds other bytes of the same scene than the sweep read:
    its frame key is the sweep's (the point runs), and its digest is of the file as the worker read it."""
    from tlm.experiments.dask_workers import worker_versions
    from tlm.fingerprint import code_fingerprint

    scene = _mesh_scene(tmp_path / "proj")
    config = {**TINY, "scene": str(scene)}
    swept = scene_identity(scene)
    key = frames.render_key(config_from_dict(config, "sweep.yaml"), tmp_path, "sweep.yaml")  # (the sweep's read)
    scene.write_text(scene.read_text(encoding="utf-8") + "# edited on the worker's disk\n", encoding="utf-8")
    (tmp_path / "sweep.yaml").write_text("{}\n")  # (the marker a worker looks for above the point's folder)
    task = sweep_point.Task("h", config, {}, str(tmp_path), "sweep.yaml", str(tmp_path / "points" / "h"),
                            {"versions": worker_versions()}, inputs=(str(scene),), code=code_fingerprint(),
                            functional=key)
    monkeypatch.setattr(sweep_point, "dask_worker_where", lambda: "the Dask worker w1 (tcp://x:1) on host h")
    got = sweep_point.run_point(task)
    assert got["status"] == "ok", got
    recorded = json.loads((tmp_path / "points" / "h" / "results.json").read_text(encoding="utf-8"))["scene_digest"]
    assert recorded == scene_identity(scene) != swept


def _edited_cornell(folder: Path, edit: bool = True) -> Path:
    thesis = (scenes_dir() / "cornell.yaml").read_text(encoding="utf-8")
    assert POWER in thesis
    path = folder / "cornell.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(thesis.replace(POWER, "power: [2e6, 2e6, 2e6]  # (my edit)") if edit else thesis,
                    encoding="utf-8")
    return path


def test_a_point_of_an_edited_scenes_cornell_moved_away_is_not_table_iii(tmp_path):
    mine = _edited_cornell(tmp_path / "proj" / "scenes")
    (point,) = _sweep(tmp_path, str(mine), tmp_path / "out", values=[1])
    assert point["scene_digest"] == scene_identity(mine) != scene_identity(scenes_dir() / "cornell.yaml")
    (tmp_path / "proj").rename(tmp_path / "gone")  # (its folder off this machine: the point's file is not here)
    inputs = read([tmp_path / "out"])
    (run,) = [r for r in inputs.runs if r.kind == "sweep-point"]
    assert run.scene == "cornell" and not Path(run.results["scene"]["source"]).exists()
    assert thesis_table(run) is None  # (before: 'cornell', by its place under a folder named scenes/)
    section = tables_section(inputs, tmp_path / "report")
    assert not section.figures and section.absent
    assert any("has no table in the thesis (" in n and "is not the thesis's Cornell Box scene" in n
               for n in section.notes), section.notes


def test_a_point_of_the_theses_bytes_is_table_iii_though_its_file_was_edited_since(tmp_path):
    copy = _edited_cornell(tmp_path / "mine", edit=False)  # (a copy of the thesis's file, not under scenes/)
    (point,) = _sweep(tmp_path, str(copy), tmp_path / "out", values=[1])
    assert point["scene_digest"] == scene_identity(scenes_dir() / "cornell.yaml")
    _edited_cornell(tmp_path / "mine")  # (edited after the sweep: the point was of the thesis's bytes)
    (run,) = [r for r in read([tmp_path / "out"]).runs if r.kind == "sweep-point"]
    assert thesis_table(run) == "cornell"  # (before: None, judged by the file's new bytes)
