"""h346: results.json ``scene_digest`` and the report's grouping of runs by scene (a review's findings, h343).

* The report's scene tables grouped runs by the digest *and* whether it was recorded: a ``tlm run`` (which records
  its digest) and a sweep's points on the same unchanged scene file (which record none: their files are digested
  now) made two groups, the second ``as for run a: ..., but (runs sw #0, sw #1)`` with nothing after "but".
* A scene file with ``extends: cornell`` (a built-in scene by name) kept its digest after the built-in's file was
  edited: the chain was followed for a path only.
* With a load's reads, the identity read every glTF buffer and the glTF again (``mesh_files``: three digests), and
  an OBJ's MTL libraries again, though the load had noted the sha256 of each (``("side", path, sha)``).
"""

from __future__ import annotations

import builtins
import io
import json
import os
import re
import shutil
from pathlib import Path

import pytest
import yaml

import tlm.caches
from tests.test_h339 import OBJ, QUIET, SCENE
from tests.test_h339 import _project as _run_project
from tlm.cli import main
from tlm.config import noting_reads
from tlm.experiments.provenance import scene_identity
from tlm.experiments.sweep import run_sweep
from tlm.scenes import cache as scene_cache
from tlm.scenes import loader, meshes
from tlm.scenes.loader import load_scene

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py: a TLM_CACHE of the test's own)
    return cache


def _project(folder: Path) -> Path:
    """test_h339's project (a scene of an OBJ with its MTL, a run config) and a sweep of two points over it."""
    _run_project(folder)
    (folder / "sw.yaml").write_text(yaml.safe_dump({"base": "exp.yaml", "grid": {"arch.fifo_depth": [1, 16]}}))
    return folder


def _summaries(html: str) -> list[str]:
    """The report's scene tables' summary lines, as text."""
    import html as h

    return [h.unescape(re.sub(r"<[^>]+>", "", s)) for s in re.findall(r"<summary>(scene .*?)</summary>", html)]


def test_a_run_and_sweep_points_of_one_unchanged_scene_are_one_scene_record(tmp_path, monkeypatch):
    from tlm.report import build_report

    p = _project(tmp_path / "p")
    assert main(["run", str(p / "exp.yaml"), "--out", str(tmp_path / "a"), *QUIET]) == 0
    done = run_sweep(p / "sw.yaml", tmp_path / "sw", jobs=1)
    assert (done.ok, done.failed) == (2, 0)
    monkeypatch.chdir(tmp_path)
    said = _summaries(build_report([tmp_path / "a", tmp_path / "sw"], tmp_path / "rep").read_text())
    recorded = json.loads((tmp_path / "a" / "results.json").read_text())["scene_digest"]
    assert len(said) == 1, said  # (was two: the run's, and the points' "as for run a: ..., but (runs ...)")
    assert f"inputs {recorded} (runs " in said[0] and "sw #0" in said[0] and "sw #1" in said[0], said
    assert "of its files now" not in said[0]  # (the run recorded it)

    (p / "m.obj").write_text(OBJ.replace("v 0 1 0", "v 0 1.01 0"))  # (the points of a later sweep: other inputs)
    assert run_sweep(p / "sw.yaml", tmp_path / "sw2", jobs=1).ok == 2
    said = _summaries(build_report([tmp_path / "a", tmp_path / "sw2"], tmp_path / "rep2").read_text())
    now = scene_identity(p / "s.yaml")
    assert now != recorded and len(said) == 2, said
    assert f"but inputs {now} (runs sw2 #0 and sw2 #1)" in said[1], said  # (h393: recorded by the points)
    assert not any(re.search(r"but \(", s) for s in said), said


