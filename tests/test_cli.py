"""The command line end to end: run folders, scene list/show/export, params, determinism."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml
from PIL import Image

from tlm.cli import main
from tlm.config import config_from_dict, describe, to_dict
from tlm.kernels.camera import primary_rays
from tlm.kernels.traverse import build_accel, closest_hit
from tlm.kernels.work import WORK_KEYS
from tlm.scenes.loader import load_scene

REPO = Path(__file__).resolve().parents[1]
CORNELL = str(REPO / "configs" / "cornell.yaml")
RING = str(REPO / "configs" / "ring.yaml")
RES = "resolution=[48,48]"
# packets of 16: at 48x48, packets of 256 are coarse enough for the run to warn of them (docs/architecture.md,
# "Packet size"), and these tests want a run with nothing to warn of
FINE = "arch.packet_size=16"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def run(out: Path, *extra: str, config: str = CORNELL, capsys=None) -> dict:
    code = main(["run", config, "--out", str(out), "--set", RES, "--set", FINE, *extra])
    assert code == 0
    if capsys is not None:
        err = capsys.readouterr().err
        assert err == ""
    return json.loads((out / "results.json").read_text())


@pytest.fixture(scope="module")
def cornell_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "cornell"
    results = run(out)
    return out, results


def flatten(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


# ---------------------------------------------------------------- run folder


@pytest.mark.slow
def test_run_folder_layout(cornell_run):
    out, _ = cornell_run
    files = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    report = [f for f in files if f.startswith("report/")]  # tests/test_report.py checks it
    assert "report/report.html" in report and all(f.endswith((".png", ".html")) for f in report)
    files = [f for f in files if not f.startswith("report/")]
    assert files == sorted([
        ".tlm-written", "config.resolved.yaml", "results.json", "trace.json",
        "images/rcast.png", "images/reflect.png", "images/refract.png", "images/composite.png",
        "radiance/rcast.npy", "radiance/reflect.npy", "radiance/refract.npy", "radiance/composite.npy",
        "aov/primary.npz", "aov/work.npz",
    ])
    assert not list(out.parent.glob(".*tmp*"))  # no temporary folder left behind


@pytest.mark.slow
def test_resolved_config_has_every_parameter(cornell_run):
    out, _ = cornell_run
    resolved = yaml.safe_load((out / "config.resolved.yaml").read_text())
    flat = flatten(resolved)
    assert set(flat) == {key for key, _, _ in describe()}
    assert flat["resolution"] == [48, 48]
    assert flat["scene"] == "cornell" and flat["mode"] == "refract" and flat["seed"] == 0
    assert flat["bsp.levels"] is None and flat["render.exposure"] is None
    assert flat["render.batch"] == 4  # a default not in configs/cornell.yaml
    # it loads back to the same config
    assert to_dict(config_from_dict(resolved)) == resolved


@pytest.mark.slow
def test_results_json(cornell_run):
    _out, results = cornell_run
    assert results["seed"] == 0 and results["mode"] == "refract"
    assert results["config"] == CORNELL
    assert results["plan"]["run"] == ["rcast", "reflect", "refract"]
    assert set(results["plan"]["left_out"]) == {"pmap"}  # the photon map is mode pmap's
    assert set(results["plan"]["reasons"]) == {"rcast", "reflect", "refract", "pmap"}
    assert results["photons"] is None and results["error"] is None
    assert results["scene"]["triangles"] == 2604
    assert results["scene"]["resolution"] == [48, 48]
    assert results["scene"]["bsp"]["levels"] == 7  # floor(ln 2604)
    assert results["primary"]["pixels"] == 48 * 48 and results["primary"]["spp"] == 4
    assert results["primary"]["rays"] == 4 * 48 * 48
    assert results["primary"]["hits"] + results["primary"]["misses"] == 4 * 48 * 48
    assert set(results["work"]) == {"rcast", "reflect", "refract"}
    for name, w in results["work"].items():
        for k in WORK_KEYS:
            assert isinstance(w[k], int) and w[k] >= 0, (name, k)
        assert w["tri_tests"] > 0 and w["node_visits"] > 0
    assert results["work"]["rcast"]["primary_rays"] == 4 * 48 * 48  # render.spp 4 by default
    assert results["work"]["reflect"]["secondary_rays"] > 0
    assert results["work"]["refract"]["secondary_rays"] > 0
    hs = results["host_seconds"]
    for stage in ("load_scene", "build_bsp", "cast", "pass_rcast", "pass_reflect", "pass_refract", "write"):
        assert isinstance(hs[stage], float) and hs[stage] >= 0
    for pkg in ("python", "numpy", "trimesh", "pyyaml", "pillow"):
        assert isinstance(results["versions"][pkg], str) and results["versions"][pkg]
    assert results["work_keys"] == list(WORK_KEYS)
    assert results["image"]["exposure"] > 0
    assert results["warnings"] == []


@pytest.mark.slow
def test_images_are_valid_nonblank_pngs(cornell_run):
    out, _ = cornell_run
    for name in ("rcast", "reflect", "refract", "composite"):
        path = out / "images" / f"{name}.png"
        raw = path.read_bytes()
        assert raw[:8] == PNG_SIGNATURE
        width, height = struct.unpack(">II", raw[16:24])  # IHDR
        assert (width, height) == (48, 48)
        with Image.open(path) as im:
            im.verify()
        with Image.open(path) as im:
            assert im.format == "PNG" and im.mode == "RGB" and im.size == (48, 48)
            px = np.asarray(im)
        assert px.shape == (48, 48, 3) and px.dtype == np.uint8
        assert px.max() > 0 and px.std() > 0, name


@pytest.mark.slow
def test_radiance_arrays(cornell_run):
    out, _ = cornell_run
    rad = {}
    for name in ("rcast", "reflect", "refract", "composite"):
        a = np.load(out / "radiance" / f"{name}.npy")
        assert a.shape == (48, 48, 3)
        assert np.issubdtype(a.dtype, np.floating)
        assert np.isfinite(a).all() and (a >= 0).all()
        assert a.max() > 0
        rad[name] = a.astype(np.float64)
    np.testing.assert_allclose(rad["composite"], rad["rcast"] + rad["reflect"] + rad["refract"],
                               rtol=1e-6, atol=1e-12)
    # each eye path belongs to one frame: a pixel shows both a Lambertian surface and the
    # mirror only where its four samples straddle the mirror's silhouette
    lit = rad["rcast"].sum(axis=2) > 0
    mirror = rad["reflect"].sum(axis=2) > 0
    both = mirror & lit
    assert mirror.sum() > 20 and both.sum() < 0.5 * mirror.sum()
    inner = mirror & np.roll(mirror, 1, 0) & np.roll(mirror, -1, 0) & np.roll(mirror, 1, 1) & np.roll(mirror, -1, 1)
    assert inner.any() and not np.any(inner & both)


@pytest.mark.slow
def test_primary_aov(cornell_run):
    out, _ = cornell_run
    with np.load(out / "aov" / "primary.npz") as z:
        aov = {k: z[k] for k in z.files}
    assert set(aov) == {"origin", "direction", "t", "triangle", "normal"}
    assert aov["origin"].shape == aov["direction"].shape == aov["normal"].shape == (48, 48, 3)
    assert aov["t"].shape == aov["triangle"].shape == (48, 48)
    assert aov["triangle"].dtype == np.int64
    hit = aov["triangle"] >= 0
    miss = ~hit
    assert hit.any() and miss.any()
    assert np.all(aov["triangle"][miss] == -1)
    assert np.all(np.isposinf(aov["t"][miss]))
    assert np.all(np.isfinite(aov["t"][hit]) & (aov["t"][hit] > 0))
    np.testing.assert_allclose(np.linalg.norm(aov["direction"], axis=2), 1.0, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(aov["normal"][hit], axis=1), 1.0, rtol=1e-9)
    assert np.all(aov["normal"][miss] == 0.0)
    np.testing.assert_array_equal(aov["origin"], np.broadcast_to([278.0, 273.0, -800.0], (48, 48, 3)))
    # the AOV is what the library computes for this scene and resolution
    scene = load_scene("cornell", resolution=[48, 48])
    o, d = primary_rays(scene.camera, np.arange(48 * 48), spp=4)
    o, d = o[::4], d[::4]  # the AOVs hold each pixel's first sample
    h = closest_hit(build_accel(scene.triangles), o, d, shared_origin=True)  # as cast() does
    np.testing.assert_array_equal(aov["direction"].reshape(-1, 3), d)
    np.testing.assert_array_equal(aov["triangle"].reshape(-1), h.triangle)
    np.testing.assert_array_equal(aov["t"].reshape(-1), h.t)
    # the pixel ids are row-major from the top: the top row sees the ceiling (y up)
    p = aov["origin"] + aov["t"][..., None] * aov["direction"]
    assert np.nanmean(np.where(hit, p[..., 1], np.nan)[:4]) > np.nanmean(np.where(hit, p[..., 1], np.nan)[-4:])


@pytest.mark.slow
def test_work_aov_matches_results(cornell_run):
    out, results = cornell_run
    with np.load(out / "aov" / "work.npz") as z:
        work = {k: z[k] for k in z.files}
    assert set(work) == {f"{p}.{k}" for p in ("rcast", "reflect", "refract") for k in WORK_KEYS}
    for key, a in work.items():
        p, k = key.split(".")
        assert a.shape == (48, 48) and a.dtype == np.int32  # (int64 only where a count does not fit)
        assert int(a.sum()) == results["work"][p][k], key


@pytest.mark.slow
def test_stdout_summary(tmp_path, capsys):
    code = main(["run", RING, "--out", str(tmp_path / "r"), "--set", "resolution=[32,24]", "--set", FINE])
    assert code == 0
    cap = capsys.readouterr()
    assert cap.err == ""
    assert "scene ring: 646 triangles, 32x24" in cap.out
    assert "left out refract: the scene has no dielectric material" in cap.out
    assert f"wrote {tmp_path / 'r'}" in cap.out
    results = json.loads((tmp_path / "r" / "results.json").read_text())
    assert results["plan"]["run"] == ["rcast", "reflect"]
    assert not (tmp_path / "r" / "images" / "refract.png").exists()


def test_a_deadlock_is_one_line_and_writes_nothing(tmp_path, capsys):
    """A model that cannot finish (here: too few events allowed) names the blocked units."""
    out = tmp_path / "d"
    code = main(["run", RING, "--out", str(out), "--mode", "rcast", "--no-report",
                 "--set", "resolution=[16,12]", "--set", "arch.max_events=50"])
    err = capsys.readouterr().err
    assert code == 1
    # (a cap hit, said as such: not "tlm: deadlock: ...")
    assert err.startswith("tlm: stopped at arch.max_events = 50 events") and err.count("\n") == 1
    assert ("stopped at arch.max_events = 50 events, the cap the config sets (raise it if the run is only long), "
            "unfinished at cycle ") in err
    assert "pipe0." in err and " waits for " in err
    assert not out.exists()


def test_a_stream_too_short_for_a_steady_throughput_warns(tmp_path, capsys):
    out = tmp_path / "short"
    code = main(["run", RING, "--out", str(out), "--mode", "rcast", "--no-report",
                 "--set", "resolution=[16,12]", "--set", "arch.frames=2", "--set", FINE])
    err = capsys.readouterr().err
    assert code == 0
    assert err.startswith("tlm: warning: arch.frames=2 is too short for a steady-state throughput (at least 5")
    results = json.loads((out / "results.json").read_text())
    assert results["timing"]["throughput_estimate"]["steady"] is False
    assert len(results["warnings"]) == 1 and "arch.frames=2" in results["warnings"][0]
    timing = results["timing"]  # the liveness bound: far above the events the run needed
    assert 8 * timing["simpy_events"] < timing["event_bound"] <= 200_000_000


@pytest.mark.slow
def test_mode_rcast(tmp_path, capsys):
    out = tmp_path / "rc"
    results = run(out, "--mode", "rcast", capsys=capsys)
    assert results["mode"] == "rcast"
    assert results["plan"]["run"] == ["rcast"]
    left = results["plan"]["left_out"]
    assert set(left) == {"reflect", "refract", "pmap"}
    for name, why in left.items():
        assert "mode 'rcast'" in why and name in why
    assert set(results["work"]) == {"rcast"}
    assert sorted(p.name for p in (out / "images").iterdir()) == ["composite.png", "rcast.png"]
    assert sorted(p.name for p in (out / "radiance").iterdir()) == ["composite.npy", "rcast.npy"]
    np.testing.assert_array_equal(np.load(out / "radiance" / "composite.npy"),
                                  np.load(out / "radiance" / "rcast.npy"))
    assert yaml.safe_load((out / "config.resolved.yaml").read_text())["mode"] == "rcast"


@pytest.mark.slow
def test_seed_and_determinism(tmp_path, cornell_run):
    base, base_results = cornell_run
    again = run(tmp_path / "again", "--seed", "0")
    for name in ("rcast", "reflect", "refract", "composite"):
        assert (tmp_path / "again" / "images" / f"{name}.png").read_bytes() == \
            (base / "images" / f"{name}.png").read_bytes(), name
        np.testing.assert_array_equal(np.load(tmp_path / "again" / "radiance" / f"{name}.npy"),
                                      np.load(base / "radiance" / f"{name}.npy"))
    assert again["work"] == base_results["work"]
    assert again["primary"] == base_results["primary"]
    with np.load(tmp_path / "again" / "aov" / "work.npz") as a, np.load(base / "aov" / "work.npz") as b:
        for k in a.files:
            np.testing.assert_array_equal(a[k], b[k])
    # another seed: recorded, different light samples, same eye rays
    other = run(tmp_path / "seed7", "--seed", "7")
    assert other["seed"] == 7
    assert yaml.safe_load((tmp_path / "seed7" / "config.resolved.yaml").read_text())["seed"] == 7
    assert other["primary"] == base_results["primary"]
    assert other["work"]["rcast"]["primary_rays"] == base_results["work"]["rcast"]["primary_rays"]
    assert not np.array_equal(np.load(tmp_path / "seed7" / "radiance" / "rcast.npy"),
                              np.load(base / "radiance" / "rcast.npy"))
    # the same seed through --set
    run(tmp_path / "seed7b", "--set", "seed=7")
    assert (tmp_path / "seed7b" / "images" / "composite.png").read_bytes() == \
        (tmp_path / "seed7" / "images" / "composite.png").read_bytes()


@pytest.mark.slow
def test_an_earlier_run_folder_is_replaced(tmp_path):
    """The run's own files are replaced; what the user added to the folder is kept."""
    out = tmp_path / "run"
    run(out, "--mode", "rcast")
    (out / "notes.txt").write_text("mine")  # an earlier run folder, with something added
    (out / "results.json").write_text("{}")
    run(out, "--mode", "rcast")
    assert (out / "notes.txt").read_text() == "mine"
    assert json.loads((out / "results.json").read_text())["mode"] == "rcast"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


