"""A scene's mesh paths without their ``..`` and a special file named as what it is
(:func:`tlm.scenes.compose.mesh_path`); the tlm version a result records is the running code's
(:func:`tlm.experiments.provenance.tlm_version`); a gathered map's radius and its rule from one
source (:func:`tlm.render.pmap.map_radius_used`)."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

import tlm
from tlm.errors import InputError
from tlm.scenes.loader import load_scene

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def _scene(folder: Path, *meshes: str) -> Path:
    """A scene file in ``folder`` whose geometry is the mesh files ``meshes``, as written."""
    folder.mkdir(parents=True, exist_ok=True)
    items = "".join(f"  - mesh: '{m}'\n    name: m{i}\n" for i, m in enumerate(meshes))
    path = folder / "s.yaml"
    path.write_text(f"geometry:\n{items}materials:\n  grey: {{type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n"
                    f"default_material: grey\nlights:\n  - {{type: point, position: [0.3, 0.3, 2], power: [1, 1, 1]}}\n"
                    "camera: {eye: [0.3, 0.3, 3], target: [0.3, 0.3, 0], up: [0, 1, 0], vfov: 40}\n"
                    "resolution: [8, 8]\n")
    return path


def _refusal(scene: Path) -> str:
    with pytest.raises(InputError) as e:
        load_scene(scene)
    return str(e.value)


def test_a_missing_mesh_up_a_folder_is_named_without_its_dotdot(tmp_path):
    scene = _scene(tmp_path / "a", "../m/nothere.obj")
    (tmp_path / "m").mkdir()
    said = _refusal(scene)
    assert f"mesh file {str(tmp_path / 'm' / 'nothere.obj')!r} not found" in said, said
    assert ".." not in said


def test_one_mesh_reached_two_ways_is_one_path(tmp_path):
    from tlm.experiments.provenance import mesh_paths

    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "tri.obj").write_text(TRI)
    scene = _scene(tmp_path / "a", "../m/tri.obj", str(tmp_path / "m" / "tri.obj"), "../a/../m/./tri.obj")
    assert mesh_paths(scene) == [tmp_path / "m" / "tri.obj"] * 3
    assert load_scene(scene).triangles.shape[0] == 3
    # a `..` after a symbolic link to a folder leads elsewhere than the name without it: kept as given
    (tmp_path / "far" / "deep").mkdir(parents=True)
    (tmp_path / "far" / "m").mkdir()
    (tmp_path / "far" / "m" / "tri.obj").write_text(TRI)
    (tmp_path / "a" / "link").symlink_to(tmp_path / "far" / "deep")
    linked = _scene(tmp_path / "a", "link/../m/tri.obj")
    assert mesh_paths(linked) == [tmp_path / "a" / "link" / ".." / "m" / "tri.obj"]
    assert load_scene(linked).triangles.shape[0] == 1



def test_an_export_warns_once_of_a_mesh_named_two_ways(tmp_path, capsys):
    from tlm.scenes.export import export_triangles

    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "tri.obj").write_text(TRI)  # (no notice beside it: an export warns of it)
    scene = load_scene(_scene(tmp_path / "a", "../m/tri.obj", str(tmp_path / "m" / "tri.obj")))
    capsys.readouterr()
    export_triangles(scene, tmp_path / "tri.ply")
    said = [line for line in capsys.readouterr().err.splitlines() if "carries no licence notice" in line]
    assert len(said) == 1, said


@pytest.mark.skipif(not os.path.exists("/dev/null") or sys.platform == "win32", reason="a POSIX device")
def test_a_device_a_pipe_a_socket_and_a_link_to_nothing_are_named_as_what_they_are(tmp_path):
    said = _refusal(_scene(tmp_path / "dev", "/dev/null"))
    assert "'/dev/null' is a character device, not a mesh file" in said and "not found" not in said, said
    os.mkfifo(tmp_path / "pipe.obj")
    said = _refusal(_scene(tmp_path / "fifo", "../pipe.obj"))
    assert f"{str(tmp_path / 'pipe.obj')!r} is a named pipe, not a mesh file" in said, said
    with socket.socket(socket.AF_UNIX) as s:
        s.bind(str(tmp_path / "sock.obj"))
        said = _refusal(_scene(tmp_path / "sock", "../sock.obj"))
    assert "is a socket, not a mesh file" in said, said
    (tmp_path / "gone.obj").symlink_to("nowhere.obj")
    said = _refusal(_scene(tmp_path / "link", "../gone.obj"))
    assert "is a symbolic link to 'nowhere.obj', which is not there" in said, said


def _copy_of_tlm(folder: Path, version: str | None) -> Path:
    """This checkout's tlm package in ``folder``, beside a pyproject.toml of ``version`` (None: none)."""
    shutil.copytree(Path(tlm.__file__).parent, folder / "tlm", ignore=shutil.ignore_patterns("__pycache__"))
    if version is not None:
        (folder / "pyproject.toml").write_text(f'[project]\nname = "tlm"\nversion = "{version}"\n')
    return folder


