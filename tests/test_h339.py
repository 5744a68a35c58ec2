"""What a run records of its inputs, and running again from a run folder (h339).

* ``results.json`` ``scene_digest``: the scene inputs' digest (scene file, ``extends:`` chain, meshes and their MTL
  libraries) as the run read them, from the digests the load computed (the mesh is not read again); the report
  names two runs of one scene file whose contents differed apart, and says so.
* A run folder's ``config.resolved.yaml`` naming a scene file that is not here says how to give it
  (``--set scene=PATH``); run with no ``--out``, it is refused (its default folder would be every such re-run's).
* A sweep folder's ``sweep.yaml`` (``tlm: sweep/1``) is no error-vs-cost study: the advice is ``tlm sweep``.
* ``render.exposure: 1e308``: no numpy warning, one tlm line.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

from tlm.cli import main
from tlm.config import noting_reads
from tlm.errors import InputError
from tlm.experiments import provenance
from tlm.experiments.provenance import scene_identity
from tlm.scenes.loader import load_scene

SCENE = ("geometry: [{mesh: m.obj}, {shape: plane, params: {size: [4, 4]}}]\n"
         "materials: {g: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\ndefault_material: g\n"
         "lights: [{type: point, position: [0, 3, -2], power: [40, 40, 40]}]\n"
         "camera: {eye: [0, 1, -5], target: [0, 0, 0], vfov: 40}\nresolution: [8, 8]\n")
OBJ = "mtllib m.mtl\nv -1 0 0\nv 1 0 0\nv 0 1 0\nusemtl g\nf 1 2 3\n"
QUIET = ["--no-progress", "--no-report", "--outputs", "images"]


def _project(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "s.yaml").write_text(SCENE)
    (folder / "m.obj").write_text(OBJ)
    (folder / "m.mtl").write_text("newmtl g\nKd 0.5 0.5 0.5\n")
    (folder / "exp.yaml").write_text("scene: s.yaml\nmode: rcast\n")
    return folder / "exp.yaml"


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))


def test_results_record_the_scene_inputs_digest_and_it_follows_a_mesh_edit(tmp_path, cache):
    exp = _project(tmp_path / "p")
    assert main(["run", str(exp), "--out", str(tmp_path / "a"), *QUIET]) == 0
    a = json.loads((tmp_path / "a" / "results.json").read_text())
    assert a["scene_digest"] == scene_identity(tmp_path / "p" / "s.yaml")
    (tmp_path / "p" / "m.obj").write_text(OBJ.replace("v 0 1 0", "v 0 1.01 0"))  # (one vertex)
    resolved = str(tmp_path / "a" / "config.resolved.yaml")
    assert main(["run", resolved, "--out", str(tmp_path / "b"), *QUIET]) == 0
    b = json.loads((tmp_path / "b" / "results.json").read_text())
    assert b["scene_digest"] != a["scene_digest"] and b["scene_digest"].startswith("sha256 ")
    assert b["scene_digest"] == scene_identity(tmp_path / "p" / "s.yaml")
    (tmp_path / "p" / "m.mtl").write_text("newmtl g\nKd 0.6 0.5 0.5\n")  # (the MTL library too)
    assert main(["run", resolved, "--out", str(tmp_path / "c"), *QUIET]) == 0
    c = json.loads((tmp_path / "c" / "results.json").read_text())
    assert c["scene_digest"] not in (a["scene_digest"], b["scene_digest"])


def test_the_digest_reuses_the_loads_mesh_digest(tmp_path, cache, monkeypatch):
    """With the load's reads, the mesh file is neither digested nor parsed again, and the identity is the same."""
    _project(tmp_path)
    with noting_reads() as reads:
        scene = load_scene(str(tmp_path / "s.yaml"))
    import tlm.scenes.meshes as meshes

    def refused(*a, **k):
        raise AssertionError("the mesh read again")

    full = scene_identity(scene.source)
    monkeypatch.setattr(meshes, "mesh_files", refused)
    assert provenance.scene_identity(scene.source, reads) == full


def test_the_report_tells_two_runs_of_one_scene_file_of_other_contents_apart(tmp_path, cache, monkeypatch):
    exp = _project(tmp_path / "p")
    assert main(["run", str(exp), "--out", str(tmp_path / "a"), *QUIET]) == 0
    (tmp_path / "p" / "m.obj").write_text(OBJ.replace("v 0 1 0", "v 0 1.01 0"))
    assert main(["run", str(tmp_path / "a" / "config.resolved.yaml"), "--out", str(tmp_path / "b"), *QUIET]) == 0
    from tlm.report import build_report

    monkeypatch.chdir(tmp_path)
    html = build_report([tmp_path / "a", tmp_path / "b"], tmp_path / "rep").read_text()
    digests = [json.loads((tmp_path / x / "results.json").read_text())["scene_digest"] for x in "ab"]
    for d in digests:
        assert f"[{d.removeprefix('sha256 ')[:8]}]" in html  # (each named with its digest)
        assert f"inputs {d}" in html
    assert "did not read the same scene inputs" in html


