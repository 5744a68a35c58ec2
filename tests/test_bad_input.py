"""Malformed input through the command line: one clear line, exit status 2, nothing written.

Every case runs ``tlm run CONFIG --out DIR`` (and, for scene files, ``tlm scene show
SCENE``) in-process and checks: exit code 2; exactly one line on stderr, starting with
``tlm: error:``; no traceback; the line names the file (or ``--set``) and the key
and/or the value; and no run folder nor temporary ``.DIR.tmp-*`` folder is left.
"""

from __future__ import annotations

import copy
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import yaml

from tlm.cli import main

# A small valid scene (the ring builder, 646 triangles) and config; each case breaks one thing.
BASE_SCENE = {
    "geometry": {"builder": "ring"},
    "materials": {
        "floor": {"type": "lambertian", "albedo": [0.75, 0.75, 0.72]},
        "gold": {"type": "mirror", "reflectance": [0.95, 0.78, 0.4]},
    },
    "parts": {"floor": "floor", "ring": "gold"},
    "lights": [
        {"type": "point", "position": [40.0, 18.0, 12.0], "power": [8e4, 8e4, 8e4]},
        {"type": "quad", "corner": [-5.0, 20.0, -5.0], "edge_u": [10.0, 0.0, 0.0],
         "edge_v": [0.0, 0.0, 10.0], "power": [100.0, 100.0, 100.0]},
    ],
    "camera": {"eye": [0.0, 32.0, -26.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "vfov": 30.0},
    "resolution": [16, 12],
}
BASE_CONFIG = {"scene": "scene.yaml", "mode": "refract", "seed": 0,
               "render": {"light_samples": 1}}

TRI_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def ply_binary(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    body = np.asarray(vertices, dtype="<f4").tobytes()
    for f in faces:
        body += struct.pack("<B3i", 3, *f)
    return header + body


@dataclass
class Case:
    """``config``/``scene``: a change applied to a deep copy of the base mapping, or text.

    ``extra``: files to write (name -> str or bytes). ``argv``: extra CLI arguments.
    ``expect``: substrings of the error line. ``show``: also check ``tlm scene show``.
    """

    config: Callable[[dict], None] | str | None = None
    scene: Callable[[dict], None] | str | None = None
    extra: dict[str, str | bytes] = field(default_factory=dict)
    argv: list[str] = field(default_factory=list)
    expect: tuple[str, ...] = ()
    show: bool = False
    config_path: str = "cfg.yaml"  # what to pass to `tlm run`


def setter(path: str, value) -> Callable[[dict], None]:
    """Set ``a.b.c`` (list indices as numbers) in a mapping."""
    def apply(d: dict) -> None:
        keys = path.split(".")
        node = d
        for k in keys[:-1]:
            node = node[int(k)] if isinstance(node, list) else node.setdefault(k, {})
        last = keys[-1]
        if isinstance(node, list):
            node[int(last)] = value
        else:
            node[last] = value
    return apply


def deleter(path: str) -> Callable[[dict], None]:
    def apply(d: dict) -> None:
        keys = path.split(".")
        node = d
        for k in keys[:-1]:
            node = node[int(k)] if isinstance(node, list) else node[k]
        del node[keys[-1]]
    return apply


def mesh_scene(name: str) -> Callable[[dict], None]:
    def apply(d: dict) -> None:
        d["geometry"] = {"mesh": name}
        d["parts"] = {}
        d["default_material"] = "floor"
    return apply


CASES: dict[str, Case] = {
    # ---- the config file
    "config-yaml-syntax": Case(config="scene: scene.yaml\nmode: [rcast\n", expect=("cfg.yaml", "YAML syntax error")),
    "config-yaml-tab": Case(config="scene: scene.yaml\nrender:\n\treflect_depth: 2\n", expect=("cfg.yaml", "YAML")),
    "config-not-mapping": Case(config="- scene\n- mode\n", expect=("cfg.yaml", "mapping")),
    # an empty file is not all the defaults by mistake (a Cornell render at 320x320)
    "config-empty": Case(config="", expect=("cfg.yaml", "is empty")),
    "config-comments-only": Case(config="# scene: ring\n\n", expect=("cfg.yaml", "is empty")),
    "set-empty-key": Case(argv=["--set", "=3"], expect=("--set", "'=3'", "empty")),
    "set-empty-key-part": Case(argv=["--set", "render..spp=3"], expect=("--set", "'render..spp=3'", "empty part")),
    "seed-flag-and-set": Case(argv=["--set", "seed=5", "--seed", "7"], expect=("--seed", "--set seed=5", "give one")),
    "mode-flag-and-set": Case(argv=["--set", "mode=pmap", "--mode", "rcast"], expect=("--mode", "--set mode=pmap")),
    # a run config where a scene file is named (a config's neighbour shadowing a built-in scene's name)
    "scene-is-a-run-config": Case(config=setter("scene", "other.yaml"), extra={"other.yaml": "scene: cornell\n"},
                                  expect=("other.yaml", "is a run config", "scene: cornell")),
    # a key given twice: PyYAML keeps the last silently, so a second section would undo the first
    "config-duplicate-section": Case(config="scene: scene.yaml\nrender: {spp: 1}\nmode: rcast\nrender:\n"
                                            "  light_samples: 1\n",
                                     expect=("cfg.yaml", "line 4", "duplicate key 'render'", "first at line 2")),
    "config-duplicate-nested": Case(config="scene: scene.yaml\nrender: {light_samples: 1, light_samples: 4}\n",
                                    expect=("cfg.yaml", "duplicate key 'light_samples'")),
    "set-duplicate-key": Case(argv=["--set", "render={spp: 1, spp: 2}"], expect=("--set", "render")),
    # a binary file where YAML text is expected (a PNG header, a UTF-16 file): one line, not a traceback
    "config-binary": Case(extra={"bin.yaml": b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR"}, config_path="bin.yaml",
                          expect=("bin.yaml", "not a UTF-8 text file", "0x89")),
    "config-utf16": Case(extra={"u16.yaml": "scene: scene.yaml\n".encode("utf-16")}, config_path="u16.yaml",
                         expect=("u16.yaml", "not a UTF-8 text file")),
    "scene-binary": Case(config=setter("scene", "bin_scene.yaml"), extra={"bin_scene.yaml": b"name: \xff\xfe\x00"},
                         expect=("bin_scene.yaml", "not a UTF-8 text file", "0xff")),
    # a clock past a terahertz (a typo: 6e29 FPS was printed) and a cache block too small to prefetch from
    "clock-absurd": Case(argv=["--set", "arch.clock_hz=1e30"], expect=("arch.clock_hz", "1e30", "1e12")),
    "block-of-two-words": Case(argv=["--set", "cache.block_words=2"], expect=("cache.block_words", "2", ">= 3")),
    # a cost table whose scale makes more cycles than an int64 holds (was an internal error)
    "programs-absurd-scale": Case(config=setter("arch.programs", "progs.yaml"), extra={"progs.yaml": yaml.safe_dump(
        {**(lambda t: {**t, "vertex": {**t["vertex"], "scale": 1e20}})(yaml.safe_load(
            (Path(__file__).resolve().parents[1] / "tlm" / "arch" / "programs.yaml").read_text()))})},
        expect=("progs.yaml", "vertex.", "64-bit cycle count")),
    "programs-binary": Case(config=setter("arch.programs", "progs.yaml"), extra={"progs.yaml": b"\x00\x9f\x92\x96"},
                            expect=("progs.yaml", "not a UTF-8 text file", "0x9f")),
    "config-unknown-top-key": Case(config=setter("mdoe", "rcast"),
                                   expect=("cfg.yaml", "mdoe", "did you mean 'mode'")),
    "config-unknown-nested-key": Case(config=setter("render.reflect_dept", 2),
                                      expect=("cfg.yaml", "render.reflect_dept", "did you mean 'reflect_depth'")),
    "config-section-not-mapping": Case(config=setter("render", 5), expect=("cfg.yaml", "render", "5")),
    "config-string-for-int": Case(config=setter("seed", "abc"), expect=("cfg.yaml", "seed: abc is not an integer")),
    "config-float-for-int": Case(config=setter("render.reflect_depth", 2.5),
                                 expect=("cfg.yaml", "render.reflect_depth", "2.5")),
    "config-bool-for-int": Case(config=setter("seed", True), expect=("cfg.yaml", "seed: true is not an integer")),
    "config-list-for-float": Case(config=setter("bsp.memory_factor", [1, 2]),
                                  expect=("cfg.yaml", "bsp.memory_factor", "[1, 2]")),
    "config-nan-float": Case(config="scene: scene.yaml\nbsp: {memory_factor: .nan}\n",
                             expect=("cfg.yaml", "bsp.memory_factor", "nan")),
    "config-bad-mode": Case(config=setter("mode", "fast"), expect=("cfg.yaml", "mode: fast is not one of")),
    "config-light-samples-zero": Case(config=setter("render.light_samples", 0),
                                      expect=("cfg.yaml", "render.light_samples", "0")),
    "config-light-samples-not-square": Case(config=setter("render.light_samples", 3),
                                            expect=("cfg.yaml", "render.light_samples", "3", "square")),
    "config-negative-seed": Case(config=setter("seed", -1), expect=("cfg.yaml", "seed", "-1")),
    "config-levels-too-deep": Case(config=setter("bsp.levels", 30), expect=("cfg.yaml", "bsp.levels", "30")),
    "config-memory-factor-small": Case(config=setter("bsp.memory_factor", 0.5),
                                       expect=("cfg.yaml", "bsp.memory_factor", "0.5")),
    "config-exposure-zero": Case(config=setter("render.exposure", 0), expect=("cfg.yaml", "render.exposure", "0")),
    "config-resolution-zero": Case(config=setter("resolution", [0, 10]),
                                   expect=("cfg.yaml", "resolution", "[0, 10]")),
    "config-resolution-negative": Case(config=setter("resolution", [-5, 5]),
                                       expect=("cfg.yaml", "resolution", "[-5, 5]")),
    "config-resolution-length": Case(config=setter("resolution", [10, 10, 10]),
                                     expect=("cfg.yaml", "resolution", "[10, 10, 10]")),
    "config-resolution-float": Case(config=setter("resolution", [10.5, 10]),
                                    expect=("cfg.yaml", "resolution", "10.5")),
    "config-missing-scene-file": Case(config=setter("scene", "nothere.yaml"),
                                      expect=("nothere.yaml", "scene", "not found")),
    "config-missing": Case(config_path="missing.yaml", expect=("missing.yaml", "not found")),
    # ---- --set
    "set-no-equals": Case(argv=["--set", "foo"], expect=("--set", "'foo'")),
    "set-unknown-key": Case(argv=["--set", "render.unknown=1"], expect=("--set", "render.unknown")),
    "set-unknown-top-key": Case(argv=["--set", "sede=3"], expect=("--set", "sede", "did you mean 'seed'")),
    "set-bad-yaml": Case(argv=["--set", "resolution=[48"], expect=("--set", "resolution", "[48")),
    "set-wrong-type": Case(argv=["--set", "render.light_samples=many"],
                           expect=("--set", "render.light_samples: many is not an integer")),
    "set-absurd-resolution": Case(argv=["--set", "resolution=[1000000,1000000]"],
                                  expect=("--set", "resolution", "[1000000, 1000000]", "GiB")),
    "set-mode-typo": Case(argv=["--set", "mode=refrac"],
                          expect=("--set", "mode: refrac is not one of", "did you mean 'refract'")),
    # ---- the scene file
    "scene-yaml-syntax": Case(scene="geometry: {builder: ring\n", expect=("scene.yaml", "YAML syntax error"),
                              show=True),
    "scene-duplicate-lights": Case(scene=yaml.safe_dump(BASE_SCENE, sort_keys=False) + "lights: []\n",
                                   expect=("scene.yaml", "duplicate key 'lights'"), show=True),
    "scene-unknown-key": Case(scene=setter("camra", {}), expect=("scene.yaml", "camra", "did you mean 'camera'"),
                              show=True),
    "scene-unknown-material-type": Case(scene=setter("materials.floor.type", "glossy"),
                                        expect=("scene.yaml", "materials.floor", "'glossy'"), show=True),
    "scene-unknown-material-key": Case(scene=setter("materials.floor.albdo", [0.1, 0.1, 0.1]),
                                       expect=("scene.yaml", "materials.floor.albdo", "did you mean 'albedo'"),
                                       show=True),
    "scene-part-unknown-material": Case(scene=setter("parts.floor", "marble"),
                                        expect=("scene.yaml", "parts.floor", "'marble'"), show=True),
    "scene-part-not-in-geometry": Case(scene=setter("parts.roof", "floor"),
                                       expect=("scene.yaml", "parts.roof", "'roof'"), show=True),
    "scene-part-without-material": Case(scene=deleter("parts.ring"), expect=("scene.yaml", "parts", "'ring'"),
                                        show=True),
    "scene-albedo-above-one": Case(scene=setter("materials.floor.albedo", [1.5, 0.5, 0.5]),
                                   expect=("scene.yaml", "materials.floor.albedo", "1.5"), show=True),
    "scene-albedo-short": Case(scene=setter("materials.floor.albedo", [0.5, 0.5]),
                               expect=("scene.yaml", "materials.floor.albedo", "[0.5, 0.5]"), show=True),
    "scene-ior-zero": Case(scene=setter("materials.gold", {"type": "dielectric", "ior": 0}),
                           expect=("scene.yaml", "materials.gold.ior", "0"), show=True),
    "scene-negative-power": Case(scene=setter("lights.0.power", [-1.0, 1.0, 1.0]),
                                 expect=("scene.yaml", "lights[0].power", "-1.0"), show=True),
    "scene-light-zero-area": Case(scene=setter("lights.1.edge_v", [20.0, 0.0, 0.0]),
                                  expect=("scene.yaml", "lights[1]", "area"), show=True),
    "scene-light-zero-edge": Case(scene=setter("lights.1.edge_u", [0.0, 0.0, 0.0]),
                                  expect=("scene.yaml", "lights[1]", "area"), show=True),
    "scene-light-unknown-type": Case(scene=setter("lights.0.type", "laser"),
                                     expect=("scene.yaml", "lights[0]", "'laser'", "quad, point, spot, directional"),
                                     show=True),
    "scene-light-missing-edge": Case(scene=deleter("lights.1.edge_v"),
                                     expect=("scene.yaml", "lights[1].edge_v", "required for type quad"), show=True),
    "scene-camera-eye-is-target": Case(scene=setter("camera.target", [0.0, 32.0, -26.0]),
                                       expect=("scene.yaml", "camera", "eye and target"), show=True),
    "scene-camera-up-parallel": Case(scene=setter("camera.up", [0.0, -32.0, 26.0]),
                                     expect=("scene.yaml", "camera.up", "parallel"), show=True),
    "scene-vfov-zero": Case(scene=setter("camera.vfov", 0), expect=("scene.yaml", "camera.vfov", "0"), show=True),
    "scene-vfov-180": Case(scene=setter("camera.vfov", 180), expect=("scene.yaml", "camera.vfov", "180"), show=True),
    "scene-camera-nan": Case(scene="geometry: {builder: ring}\nmaterials: {m: {type: mirror, reflectance: [1, 1, 1]}}\n"
                             "default_material: m\ncamera: {eye: [0, .nan, 0], target: [0, 0, 1], vfov: 30}\n"
                             "resolution: [8, 8]\n", expect=("scene.yaml", "camera.eye", "nan"), show=True),
    "scene-resolution-zero": Case(scene=setter("resolution", [0, 5]), expect=("scene.yaml", "resolution", "[0, 5]"),
                                  show=True),
    "scene-absurd-resolution": Case(scene=setter("resolution", [1000000, 1000000]),
                                    expect=("scene.yaml", "resolution", "GiB"), show=True),
    "scene-both-builder-and-mesh": Case(scene=setter("geometry.mesh", "x.obj"),
                                        expect=("scene.yaml", "geometry", "exactly one"), show=True),
    "scene-unknown-builder": Case(scene=setter("geometry.builder", "rng"),
                                  expect=("scene.yaml", "geometry.builder", "'rng'", "did you mean 'ring'"),
                                  show=True),
    "scene-bad-builder-param": Case(scene=setter("geometry.params", {"n_seg": -3}),
                                    expect=("scene.yaml", "geometry.params", "n_seg"), show=True),
    # a tessellation larger than the machine: refused before it is allocated (not an out-of-memory kill)
    "scene-huge-builder": Case(scene=setter("geometry.params", {"n_seg": 10**9}),
                               expect=("scene.yaml", "geometry.params", "GiB", "more than this machine"), show=True),
    "scene-huge-shape": Case(scene=setter("geometry", [{"shape": "sphere", "params": {"segments": 10**5,
                                                                                      "rings": 10**5}}]),
                             expect=("scene.yaml", "geometry[0].params", "19,999,800,000 triangles", "GiB"),
                             show=True),
    "set-huge-caustic-count": Case(config=setter("mode", "pmap"),
                                   argv=["--set", "photons.count=1000", "--set",
                                         "photons.caustic_count=10000000000000"],
                                   expect=("--set", "photons.count + photons.caustic_count", "10,000,000,001,000")),
    "set-huge-photon-count": Case(config=setter("mode", "pmap"), argv=["--set", "photons.count=10000000000000"],
                                  expect=("--set", "photons.count", "10,000,000,000,000 photons", "GiB")),
    # the reference a pmap run computes (none can be cached at that size): said with the run's own check
    "set-huge-reference-photons": Case(config=setter("mode", "pmap"),
                                       argv=["--set", "photons.count=1000",
                                             "--set", "reference.photons=10000000000000"],
                                       expect=("--set", "reference.photons", "10,000,000,000,000 photons", "GiB")),
    "scene-unknown-builder-param": Case(scene=setter("geometry.params", {"segments": 10}),
                                        expect=("scene.yaml", "geometry.params", "segments"), show=True),
    # ---- meshes
    # finite numbers whose products overflow (an infinite light power in results.json, warnings)
    "scene-emission-huge": Case(scene=setter("materials.floor.emission", [1e308, 1e308, 1e308]),
                                expect=("scene.yaml", "materials.floor.emission", "beyond"), show=True),
    "scene-power-huge": Case(scene=setter("lights.0.power", [1e31, 1.0, 1.0]),
                             expect=("scene.yaml", "lights[0].power", "beyond"), show=True),
    "mesh-far-vertex-obj": Case(scene=mesh_scene("far.obj"),
                                extra={"far.obj": "v 0 0 0\nv 1e35 0 0\nv 0 1 0\nf 1 2 3\n"},
                                expect=("scene.yaml", "geometry", "beyond"), show=True),
    "scene-extends-missing": Case(scene="extends: nope.yaml\n", expect=("scene.yaml", "extends:", "'nope.yaml'"),
                                  show=True),
    "mesh-is-a-folder": Case(scene=mesh_scene("."), expect=("scene.yaml", "geometry.mesh", "is a folder"), show=True),
    "mesh-nan-vertex-obj": Case(scene=mesh_scene("bad.obj"),
                                extra={"bad.obj": "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n"},
                                expect=("bad.obj", "NaN"), show=True),
    "mesh-inf-vertex-ply": Case(scene=mesh_scene("bad.ply"),
                                extra={"bad.ply": ply_binary(np.array([[0, 0, 0], [1, 0, 0], [0, np.inf, 0]]),
                                                             np.array([[0, 1, 2]]))},
                                expect=("bad.ply", "infinite"), show=True),
    "mesh-empty-file": Case(scene=mesh_scene("empty.obj"), extra={"empty.obj": ""},
                            expect=("empty.obj", "empty"), show=True),
    "mesh-no-faces": Case(scene=mesh_scene("points.obj"), extra={"points.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\n"},
                          expect=("points.obj", "without faces"), show=True),
    "mesh-missing-file": Case(scene=mesh_scene("nothere.obj"),
                              expect=("scene.yaml", "geometry.mesh", "nothere.obj", "not found"), show=True),
    "mesh-unsupported-extension": Case(scene=mesh_scene("tri.xyz"), extra={"tri.xyz": TRI_OBJ},
                                       expect=("tri.xyz", "unsupported", "'.xyz'"), show=True),
    "mesh-garbage-ply": Case(scene=mesh_scene("junk.ply"), extra={"junk.ply": b"ply\nformat nonsense\n\x00\x01"},
                             expect=("junk.ply",), show=True),
    "mesh-not-a-string": Case(scene=setter("geometry", {"mesh": 5}), expect=("scene.yaml", "geometry.mesh", "5"),
                              show=True),
}


# Bugs: the scene's and resolution's errors do not name the config file they come from.
NO_CONFIG_FILE = "BUG: errors about the config's `scene`/`resolution` keys do not name the config file"
CONFIG_SCENE_CASES = {
    "config-unknown-scene-name": Case(config=setter("scene", "cornel"),
                                      expect=("scene", "'cornel'", "did you mean 'cornell'")),
    "config-absurd-resolution": Case(config=setter("resolution", [1000000, 1000000]),
                                     expect=("resolution", "[1000000, 1000000]", "GiB")),
}


def write_inputs(tmp_path: Path, case: Case) -> None:
    scene = copy.deepcopy(BASE_SCENE)
    if isinstance(case.scene, str):
        (tmp_path / "scene.yaml").write_text(case.scene)
    else:
        if case.scene is not None:
            case.scene(scene)
        (tmp_path / "scene.yaml").write_text(yaml.safe_dump(scene, sort_keys=False))
    config = copy.deepcopy(BASE_CONFIG)
    if isinstance(case.config, str):
        (tmp_path / "cfg.yaml").write_text(case.config)
    else:
        if case.config is not None:
            case.config(config)
        (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    for name, content in case.extra.items():
        p = tmp_path / name
        if isinstance(content, bytes):
            p.write_bytes(content)
        else:
            p.write_text(content)


def snapshot(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def run_and_check(tmp_path: Path, capsys, argv: list[str], expect: tuple[str, ...]) -> str:
    before = snapshot(tmp_path)
    code = main(argv)
    cap = capsys.readouterr()
    assert code == 2, (code, cap.err)
    lines = cap.err.splitlines()
    assert len(lines) == 1, cap.err
    line = lines[0]
    assert line.startswith("tlm: error: ")
    assert "Traceback" not in cap.err and "Traceback" not in cap.out
    for s in expect:
        assert s in line, f"{s!r} not in {line!r}"
    after = snapshot(tmp_path)
    assert after == before, f"left behind: {after - before}"
    assert not any(".tmp-" in p for p in after)
    return line


def run_argv(tmp_path: Path, case: Case) -> list[str]:
    return ["run", str(tmp_path / case.config_path), "--out", str(tmp_path / "out"), *case.argv]


@pytest.mark.slow
def test_base_inputs_are_valid(tmp_path, capsys):
    """The unbroken scene and config render (so each case breaks exactly one thing)."""
    write_inputs(tmp_path, Case())
    assert main(["scene", "show", str(tmp_path / "scene.yaml")]) == 0
    assert main(["run", str(tmp_path / "cfg.yaml"), "--out", str(tmp_path / "out")]) == 0
    assert (tmp_path / "out" / "results.json").is_file()
    # the mesh variant too
    write_inputs(tmp_path, Case(scene=mesh_scene("tri.obj"), extra={"tri.obj": TRI_OBJ}))
    assert main(["scene", "show", str(tmp_path / "scene.yaml")]) == 0
    capsys.readouterr()


@pytest.mark.slow
@pytest.mark.parametrize("name", list(CASES))
def test_bad_run(tmp_path, capsys, name):
    case = CASES[name]
    write_inputs(tmp_path, case)
    run_and_check(tmp_path, capsys, run_argv(tmp_path, case), case.expect)


@pytest.mark.slow
@pytest.mark.parametrize("name", [n for n, c in CASES.items() if c.show])
def test_bad_scene_show(tmp_path, capsys, name):
    case = CASES[name]
    write_inputs(tmp_path, case)
    run_and_check(tmp_path, capsys, ["scene", "show", str(tmp_path / "scene.yaml")], case.expect)


@pytest.mark.parametrize("name", list(CONFIG_SCENE_CASES))
def test_bad_config_scene_keys(tmp_path, capsys, name):
    case = CONFIG_SCENE_CASES[name]
    write_inputs(tmp_path, case)
    run_and_check(tmp_path, capsys, run_argv(tmp_path, case), case.expect)


@pytest.mark.parametrize("name", list(CONFIG_SCENE_CASES))
def test_bad_config_scene_keys_name_the_config(tmp_path, capsys, name):
    case = CONFIG_SCENE_CASES[name]
    write_inputs(tmp_path, case)
    run_and_check(tmp_path, capsys, run_argv(tmp_path, case), (*case.expect, "cfg.yaml"))


def test_scene_show_unknown_name(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    run_and_check(tmp_path, capsys, ["scene", "show", "cornel"], ("'cornel'", "did you mean 'cornell'"))
    run_and_check(tmp_path, capsys, ["scene", "show", "nothere.yaml"], ("nothere.yaml", "not found"))


def test_scene_export_bad_extension(tmp_path, capsys):
    run_and_check(tmp_path, capsys, ["scene", "export", "ring", str(tmp_path / "x.stl")],
                  ("x.stl", "unsupported", "'.stl'"))


def test_existing_run_folder_survives_a_bad_run(tmp_path, capsys):
    """A failed run must not remove or touch an earlier run folder of the same name."""
    write_inputs(tmp_path, Case(config=setter("render.light_samples", 3)))
    out = tmp_path / "out"
    out.mkdir()
    (out / "results.json").write_text("{}")
    run_and_check(tmp_path, capsys, ["run", str(tmp_path / "cfg.yaml"), "--out", str(out)], ("cfg.yaml",))
    assert (out / "results.json").read_text() == "{}"


@pytest.mark.parametrize("argv", [["--seed", "abc"], ["--mode", "fast"]], ids=["seed-abc", "mode-fast"])
def test_bad_command_line_arguments(tmp_path, capsys, argv):
    write_inputs(tmp_path, Case())
    try:
        code = main(["run", str(tmp_path / "cfg.yaml"), "--out", str(tmp_path / "out"), *argv])
    except SystemExit as e:
        code = e.code
    cap = capsys.readouterr()
    assert code == 2
    assert not (tmp_path / "out").exists()
    lines = cap.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("tlm: error: "), cap.err
    assert argv[1] in lines[0]


@pytest.mark.parametrize("text", [
    "a: &a {x: 1}\nb: {<<: *a, x: 2}\n",
    "a: &a {x: 1}\nb: {<<: [*a], x: 2, y: 3}\n",
    # an anchored mapping that merges, merged later by a sibling of its parent (PyYAML flattens
    # it in place first) and merged twice
    "base: &base {x: 1}\nsec:\n  sub: &s\n    <<: *base\n    x: 2\nother:\n  <<: *s\n",
    "base: &base {x: 1}\npoints: [&p1 {<<: *base, x: 2}]\nother: {<<: *p1}\nmore: {<<: *p1, y: 3}\n",
    "a: {<<: &m {x: 1, y: 2}, x: 3}\nb: {<<: *m}\n",
    "a: &a {x: 1}\nb: &b {<<: *a, x: 2}\nc: {<<: *b}\nd: {<<: *b}\n",
])
def test_merge_keys_may_be_set_again_as_yaml_allows(text):
    from tlm.config_words import parse_yaml

    assert parse_yaml(text) == yaml.safe_load(text)


@pytest.mark.parametrize("text", ["a: 1\na: 2\n", "a: {x: 1, x: 2}\n", "a: &a {x: 1}\nb: {<<: *a, y: 1, y: 2}\n",
                                  "l: [{q: 1, q: 2}]\n"])
def test_a_key_given_twice_in_one_mapping_is_refused(text):
    from tlm.config_words import DuplicateKeyError, parse_yaml

    with pytest.raises(DuplicateKeyError, match="duplicate key"):
        parse_yaml(text)


def test_a_reference_too_large_for_memory_is_refused_before_the_render(tmp_path, capsys, monkeypatch, cache):
    """The run checks the photons of the reference it will compute with its own, before rendering
    anything; a run that finds its reference cached, or computes none (``--no-reference``), does not."""
    import tlm.experiments.run as runs

    def no_render(*a, **k):
        raise AssertionError("rendered before the reference's photons were checked")

    write_inputs(tmp_path, Case(config=setter("mode", "pmap")))
    monkeypatch.setattr(runs, "render_batches", no_render)
    argv = ["run", str(tmp_path / "cfg.yaml"), "--out", str(tmp_path / "out"), "--set", "photons.count=1000",
            "--set", "reference.photons=10000000000000"]
    run_and_check(tmp_path, capsys, argv, ("reference.photons", "GiB"))
    assert main([*argv, "--no-reference"]) == 1  # no reference, no check: on to the render
    assert "rendered before" in capsys.readouterr().err