def _recorded_version(folder: Path) -> str:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    code = ("import tlm\nfrom tlm.experiments.provenance import versions\n"
            "print(tlm.__file__)\nprint(versions()['tlm'])\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=folder, env=env, capture_output=True, text=True,
                         timeout=120, check=True).stdout.splitlines()
    assert Path(out[0]).parent == folder / "tlm"  # (the copy runs, not the installed tlm)
    return out[1]


@pytest.mark.slow  # (a subprocess)
def test_a_checkout_records_its_own_version_not_the_installed_copys(tmp_path):
    import importlib.metadata as md

    try:
        installed = md.version("tlm")
    except md.PackageNotFoundError:
        installed = None
    assert _recorded_version(_copy_of_tlm(tmp_path / "checkout", "9.9.9.dev7")) == "9.9.9.dev7"
    bare = _recorded_version(_copy_of_tlm(tmp_path / "bare", None))  # (no source tree's file: not the installed one's)
    assert bare == ("unknown (not installed)" if installed is None else
                    f"unknown (installed tlm {installed} is another copy)")


@pytest.fixture(scope="module")
def traced():
    from tlm.kernels.photons import trace_photons
    from tlm.kernels.traverse import build_accel

    scene = load_scene("cornell", resolution=[8, 8])
    accel = build_accel(scene.triangles)
    return scene, accel, trace_photons(scene, accel, 1500, seed=0, global_map=True).photons


@pytest.mark.parametrize("estimate", [{}, {"final_gather": 0}, {"radius_fraction": 0.05}, {"radius": 20.0},
                                      {"final_gather_photons": 40},
                                      {"caustic_radius": 30.0, "radius_fraction": 0.03}])
def test_a_gathered_maps_radius_and_rule_are_the_ones_results_json_records(traced, estimate):
    from tlm.config import config_from_dict
    from tlm.render.frame import Frame
    from tlm.render.pmap import gathered_radii, map_radius_used, radii

    scene, accel, photons = traced
    frame = Frame.create(scene, accel, config_from_dict({"scene": "cornell", "mode": "pmap", "estimate": estimate}))
    recorded = radii(frame, photons)
    keys = {"global": "global_radius", "indirect": "radius", "caustic": "caustic_radius"}
    gathered = gathered_radii(frame, photons)
    assert gathered
    for name, r in gathered.items():
        assert map_radius_used(frame, photons, name) == (r, recorded[f"{keys[name]}_rule"]) == (
            recorded[keys[name]], recorded[f"{keys[name]}_rule"])


def test_error_vs_cost_reads_a_radius_rule_from_the_photon_maps_own(traced, monkeypatch):
    """error_cost.radius_rule_used keeps no rules of its own: the photon map's (_radius_used) decides."""
    from tlm.config import config_from_dict
    from tlm.experiments.error_cost import radius_rule_used
    from tlm.render import pmap
    from tlm.render.frame import Frame

    scene, accel, photons = traced
    frame = Frame.create(scene, accel, config_from_dict({"scene": "cornell", "mode": "pmap",
                                                         "estimate": {"final_gather": 0}}))
    names = pmap.gathered_maps(frame, photons)
    assert [radius_rule_used(frame, photons, n) for n in names] == ["density"] * len(names)
    monkeypatch.setattr(pmap, "_radius_used", lambda frame, photons, which: (1.0, f"{which} rule"))
    assert [radius_rule_used(frame, photons, n) for n in names] == [f"{n} rule" for n in names]


@pytest.mark.slow  # (a subprocess)
def test_tlm_version_names_the_running_codes_version(tmp_path):
    folder = _copy_of_tlm(tmp_path / "checkout", "9.9.9.dev7")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run([sys.executable, "-m", "tlm", "--version"], cwd=folder, env=env, capture_output=True,
                         text=True, timeout=120, check=True).stdout
    assert out.startswith("tlm 9.9.9.dev7 (Python "), out