def test_a_moved_run_folders_config_says_how_to_give_the_scene(tmp_path, cache, capsys):
    exp = _project(tmp_path / "p")
    assert main(["run", str(exp), "--out", str(tmp_path / "a"), *QUIET]) == 0
    resolved = tmp_path / "a" / "config.resolved.yaml"
    data = yaml.safe_load(resolved.read_text())
    data["scene"] = "/nowhere/old/s.yaml"  # (the project moved since)
    resolved.write_text(yaml.safe_dump(data))
    capsys.readouterr()
    assert main(["run", str(resolved), "--out", str(tmp_path / "b"), *QUIET]) == 2
    err = capsys.readouterr().err
    assert "'/nowhere/old/s.yaml' not found" in err and "--set scene=PATH" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "b").exists()
    assert main(["run", str(resolved), "--out", str(tmp_path / "b"), *QUIET,
                 "--set", f"scene={tmp_path / 'p' / 's.yaml'}"]) == 0
    with pytest.raises(InputError) as e:  # (a config of another name: no such line)
        load_scene("/nowhere/old/s.yaml", None, None, "exp.yaml")
    assert "--set scene" not in str(e.value)
    with pytest.raises(InputError) as e:
        load_scene("/nowhere/old/s.yaml", None, None, "r/config.resolved.yaml, with --set")
    assert "--set scene=PATH" in str(e.value)


def test_a_run_folders_config_run_again_without_out_is_refused(tmp_path, cache, capsys, monkeypatch):
    exp = _project(tmp_path / "p")
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(exp), "--out", "runs/a", *QUIET]) == 0
    capsys.readouterr()
    assert main(["run", "runs/a/config.resolved.yaml", *QUIET]) == 2
    err = capsys.readouterr().err
    assert "give --out, say --out runs/a-again" in err and len(err.splitlines()) == 1
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == ["a"]  # (no runs/config.resolved)


def test_a_sweep_folders_record_is_no_error_vs_cost_study(tmp_path, cache, capsys):
    folder = tmp_path / "sw"
    folder.mkdir()
    (tmp_path / "sw.yaml").write_text("base: cornell\ngrid: {bsp.levels: [5, 7]}\n")  # (the sweep file, still here)
    record = {"tlm": "sweep/1", "sweep": str(tmp_path / "sw.yaml"), "description": None, "base_file": "cornell",
              "base": {"scene": "cornell", "mode": "rcast"}, "set": {}, "overrides": ["resolution=[8, 8]"],
              "grid": {"bsp.levels": [5, 7]}, "zip": None,
              "points": [{"point": 0, "hash": "a" * 16, "factors": {"bsp.levels": 5}}]}
    (folder / "sweep.yaml").write_text(yaml.safe_dump(record, sort_keys=False))
    for command in ("sweep", "run", "error-vs-cost"):
        assert main([command, str(folder / "sweep.yaml")]) == 2
        err = capsys.readouterr().err
        assert "error-vs-cost study file (it has" not in err and "a sweep folder's record" in err, err
        assert f"tlm sweep {tmp_path / 'sw.yaml'} --out {folder} --set 'resolution=[8, 8]'" in err
        assert len(err.splitlines()) == 1


def test_an_exposure_past_the_floats_warns_in_one_tlm_line(tmp_path, cache, capsys):
    from tlm.render.image import overflow_line, to_srgb8

    rad = np.full((2, 2, 3), 20.0, dtype=np.float32)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # (numpy's RuntimeWarning: overflow encountered in multiply)
        assert (to_srgb8(rad, 1e308) == 255).all()
    assert "4 of 4 pixels" in overflow_line(rad, 1e308) and overflow_line(rad, 1e3) is None
    root = Path(__file__).resolve().parents[1]
    assert main(["run", str(root / "configs" / "cornell.yaml"), "--out", str(tmp_path / "r"), *QUIET,
                 "--set", "resolution=[8, 8]", "--set", "render.exposure=1e308"]) == 0
    err = capsys.readouterr().err
    assert "RuntimeWarning" not in err and "render.exposure = 1e+308 takes the radiance" in err
    results = json.loads((tmp_path / "r" / "results.json").read_text())
    assert any(w.startswith("render.exposure = 1e+308") for w in results["warnings"])


def test_two_runs_of_one_config_are_byte_identical_but_their_host_seconds(tmp_path, cache):
    """docs/usage.md, "What is reproducible": images, arrays, cycles and the scene digest of two runs alike."""
    exp = _project(tmp_path / "p")
    for x in "ab":
        assert main(["run", str(exp), "--out", str(tmp_path / x), "--no-progress", "--no-report"]) == 0
    for name in ("images/composite.png", "radiance/composite.npy", "aov/work.npz", "trace.json"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    a, b = (json.loads((tmp_path / x / "results.json").read_text()) for x in "ab")
    for r in (a, b):
        del r["host_seconds"]
    assert a["scene_digest"].startswith("sha256 ") and a == b