@pytest.mark.parametrize("make", ["folder_of_other_things", "file", "cwd", "parent"])
def test_out_never_replaces_anything_else(tmp_path, monkeypatch, capsys, make):
    """--out refuses what is not an earlier run folder: nothing is deleted, exit 2."""
    work = tmp_path / "work"
    work.mkdir()
    (work / "precious.txt").write_text("keep")
    monkeypatch.chdir(work)
    out = {"folder_of_other_things": "..", "file": "precious.txt", "cwd": ".", "parent": ".."}[make]
    if make == "folder_of_other_things":
        (tmp_path / "mine").mkdir()
        (tmp_path / "mine" / "notes.txt").write_text("keep")
        out = str(tmp_path / "mine")
    assert main(["run", CORNELL, "--mode", "rcast", "--set", "resolution=[8,8]", "--out", out]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tlm: error: --out:")
    assert (work / "precious.txt").read_text() == "keep"
    if make == "folder_of_other_things":
        assert (tmp_path / "mine" / "notes.txt").read_text() == "keep"
    assert not list(tmp_path.rglob(".*.tmp-*"))


def test_export_into_a_missing_folder_makes_it(tmp_path, capsys):
    assert main(["scene", "export", "ring", str(tmp_path / "nowhere" / "x.ply")]) == 0  # (h474: as --out does)
    assert (tmp_path / "nowhere" / "x.ply").is_file()


@pytest.mark.slow
def test_default_out_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["run", CORNELL, "--mode", "rcast", "--set", "resolution=[16,16]"]) == 0
    assert (tmp_path / "runs" / "cornell" / "results.json").is_file()


