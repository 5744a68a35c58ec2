"""Checking a sweep's points: each factor value checked once, the same keys, the same refusals.

``load_sweep`` checks a point's config field by field, each combination of factor values
under a field once (tlm.experiments.sweep_file._Checked), and puts each point's key together
from its fields' JSON. These tests hold it to what checking every point's whole config
did: the same point hashes (the keys of finished points and of resumes), the same first
error, word for word, and the same ``sweep.yaml``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import pytest
import yaml

import tlm.experiments.sweep_file as sweep_mod
import tlm.fingerprint as fingerprint
from tlm.config import config_from_dict
from tlm.config_words import dump_yaml, value_text
from tlm.errors import InputError
from tlm.experiments.sweep_file import Point, Sweep, _assign, expand, load_sweep

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [24, 16], "render": {"light_samples": 1},
        "arch": {"frames": 2, "trace": False, "packet_size": 32}}


def _fake_inputs(cfg, folder, source, seen=None, work=None):
    """What point_inputs gives, without the scene and the programs table (whose content
    is not what these tests pin): a function of the config alone."""
    work = json.dumps({k: v for k, v in dataclasses.asdict(cfg).items() if k != "arch"}, sort_keys=True)
    return {"functional": hashlib.sha256(work.encode()).hexdigest()[:16], "programs": str(cfg.arch.programs)}


@pytest.fixture
def fixed_inputs(monkeypatch):
    monkeypatch.setattr(fingerprint, "_CODE", "0123456789abcdef")  # (the code's own fingerprint changes with it)
    monkeypatch.setattr(sweep_mod, "point_inputs", _fake_inputs)


def _write(tmp_path: Path, **body) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, **body}, sort_keys=False))
    return path


# (computed with tlm.experiments.sweep as it was before the per-field checks: every point's whole
# config checked, hashed by config_hash; a change of the schema or of its defaults changes them all; since
# h209 the key holds arch.trace as true, BASE's false aside: HEAD's hashes of this sweep with arch.trace true;
# since h311 the schema holds arch.settle_frames: the hashes of before with that field left out of the key, checked)
PINNED = ["d668835fe0ca57d1", "606ca8cf3cdbb16c", "67b6d160cad0a242", "b2ca804e91bb0c38",
          "324e77b05445da10", "13b64b9db7ad2c77", "91efd3205866e523", "4fde2bfb1427a144"]


def test_point_hashes_are_those_of_before(tmp_path, fixed_inputs):
    """The keys of finished points: a changed hash would run every finished point again."""
    path = _write(tmp_path, set={"render.spp": 2, "estimate.filter": "disk"},
                  grid={"arch.pipelines": [1, 4], "resolution": [[24, 16], [16, 16]]},
                  zip={"arch.clock_hz": [1000000000, 6.0e8], "seed": [0, 3]})
    points = load_sweep(path).points
    assert [p.hash for p in points] == PINNED
    for p in points:  # (and the key is config_hash of the point's resolved config, arch.trace as true: h209)
        keyed = {**p.config, "arch": {**p.config["arch"], "trace": True}}
        assert p.hash == sweep_mod.config_hash(keyed, _fake_inputs(config_from_dict(p.config), None, ""))


def test_configs_are_those_of_the_whole_check(tmp_path, fixed_inputs):
    """Each point's resolved config and key, against its whole config checked alone."""
    path = _write(tmp_path, set={"render.threads": 2},
                  grid={"arch.scheduler": ["static", "dynamic"], "arch.clock_hz": [1, 2.5e8],
                        "reference.min_rounds": [2, 8], "bsp": [{"levels": 3}, None]},
                  zip={"mode": ["rcast", "pmap"], "estimate.final_gather": [0, 4]})
    sw = load_sweep(path)
    raw = {"scene": "cornell", "mode": "rcast", "resolution": [24, 16],
           "render": {"light_samples": 1, "threads": 2}, "arch": {"frames": 2, "trace": False, "packet_size": 32}}
    factors = expand({"arch.scheduler": ["static", "dynamic"], "arch.clock_hz": [1, 2.5e8],
                      "reference.min_rounds": [2, 8], "bsp": [{"levels": 3}, None]},
                     {"mode": ["rcast", "pmap"], "estimate.final_gather": [0, 4]})
    assert len(sw.points) == len(factors) == 32
    from tlm.render.planner import inert_settings

    for p, f, inert in zip(sw.points, factors, sw.inert):
        point = raw
        for k, v in f.items():
            point = _assign(point, k, v)
        cfg = config_from_dict(point)
        resolved = dataclasses.asdict(cfg)
        assert p.factors == f
        assert json.dumps(p.config) == json.dumps(resolved)  # (the keys' order too: config.resolved.yaml)
        keyed = {**resolved, "arch": {**resolved["arch"], "trace": True}}  # (the key's arch.trace: h209)
        assert p.hash == sweep_mod.config_hash(keyed, _fake_inputs(cfg, None, ""))
        assert isinstance(p.config["arch"]["clock_hz"], float)
        assert inert == inert_settings(cfg)