def test_a_scene_that_extends_a_built_in_by_name_follows_an_edit_of_its_file(tmp_path, monkeypatch):
    builtin = tmp_path / "builtin"
    builtin.mkdir()
    shutil.copy(ROOT / "scenes" / "cornell.yaml", builtin / "cornell.yaml")
    monkeypatch.setattr(loader, "scenes_dir", lambda: builtin)  # (an installation's built-in scenes, to edit)
    mine = tmp_path / "p" / "mine.yaml"
    mine.parent.mkdir()
    mine.write_text("extends: cornell\nname: mine\n")
    assert load_scene(str(mine)).source == str(mine)  # (it loads: the built-in is found by its name)
    first = scene_identity(mine)
    with (builtin / "cornell.yaml").open("a") as f:
        f.write("photons: 1000\n")  # (the built-in edited: the scene a load of mine.yaml reads is another)
    assert scene_identity(mine) != first
    (tmp_path / "p" / "sub").mkdir()
    shutil.copy(builtin / "cornell.yaml", tmp_path / "p" / "sub" / "cornell.yaml")
    by_path = tmp_path / "p" / "by_path.yaml"
    by_path.write_text("extends: sub/cornell.yaml\nname: mine\n")
    assert scene_identity(by_path) != scene_identity(mine)  # (other bytes of its own)
    by_path.write_text("extends: cornell\nname: mine\n")
    assert scene_identity(by_path) == scene_identity(mine)  # (a copy: its chain the same files)


def _gltf(folder: Path, glb: bool) -> Path:
    """A glTF of two buffer files beside it (``model.gltf``, or ``model.glb`` whose JSON names them: no BIN chunk)."""
    trimesh = pytest.importorskip("trimesh")
    from tlm.scenes.materials import write_glb

    folder.mkdir(parents=True, exist_ok=True)
    files = trimesh.exchange.gltf.export_gltf(trimesh.Scene([trimesh.creation.box(), trimesh.creation.icosphere()]))
    for name, data in files.items():
        if name.endswith(".bin"):
            (folder / name).write_bytes(data)
    assert len(list(folder.glob("*.bin"))) >= 1
    if glb:
        (folder / "model.glb").write_bytes(write_glb(json.loads(files["model.gltf"])))
    else:
        (folder / "model.gltf").write_bytes(files["model.gltf"])
    mesh = "model.glb" if glb else "model.gltf"
    (folder / "s.yaml").write_text(SCENE.replace("m.obj", mesh))
    return folder / "s.yaml"


def _opened(monkeypatch) -> list[str]:
    """The files opened from now on (``open``, ``Path.read_bytes``, ...), by their names."""
    got: list[str] = []
    real = io.open

    def noting(file, *a, **k):
        if isinstance(file, str | os.PathLike):
            got.append(os.path.basename(os.fspath(file)))
        return real(file, *a, **k)

    monkeypatch.setattr(builtins, "open", noting)
    monkeypatch.setattr(io, "open", noting)
    return got


@pytest.mark.parametrize("case", ["cornell-box", "gltf", "glb"])
def test_the_digest_from_a_loads_reads_reads_no_mesh_library_or_buffer_again(tmp_path, monkeypatch, case):
    scene = (ROOT / "scenes" / "cornell-box.yaml" if case == "cornell-box"  # (an OBJ with its MTL library)
             else _gltf(tmp_path / case, glb=case == "glb"))
    with noting_reads() as reads:
        load_scene(str(scene))
    full = scene_identity(scene)  # (every file read now: the identity of the files as they are)
    digests = []
    real = tlm.caches.file_digest
    monkeypatch.setattr(tlm.caches, "file_digest", lambda p: digests.append(Path(p).name) or real(p))

    def refused(*a, **k):
        raise AssertionError("the mesh's files read again")

    monkeypatch.setattr(meshes, "mesh_files", refused)
    monkeypatch.setattr(scene_cache, "mesh_files", refused)
    opened = _opened(monkeypatch)
    got = scene_identity(scene, reads)
    monkeypatch.undo()
    assert got == full  # (the same digest as the files' own)
    assert digests == []  # (was: model.gltf and each .bin, or the .mtl)
    others = [f for f in opened if not f.endswith(".yaml")]
    # (a .gltf's JSON is read for its buffers' names, a .glb's JSON chunk alone; no .bin, .mtl or .obj)
    assert others == ({"gltf": ["model.gltf"], "glb": ["model.glb"]}.get(case, [])), opened


def test_a_glbs_json_chunk_alone_is_read_for_its_buffers(tmp_path):
    from tlm.experiments.provenance import _buffer_paths

    scene = _gltf(tmp_path, glb=True)
    glb = scene.parent / "model.glb"
    with glb.open("ab") as f:  # (a BIN chunk after the JSON, cut short: never read)
        f.write(b"\x10\x00\x00\x00BIN\x00\x01")
    data = glb.read_bytes()
    uris = [b["uri"] for b in json.loads(data[20:20 + int.from_bytes(data[12:16], "little")])["buffers"]]
    assert [p.name for p in _buffer_paths(glb)] == uris and uris