@pytest.mark.slow
def test_relative_scene_path_in_config(tmp_path):
    """A config's scene path is relative to the config file."""
    (tmp_path / "scenes").mkdir()
    text = (REPO / "scenes" / "ring.yaml").read_text().replace("resolution: [320, 240]", "resolution: [20, 10]")
    (tmp_path / "scenes" / "myring.yaml").write_text(text)
    (tmp_path / "cfg").mkdir()
    cfg = tmp_path / "cfg" / "exp.yaml"
    cfg.write_text("scene: ../scenes/myring.yaml\nmode: rcast\n")
    assert main(["run", str(cfg), "--out", str(tmp_path / "o")]) == 0
    results = json.loads((tmp_path / "o" / "results.json").read_text())
    assert results["scene"]["resolution"] == [20, 10]
    assert results["scene"]["triangles"] == 646


# ---------------------------------------------------------------- scene commands


def test_scene_list(capsys):
    assert main(["scene", "list"]) == 0
    lines = capsys.readouterr().out.split()
    assert {"ring", "room", "cornell"} <= set(lines)
    assert lines == sorted(lines)


@pytest.mark.parametrize("name,count", [("cornell", 2604), ("ring", 646), ("room", 7812)])
def test_scene_show(capsys, name, count):
    assert main(["scene", "show", name]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["name"] == name
    assert info["triangles"] == count
    assert sum(m["triangles"] for m in info["materials"]) == count
    assert sum(info["parts"].values()) == count
    assert len(info["bounds"]["min"]) == len(info["bounds"]["max"]) == 3
    assert info["lights"] and info["camera"]["vfov"] > 0


def test_scene_show_by_path(capsys):
    assert main(["scene", "show", str(REPO / "scenes" / "cornell.yaml")]) == 0
    assert json.loads(capsys.readouterr().out)["triangles"] == 2604


def parse_obj(path: Path) -> np.ndarray:
    verts, faces = [], []
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            verts.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            faces.append([int(x.split("/")[0]) - 1 for x in line.split()[1:]])
    return np.asarray(verts)[np.asarray(faces)]


def parse_ply(path: Path) -> tuple[np.ndarray, np.ndarray]:
    raw = path.read_bytes()
    end = raw.index(b"end_header\n") + len(b"end_header\n")
    header = raw[:end].decode().splitlines()
    assert header[1] == "format binary_little_endian 1.0"
    nv = int(next(h for h in header if h.startswith("element vertex")).split()[-1])
    nf = int(next(h for h in header if h.startswith("element face")).split()[-1])
    at = header.index(next(h for h in header if h.startswith("element vertex")))
    props = [h.split() for h in header[at + 1:] if h.startswith("property")][:header[at + 1:].index(
        next(h for h in header[at + 1:] if h.startswith("element")))]
    assert [p[2] for p in props[:3]] == ["x", "y", "z"] and all(p[1] == "double" for p in props)  # (then nx ny nz)
    verts = np.frombuffer(raw, dtype="<f8", count=len(props) * nv, offset=end).reshape(nv, len(props))[:, :3]
    rec = np.frombuffer(raw, dtype=[("k", "u1"), ("v", "<i4", 3), ("m", "<i4")], count=nf,
                        offset=end + 8 * len(props) * nv)
    assert np.all(rec["k"] == 3)
    assert len(raw) == end + 8 * len(props) * nv + rec.itemsize * nf
    return verts[rec["v"]], rec["m"]


@pytest.mark.parametrize("name", ["cornell", "ring"])
@pytest.mark.parametrize("ext", ["ply", "obj"])
def test_scene_export_round_trip(tmp_path, capsys, name, ext):
    path = tmp_path / f"x.{ext}"
    assert main(["scene", "export", name, str(path)]) == 0
    assert str(path) in capsys.readouterr().out
    scene = load_scene(name)
    mesh = trimesh.load(path, process=False, force="mesh")
    got = np.asarray(mesh.vertices)[np.asarray(mesh.faces)]
    if ext == "ply":  # same triangles, same order, exact
        np.testing.assert_array_equal(got, scene.triangles)
    else:  # (trimesh groups an OBJ's faces by usemtl: the same triangles; the file's order is parse_obj's, below)
        assert sorted(map(bytes, got)) == sorted(map(bytes, scene.triangles))
    if ext == "ply":
        tri, mat = parse_ply(path)
        np.testing.assert_array_equal(tri, scene.triangles)
        np.testing.assert_array_equal(mat, scene.material_index)
    else:
        np.testing.assert_array_equal(parse_obj(path), scene.triangles)
    # no temporary file left (an OBJ's MTL library beside it)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([path.name, *(["x.mtl"] if ext == "obj" else [])])


def test_exported_mesh_loads_as_a_scene(tmp_path):
    """An exported PLY is a valid mesh for a scene file, with the same triangles."""
    assert main(["scene", "export", "cornell", str(tmp_path / "c.ply")]) == 0
    (tmp_path / "s.yaml").write_text(
        "geometry: {mesh: c.ply}\n"
        "materials: {w: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n"
        "default_material: w\n"
        "camera: {eye: [278, 273, -800], target: [278, 273, 0], vfov: 39.3}\n"
        "resolution: [8, 8]\n"
    )
    scene = load_scene(str(tmp_path / "s.yaml"))
    np.testing.assert_array_equal(scene.triangles, load_scene("cornell").triangles)


def test_params(capsys):
    assert main(["params"]) == 0
    out = capsys.readouterr().out
    lines = out.strip().splitlines()
    keys = [key for key, _, _ in describe()]
    assert len(lines) == len(keys)
    for line, key in zip(lines, keys, strict=True):
        assert line.split()[0] == key
    for key in ("scene", "mode", "seed", "resolution", "bsp.levels", "bsp.memory_factor",
                "render.reflect_depth", "render.refract_depth", "render.light_samples",
                "render.exposure", "render.batch"):
        assert key in keys


@pytest.mark.slow
def test_python_dash_m(tmp_path):
    """``python -m tlm`` is the same entry point (smoke test in a subprocess)."""
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "tlm", "scene", "list"], cwd=REPO, capture_output=True,
                       text=True, timeout=60, check=False)
    assert r.returncode == 0, r.stderr
    assert "cornell" in r.stdout.split()
