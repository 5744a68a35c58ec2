"""Follow-ups of the faults fixer (356f0e1).

* A scene load made LAPACK calls (``np.linalg.inv``/``det`` of 3x3 transforms): OpenBLAS's
  first call takes a buffer of its own and, under a small ``ulimit -v``, ends the process itself
  (``OpenBLAS error: Memory allocation still failed ...``, exit 1). They are written out now
  (:func:`tlm.scenes.meshes.det3`, :func:`~tlm.scenes.meshes.inverse3`), equal up to rounding.
* A SIGHUP during a delayed import could cut it (:data:`tlm.whole_imports.HELD` held SIGINT
  and SIGTERM only).
* A sweep's workers ignored SIGINT only: a hang-up, sent to the whole process group, killed them.
* ``cli_signals._writing`` (now ``cli_streams._writing``) read ``tlm.claims._CLAIMS``; now :func:`tlm.claims.holding`.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tlm.scenes.model import Geometry

REPO = Path(__file__).resolve().parents[1]
POSIX_HUP = pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="POSIX")


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py) every test here has its own: scenes are loaded, not read back
    return cache


def _no_lapack(monkeypatch) -> None:
    """np.linalg's LAPACK calls (those that reach OpenBLAS's buffer) made to fail."""
    def refuse(*args, **kwargs):
        raise AssertionError("np.linalg LAPACK call on a scene's load path")

    for name in ("inv", "det", "solve", "slogdet", "pinv", "lstsq", "svd", "eig", "eigh", "qr", "cholesky"):
        monkeypatch.setattr(np.linalg, name, refuse)


def test_every_built_in_scene_loads_without_a_lapack_call(monkeypatch):
    from tlm.scenes.loader import listed_scenes, load_scene

    _no_lapack(monkeypatch)
    names = listed_scenes()
    assert "examples/mesh_on_floor" in names  # (a rotated, scaled mesh item: det of its transform)
    for name in names:
        assert len(load_scene(name).triangles) > 0


def test_closed_forms_equal_numpy_linalg():
    from tlm.scenes.meshes import det3, inverse3

    rng = np.random.default_rng(7)
    m = rng.normal(size=(500, 3, 3))
    inv = np.linalg.inv(m)
    assert np.allclose(det3(m), np.linalg.det(m), rtol=1e-12, atol=1e-13)
    assert np.array_equal(np.sign(det3(m)), np.sign(np.linalg.det(m)))
    assert np.allclose(inverse3(m), inv, rtol=1e-11, atol=1e-12 * np.abs(inv).max())
    one = m[0]
    assert np.allclose(inverse3(one), np.linalg.inv(one), rtol=1e-12, atol=1e-14) and np.ndim(det3(one)) == 0
    assert np.isnan(inverse3(np.zeros((3, 3)))).all()  # (singular: no LinAlgError)


def _old_transform(tri, normals, m, t):
    """transform_geometry as it was (np.linalg), for the comparison."""
    tri = tri @ m.T + t
    normals = normals @ np.linalg.inv(m)
    length = np.linalg.norm(normals, axis=2, keepdims=True)
    normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    if np.linalg.det(m / np.abs(m).max()) < 0.0:
        tri, normals = tri[:, [0, 2, 1]], normals[:, [0, 2, 1]]
    return tri, normals


@pytest.mark.parametrize("scale", [[1.0, 1.0, 1.0], [-1.0, 2.0, 0.5], [3.0, -1e-3, 7.0], [-2.0, -2.0, -2.0]])
def test_a_transformed_item_with_file_normals_calls_no_lapack(monkeypatch, scale):
    from tlm.scenes.compose import item_transform, transform_geometry

    rng = np.random.default_rng(3)
    tri = rng.normal(size=(40, 3, 3))
    normals = rng.normal(size=(40, 3, 3))
    normals /= np.linalg.norm(normals, axis=2, keepdims=True)
    m, t = item_transform({"scale": scale, "rotate": [10.0, 20.0, 30.0], "translate": [1.0, 2.0, 3.0]}, "s.yaml", "t")
    want_tri, want_normals = _old_transform(tri, normals, m, t)
    geom = Geometry(triangles=tri, part=np.zeros(40, dtype=np.int32), part_names=("p",), normals=normals)
    _no_lapack(monkeypatch)
    got = transform_geometry(geom, m, t)
    assert np.array_equal(got.triangles, want_tri)  # (the triangles bit for bit, mirrored alike)
    assert np.allclose(got.normals, want_normals, rtol=0, atol=1e-14)


def test_a_gltf_node_transform_with_normals_calls_no_lapack(monkeypatch, tmp_path):
    trimesh = pytest.importorskip("trimesh")
    from tlm.scenes.meshes import load_mesh

    box = trimesh.creation.box()
    box.vertex_normals  # noqa: B018  (made, so that the file holds them)
    scene = trimesh.Scene()
    scene.add_geometry(box, transform=np.diag([-2.0, 1.0, 0.5, 1.0]))  # (mirroring, non-uniform)
    path = tmp_path / "box.glb"
    path.write_bytes(scene.export(file_type="glb", include_normals=True))
    _no_lapack(monkeypatch)
    geom = load_mesh(path)
    assert geom.normals is not None and geom.normals.shape == (12, 3, 3)
    assert np.allclose(np.linalg.norm(geom.normals, axis=2), 1.0)
    # (each file normal points away from the box's centre, as before the transform: the inverse transpose)
    centres = geom.triangles.mean(axis=1)
    assert (np.einsum("ij,ij->i", geom.normals[:, 0], centres) > 0).all()
    # the winding reversed by the mirror: each face's geometric normal points outwards still
    face = np.cross(geom.triangles[:, 1] - geom.triangles[:, 0], geom.triangles[:, 2] - geom.triangles[:, 0])
    assert (np.einsum("ij,ij->i", face, centres) > 0).all()


@POSIX_HUP
def test_sighup_is_held_to_an_imports_end():
    from tlm.whole_imports import HELD, HeldInterrupt, imports_whole

    assert signal.SIGHUP in HELD

    def raiser(signum, frame):
        raise KeyboardInterrupt

    seen = {}

    @imports_whole
    def call():
        seen["handler"] = signal.getsignal(signal.SIGHUP)

    before = signal.signal(signal.SIGHUP, raiser)
    try:
        call()
        assert signal.getsignal(signal.SIGHUP) is raiser  # (put back)
    finally:
        signal.signal(signal.SIGHUP, before)
    assert isinstance(seen["handler"], HeldInterrupt)


@POSIX_HUP
def test_processes_a_sweep_starts_ignore_a_hang_up():
    """A worker started in the block survives the SIGHUP that a closed terminal sends the whole group."""
    from tlm.experiments.executors import _sigint_ignored

    before = signal.getsignal(signal.SIGHUP)
    with _sigint_ignored():
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
        child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    assert signal.getsignal(signal.SIGHUP) is before
    try:
        time.sleep(0.5)
        child.send_signal(signal.SIGHUP)
        time.sleep(0.5)
        assert child.poll() is None
    finally:
        child.kill()
        child.wait()


@POSIX_HUP
def test_a_spawned_workers_set_up_ignores_a_hang_up():
    code = ("import os, signal\n"
            "from tlm.experiments.executors import _worker_init\n"
            "_worker_init({}, os.getppid())\n"
            "print(*(signal.getsignal(s) is signal.SIG_IGN for s in (signal.SIGINT, signal.SIGHUP)))\n")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert proc.stdout.split() == ["True", "True"], proc.stderr


def test_writing_asks_claims_holding(tmp_path, monkeypatch):
    from tlm import claims, cli_streams

    assert not claims.holding()
    with claims.claimed(tmp_path / "out"):
        assert claims.holding() and cli_streams._writing()
    assert not claims.holding() and not cli_streams._writing()
    monkeypatch.setattr(claims, "holding", lambda: True)  # (the public helper is what _writing reads)
    assert cli_streams._writing()
