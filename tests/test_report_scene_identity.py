"""A report judges every thesis cell by its scene file (:func:`tlm.experiments.thesis.table_of`:
the file's identity against the built-in files'): each scene file's identity (its digest, its
YAML parsed, its meshes read) is computed once per report, not once a cell and table, and is
the same identity as before (:func:`tlm.experiments.provenance.identities_remembered`)."""

from __future__ import annotations

import shutil
from collections import Counter
from pathlib import Path

import pytest

import tlm.report
from tlm.experiments import provenance
from tlm.experiments.provenance import scene_identity
from tlm.experiments.thesis import PM_METRICS, table_of
from tlm.report import common
from tlm.report.collect import Inputs, Run, Study
from tlm.scenes.loader import scenes_dir

MODES = ("rcast", "reflect", "refract", "pmap")
MESH_SCENE = ("geometry: [{mesh: m.obj}, {shape: plane, params: {size: [4, 4]}}]\n"
              "materials: {g: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\ndefault_material: g\n"
              "camera: {eye: [0, 1, -5], target: [0, 0, 0], vfov: 40}\nresolution: [16, 16]\n")
OBJ = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl g\nf 1 2 3\n"
MTL = "newmtl g\nKd 0.5 0.5 0.5\n"


def mesh_scene(folder: Path) -> Path:
    """A scene file whose geometry reads an OBJ and its material library."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "m.obj").write_text(OBJ)
    (folder / "m.mtl").write_text(MTL)
    (folder / "mesh.yaml").write_text(MESH_SCENE)
    return folder / "mesh.yaml"


@pytest.fixture
def counted(monkeypatch):
    """Counts of the scene files digested (``provenance._identity`` of a scene file itself, not
    of a file its ``extends:`` names) and of the scene files whose meshes were read."""
    digests: Counter = Counter()
    meshes: Counter = Counter()
    identity, mesh_lines = provenance._identity, provenance._mesh_lines

    def _identity(path, depth):
        if depth == 0:
            digests[str(path)] += 1
        return identity(path, depth)

    def _mesh_lines(path):
        meshes[str(path)] += 1
        return mesh_lines(path)

    monkeypatch.setattr(provenance, "_identity", _identity)
    monkeypatch.setattr(provenance, "_mesh_lines", _mesh_lines)
    return digests, meshes


def study_inputs(root: Path, sources: dict[str, Path]) -> Inputs:
    """A thesis study's inputs as ``tlm.report.collect.read`` gives them: every scene of
    ``sources`` (name -> scene file) in the four modes, at 16x16 (not comparable)."""
    runs, rows = [], []
    for name, source in sources.items():
        for mode in MODES:
            scene = {"name": name, "source": str(source), "resolution": [16, 16]}
            runs.append(Run(root / name / mode, f"{name}/{mode}", "thesis", {"scene": scene, "mode": mode}, {}))
            rows += [{"scene": name, "mode": mode, "metric": m, "thesis": 10.0, "ours": 11.0, "rel_error": 0.1,
                      "calibrated": False} for m in (*PM_METRICS, "TThru", "FPS")]
    return Inputs([root], runs=runs, studies=[Study("thesis", root, rows)])


def test_a_report_computes_each_scene_files_identity_once(tmp_path, monkeypatch, counted):
    digests, meshes = counted
    builtin = scenes_dir()
    mine = tmp_path / "mine"
    mesh = mesh_scene(mine)  # (a room of the user's, of a mesh: not the thesis's)
    shutil.copy(builtin / "cornell.yaml", mine / "cornell.yaml")  # (a copy: the thesis's scene, judged by bytes)
    sources = {"ring": builtin / "thesis" / "ring.yaml", "room": mesh, "cornell": mine / "cornell.yaml"}
    root = tmp_path / "study"
    root.mkdir()
    monkeypatch.setattr(tlm.report, "read", lambda dirs, skip=None: study_inputs(root, sources))
    monkeypatch.setattr(common, "write_png", lambda fig, path: Path(path).write_bytes(b""))  # (not drawn: faster)
    page = tlm.report.build_report([root], tmp_path / "rep")
    assert page.is_file()
    files = {str(p) for p in sources.values()} | {str(builtin / f"{n}.yaml") for n in ("thesis/room", "cornell")}
    assert set(digests) == files  # every scene file of a cell, and the built-in ones beside them
    assert all(n == 1 for n in digests.values()), digests
    assert all(n == 1 for n in meshes.values()) and str(mesh) in meshes, meshes
    # the judgement is the same: the copy of cornell.yaml is the thesis's scene, the mesh scene none
    assert table_of(mine / "cornell.yaml") == "cornell" and table_of(mesh) is None
    text = page.read_text(encoding="utf-8")
    # (h389: the user's room is left out of the tables, a scene with no table in the thesis, not tabled "n/c")
    said = f"scene &#x27;{mesh}&#x27; has no table in the thesis (not the thesis&#x27;s Room scene, thesis/room)"
    assert said in text
    assert "the scene " + str(mesh) not in text and "the scene " + str(mine / "cornell.yaml") not in text


def test_table_of_digests_the_file_it_judges_once(tmp_path, counted):
    """Outside a report too: the file judged once a call, not once a table."""
    digests, _ = counted
    scene = mesh_scene(tmp_path)
    assert table_of(scene) is None  # (compared with all three tables' files)
    assert digests[str(scene)] == 1


def test_a_remembered_identity_is_the_same_and_follows_the_scene_file(tmp_path, counted):
    from tlm.experiments.provenance import identities_remembered

    digests, _ = counted
    scene = mesh_scene(tmp_path)
    before = scene_identity(scene)
    with identities_remembered():
        assert scene_identity(scene) == before
        assert scene_identity(scene) == before  # (given again)
        with identities_remembered():  # (a scope inside shares the outer's)
            assert scene_identity(scene) == before
        assert digests[str(scene)] == 2  # (once before the scope, once inside)
        scene.write_text(MESH_SCENE.replace("[16, 16]", "[160, 16]"))  # a change of the scene file is seen
        changed = scene_identity(scene)
        assert changed != before
        assert scene_identity(Path("/no/such/scene.yaml")) == "path /no/such/scene.yaml"
    (tmp_path / "m.obj").write_text(OBJ + "f 3 2 1\n")  # outside: every call computes (a mesh change is seen)
    assert scene_identity(scene) not in (before, changed)
    assert digests[str(scene)] == 4