def _first_error(path: Path) -> str:
    """The message of the first point whose whole config fails its check (point order):
    what load_sweep said when it checked every point's config alone."""
    raw = yaml.safe_load(path.read_text())
    fixed = dict(raw["base"])
    for k, v in (raw.get("set") or {}).items():
        fixed = _assign(fixed, k, v)
    for i, factors in enumerate(expand(raw.get("grid") or {}, raw.get("zip") or {})):
        point = fixed
        for k, v in factors.items():
            point = _assign(point, k, v)
        shown = ", ".join(f"{k}={value_text(v)}" for k, v in factors.items())
        try:
            config_from_dict(point, f"{path} (point {i}: {shown})")
        except InputError as e:
            return str(e)
    raise AssertionError("no point fails")


@pytest.mark.parametrize("body", [
    {"grid": {"arch.fifo_depth": [16, 8, 4, 0], "arch.pipelines": [1, 2, 3]}},  # a late point
    {"grid": {"arch.pipelines": [1, 5000], "arch.fifo_depth": [16, 0]}},  # two bad values: the first point's
    {"grid": {"seed": [0, -1], "arch.fifo_depth": [16, 0]}},  # two sections: RunConfig's field order
    {"grid": {"arch.fifo_depth": [16, 0], "bsp.levels": [3, 99]}},
    {"zip": {"reference.min_rounds": [2, 9, 3], "reference.max_rounds": [4, 8, 2]}},  # a check across fields
    {"grid": {"reference.min_rounds": [200], "arch.pipelines": [1, 2]}},  # (the base's max_rounds)
    {"grid": {"arch.fifo_dept": [1, 2]}},  # an unknown key under a section
    {"grid": {"arch.pipelines": [1, 2], "colour": ["red"]}},  # an unknown key at the top
    {"grid": {"arch.pipelines": [1, 2], "seed.x": [1]}},  # a key under a plain field
    {"grid": {"arch": [{"fifo_depth": 2}, {"pipelines": 0}]}},  # a section as a factor
    {"grid": {"arch": [{"fifo_depth": 2}, "big"]}},
    {"grid": {"render.light_samples": [1, 4, 5]}},
    {"grid": {"arch.clock_hz": [1, float("nan")]}},
    {"grid": {"arch.trace": [True, 1]}},
    {"grid": {"arch.fifo_depth": [1, True]}},  # (True == 1: not the same value to the checks)
    {"grid": {"resolution": [[16, 16], [16, 16, 16]]}},
    {"grid": {"mode": ["rcast", "raytrace"]}},
    {"zip": {"estimate.filter": ["disk", "mvoxl"], "estimate.k": [8, 0]}},
])
def test_refusals_are_word_for_word_those_of_before(tmp_path, body, fixed_inputs):
    path = _write(tmp_path, **body)
    with pytest.raises(InputError) as got:
        load_sweep(path)
    assert str(got.value) == _first_error(path)


def test_every_config_is_checked_before_any_file_is_read(tmp_path):
    """A point that names a missing scene does not hide a later point's bad value."""
    path = _write(tmp_path, grid={"scene": ["nowhere.yaml", "cornell"], "arch.fifo_depth": [4, 0]})
    with pytest.raises(InputError) as got:
        load_sweep(path)
    assert str(got.value) == _first_error(path)
    assert "point 1: scene=nowhere.yaml, arch.fifo_depth=0" in str(got.value)


def test_each_factor_value_is_checked_once(tmp_path, fixed_inputs, monkeypatch):
    """A sweep of 400 points checks the base and the base with ``set`` as whole configs,
    and the points field by field, not one whole config per point."""
    whole = []

    def counted(raw, source="(dict)"):
        whole.append(source)
        return config_from_dict(raw, source)

    monkeypatch.setattr(sweep_mod, "config_from_dict", counted)
    path = _write(tmp_path, grid={"arch.pipelines": list(range(1, 21)), "arch.page_miss_cycles": list(range(20))})
    assert len(load_sweep(path).points) == 400
    assert len(whole) == 2, whole[:5]


def _sweep(points: list[Point], grid: dict, zipped: dict | None = None, description: str | None = None) -> Sweep:
    return Sweep(Path("/x/s.yaml"), description, {"scene": "cornell", "arch": {"fifo_depth": [1, 2]}}, None,
                 {"mode": "rcast"}, grid, zipped or {}, Path("/x"), points)


def test_sweep_yaml_is_the_dump_of_the_sweep():
    """``sweep.yaml``, put together line by line, is yaml.safe_dump of the sweep, quotes,
    escapes and folded long strings included."""
    values = ["plain", "yes", "null", "1e3", "0x1F", "", " lead", "a: b", "#hash", "- x", "é and ü", "two\nlines",
              "x" * 100, "many words " * 12, 7, -3, 2.5, 1e-05, 1e20, True, False, None]
    hashes = ["0123456789abcdef", "1234567890123456", "0000000000000012", "8e91000000000000", "1e10000000000000",
              "00000000000000ff", "abcdefabcdefabcd"]
    grid = {"scene": values, "arch.fifo_depth": [1, 2, 3]}
    factors = expand(grid, {})
    points = [Point(i, f, {}, hashes[i % len(hashes)]) for i, f in enumerate(factors)]
    sw = _sweep(points, grid, description="long " * 30)
    assert sw.marker() == dump_yaml(sw.to_dict(), sort_keys=False)
    # a list for a value: the dump's own (anchors where points share it)
    grid = {"resolution": [[16, 16], [8, 8]]}
    points = [Point(i, f, {}, hashes[i]) for i, f in enumerate(expand(grid, {"seed": [0]}))]
    sw = _sweep(points, grid, {"seed": [0]})
    assert sw.marker() == dump_yaml(sw.to_dict(), sort_keys=False)
