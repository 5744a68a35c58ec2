"""Sweep factors that change no result, and a null beside the value it resolves to (h490, from the probe h484).

* ``render.batch`` and ``render.batch_rays`` change the host's speed and memory alone (the work, the cycles and
  the images are bit-identical for every value): a sweep over them is refused, as one over ``render.threads`` is,
  before any point runs (it rendered each value again, with identical rows).
* ``render.exposure`` scales only the pictures ``tlm run`` writes, and a sweep writes none: said to change nothing.
* ``arch.programs: [null, <tlm's own table>]`` is one table: refused as a value given twice; ``bsp.levels: [null,
  7]`` on cornell (floor(ln 2604) = 7) is said after the points ran, from their ``results.json``.
* ``grid: {resolution: [32, 32]}`` says each value must be ``[w, h]`` (not ``32 given twice``), and a point's
  error names its factor values as YAML writes them (``null``, ``true``, ``RCast``), not as Python's reprs.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import pytest
import yaml

import tlm.experiments.sweep_file as sweep_mod
from tlm.arch.costs import DEFAULT_PATH
from tlm.errors import InputError
from tlm.experiments.sweep_file import load_sweep

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [24, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False}}


def _fake_inputs(cfg, folder, source, seen=None, work=None):
    """What point_inputs gives, without loading the scene or the table: a function of the config alone."""
    work = json.dumps({k: v for k, v in dataclasses.asdict(cfg).items() if k != "arch"}, sort_keys=True)
    return {"functional": hashlib.sha256(work.encode()).hexdigest()[:16], "programs": str(cfg.arch.programs)}


@pytest.fixture(autouse=True)
def fixed_inputs(monkeypatch):
    monkeypatch.setattr(sweep_mod, "point_inputs", _fake_inputs)


def _write(tmp_path: Path, **body) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, **body}, sort_keys=False))
    return path


@pytest.mark.parametrize("key, values, host", [("render.batch", [1, 4, 16], "speed"),
                                               ("render.batch_rays", [4096, 131072], "memory")])
def test_a_factor_of_the_host_alone_is_refused(tmp_path, key, values, host):
    with pytest.raises(InputError) as e:
        load_sweep(_write(tmp_path, grid={key: values, "arch.fifo_depth": [4, 16]}))
    text = str(e.value)
    assert e.value.key == key
    assert f"points 0 and 2 differ only in {key} ({key} changes no result, only the host's {host}" in text, text
    assert f"give {key} under set:" in text and f"tlm run --set {key}=N" in text, text
    # (a section's mapping that sets it alone: the same; one that sets spp too, or a zip beside spp: other runs)
    with pytest.raises(InputError, match=r"differ only in render \(render.batch changes no result"):
        load_sweep(_write(tmp_path, grid={"render": [{"batch": 1}, {"batch": 4}]}))
    assert len(load_sweep(_write(tmp_path, zip={key: values[:2], "render.spp": [1, 4]})).points) == 2
    assert len(load_sweep(_write(tmp_path, set={key: values[0]}, grid={"render.spp": [1, 4]})).points) == 2


def test_the_threads_and_a_batch_together_are_named_both(tmp_path):
    with pytest.raises(InputError) as e:
        load_sweep(_write(tmp_path, zip={"render.threads": [1, 2], "render.batch": [1, 4]}))
    assert "(render.threads, render.batch change no result, only the host's speed" in str(e.value), str(e.value)


def test_the_exposure_is_said_to_change_nothing(tmp_path):
    path = _write(tmp_path, grid={"render.exposure": [0.5, 1.0, 2.0]})
    sweep = load_sweep(path)
    assert len(sweep.points) == 3
    assert sweep.inert_factors() == [f"{path}: the factor render.exposure changes nothing in any point: a sweep "
                                     "writes no image, and the exposure scales only the pictures tlm run writes "
                                     "(not the work, the cycles or the radiance's errors)"]
    said = load_sweep(_write(tmp_path, grid={"arch.fifo_depth": [4, 16]}), ["render.exposure=2"]).inert_sets()
    assert len(said) == 1 and "--set render.exposure=2 changes nothing in any point" in said[0], said


def test_a_null_programs_table_beside_its_own_file_is_refused(tmp_path):
    table = str(Path(DEFAULT_PATH).resolve())
    with pytest.raises(InputError) as e:
        load_sweep(_write(tmp_path, grid={"arch.programs": [None, table]}))
    assert e.value.key == "arch.programs"
    assert (f"points 0 and 1 are one run: arch.programs: null and {table} give one programs table (null is "
            f"tlm's own, {table}): give one of them") in str(e.value), str(e.value)
    with pytest.raises(InputError, match=r"arch: \{programs: null\} and \{programs: "):  # (a section's mapping)
        load_sweep(_write(tmp_path, grid={"arch": [{"programs": None}, {"programs": table}]}))


def test_a_null_that_resolved_to_another_value_is_said_after_the_points(tmp_path):
    path = _write(tmp_path, grid={"bsp.levels": [None, 5, 7], "arch.fifo_depth": [4, 16]})
    sweep = load_sweep(path)

    def results(point) -> dict:
        levels = point.factors["bsp.levels"]
        return {"scene": {"triangles": 2604, "bsp": {"requested_levels": 7 if levels is None else levels}}}

    lines = sweep.unread_factors([(p, results(p)) for p in sweep.points])
    assert lines == [f"{path}: the factor bsp.levels: null and 7 were one setting at points 0 and 4 (and 1 more such "
                     "pair) (null is floor(ln n) of the scene's 2604 triangles, 7 there), so they ran one run twice: "
                     "give one of them"], lines
    assert sweep.unread_factors([(p, results(p)) for p in sweep.points if p.factors["bsp.levels"] != 7]) == []


def test_a_value_of_the_wrong_type_is_said_before_a_value_given_twice(tmp_path):
    with pytest.raises(InputError) as e:
        load_sweep(_write(tmp_path, grid={"resolution": [32, 32]}))
    assert "(point 0: resolution=32): resolution: 32 is not a list of 2 integers" in str(e.value), str(e.value)
    with pytest.raises(InputError, match=r"grid.resolution: \[32, 32\] given twice"):  # (as before: both right)
        load_sweep(_write(tmp_path, grid={"resolution": [[32, 32], [32, 32]]}))


@pytest.mark.parametrize("grid, shown", [({"arch.fifo_depth": [4, None]}, "arch.fifo_depth=null"),
                                         ({"arch.fifo_depth": [4, True]}, "arch.fifo_depth=true"),
                                         ({"mode": ["rcast", "RCast"]}, "mode=RCast"),
                                         ({"render.light_samples": [1, "four"]}, "render.light_samples=four")])
def test_a_point_error_names_its_values_as_yaml_writes_them(tmp_path, grid, shown):
    with pytest.raises(InputError) as e:
        load_sweep(_write(tmp_path, grid=grid))
    assert f"(point 1: {shown}): " in str(e.value), str(e.value)
    with pytest.raises(InputError, match=r"grid: must be a mapping of dotted keys, got \[a, b\]$"):
        load_sweep(_write(tmp_path, grid=["a", "b"]))
    with pytest.raises(InputError, match=r"grid.mode: rcast is not a list of values$"):
        load_sweep(_write(tmp_path, grid={"mode": "rcast"}))
