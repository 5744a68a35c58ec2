"""A RunConfig given to the API is checked as a mapping is; the loaded config is immutable (h502).

1. A ``RunConfig`` changed with ``dataclasses.replace`` (``tlm.render_image(replace(cfg.settings, mode="nope"))``)
   was never checked: ``tlm.api_config.load_config`` wrapped it in a ``Config`` as it was, and so did a ``Config``
   made of one, so a bad value failed deep in the render (``tuple.index`` in the planner, a ``KeyError`` in SimPy)
   or not at all (``seed=-3``: a run whose ``config.resolved.yaml`` did not load again). Now ``Config`` checks its
   settings by ``config_from_dict``'s rules (:func:`tlm.config.checked`): the same InputError as the mapping's, once
   (what the checks made is not checked again: a loaded config, and the sections a ``replace`` kept).
2. ``cfg.resolution`` was a list in a frozen config: ``cfg.resolution[0] = 16`` changed a result already returned,
   and ``hash(cfg.settings)`` raised TypeError. A list-valued setting is now held as a tuple; what is written (the
   YAML, the JSON, the keys: :func:`tlm.config.to_dict`) and the messages still spell it as the list.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import json
import pickle
import re
from pathlib import Path

import numpy as np
import pytest

import tlm
from tlm import config as config_module
from tlm.api_config import Config
from tlm.config import RunConfig, to_dict
from tlm.config_words import dump_yaml
from tlm.errors import InputError

SMALL = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1}}
R = dataclasses.replace


@pytest.fixture(scope="module")
def cfg():
    return tlm.load_config(SMALL)


# (what replace gives the settings, the same key and value given in a mapping)
BAD = {
    "mode": (lambda s: R(s, mode="nope"), {"mode": "nope"}),
    "spp 0": (lambda s: R(s, render=R(s.render, spp=0)), {"render.spp": 0}),
    "spp 2.5": (lambda s: R(s, render=R(s.render, spp=2.5)), {"render.spp": 2.5}),
    "light_samples 2": (lambda s: R(s, render=R(s.render, light_samples=2)), {"render.light_samples": 2}),
    "scene None": (lambda s: R(s, scene=None), {"scene": None}),
    "pipelines 0": (lambda s: R(s, arch=R(s.arch, pipelines=0)), {"arch.pipelines": 0}),
    "seed -3": (lambda s: R(s, seed=-3), {"seed": -3}),
    "resolution [16, 0]": (lambda s: R(s, resolution=[16, 0]), {"resolution": [16, 0]}),
    "resolution of 3": (lambda s: R(s, resolution=(16, 32, 3)), {"resolution": [16, 32, 3]}),
    "dynamic tiles": (lambda s: R(s, arch=R(s.arch, scheduler="dynamic", pipelines=4096, tiles_per_pipeline=17)),
                      {"arch.scheduler": "dynamic", "arch.pipelines": 4096, "arch.tiles_per_pipeline": 17}),
    "rounds": (lambda s: R(s, reference=R(s.reference, min_rounds=9, max_rounds=8)),
               {"reference.min_rounds": 9, "reference.max_rounds": 8}),
}


@pytest.mark.parametrize("case", list(BAD))
def test_a_changed_run_config_is_refused_as_the_mapping_of_its_value_is(cfg, case):
    change, mapping = BAD[case]
    bad = change(cfg.settings)
    with pytest.raises(InputError) as as_mapping:
        tlm.load_config(SMALL, mapping)
    line = str(as_mapping.value).replace("(dict), with the overrides", "(RunConfig)")
    assert line.startswith("(RunConfig): ") and as_mapping.value.key in line
    for given in (lambda: tlm.load_config(bad), lambda: Config(bad, Path.cwd()),
                  lambda: R(cfg, settings=bad), lambda: tlm.load_config(bad, {"seed": 1})):
        with pytest.raises(InputError) as got:
            given()
        assert str(got.value) == line


def test_the_api_refuses_a_bad_run_config_before_any_work(cfg, tmp_path):
    with pytest.raises(InputError, match=r"^\(RunConfig\): mode: nope is not one of rcast, reflect"):
        tlm.render_image(R(cfg.settings, mode="nope"))
    with pytest.raises(InputError, match=r"^\(RunConfig\): seed: -3 must be >= 0"):
        tlm.run(R(cfg.settings, seed=-3), tmp_path / "out")
    assert not (tmp_path / "out" / "config.resolved.yaml").exists()
    with pytest.raises(InputError, match=r"^settings: 'cornell' is not a RunConfig"):
        Config("cornell", Path.cwd())


def test_a_good_run_config_is_held_as_a_loaded_one_is(cfg):
    given = R(cfg.settings, resolution=np.array([16, 12]), render=R(cfg.render, spp=np.int64(2)))
    got = tlm.load_config(given).settings
    assert got.resolution == (16, 12) and type(got.render.spp) is int and got.render.spp == 2
    assert got == tlm.load_config(SMALL, {"resolution": [16, 12], "render.spp": 2}).settings
    assert tlm.load_config(RunConfig()).settings == tlm.load_config({}).settings
    assert Config(RunConfig(resolution=[4, 4]), Path.cwd()).resolution == (4, 4)


def test_a_config_is_checked_once(cfg, monkeypatch):
    calls = []
    field = config_module._field
    monkeypatch.setattr(config_module, "_field", lambda f, *a: calls.append(f.name) or field(f, *a))
    assert tlm.load_config(cfg.settings).settings is cfg.settings  # (made by the checks: as it is)
    assert tlm.load_config(cfg).settings is cfg.settings
    assert calls == []
    changed = tlm.load_config(R(cfg.settings, seed=3)).settings
    assert changed.seed == 3 and changed.arch is cfg.arch and changed.render is cfg.render  # (its sections kept)
    assert sorted(calls) == ["mode", "resolution", "scene", "seed"]  # (its plain fields alone)
    calls.clear()
    assert tlm.load_config(changed).settings is changed and calls == []  # (checked: not again)


def test_the_loaded_config_is_immutable_and_hashable(cfg):
    res = cfg.resolution
    assert res == (8, 8)
    with pytest.raises(TypeError):
        cfg.resolution[0] = 16
    assert {cfg.settings: 1}[tlm.load_config(SMALL).settings] == 1 and hash(cfg) == hash(tlm.load_config(SMALL))

    @functools.lru_cache
    def width(settings: RunConfig) -> int:
        return settings.resolution[0]

    assert width(cfg.settings) == 8
    assert pickle.loads(pickle.dumps(cfg)) == cfg and copy.deepcopy(cfg.settings) == cfg.settings
    assert "resolution=[8, 8], seed=0)" in repr(cfg)  # (as written, not (8, 8))


def test_what_is_written_keeps_the_list(cfg):
    assert cfg.resolution == (8, 8)
    plain = to_dict(cfg.settings)
    assert plain["resolution"] == [8, 8] and type(plain["resolution"]) is list
    assert "resolution:\n- 8\n- 8\n" in dump_yaml(plain, sort_keys=False)
    assert '"resolution": [8, 8]' in json.dumps(plain)
    from tlm.experiments.frames import functional_key

    assert functional_key(cfg.settings, "s", "c") == functional_key(plain, "s", "c")
    for value, said in (([16, 32, 3], "[16, 32, 3] must have 2 entries"), ([16, -32], "[16, -32] must be positive"),
                        ([1.5, 2], "[1.5, 2] is not a list of 2 integers (e.g. [64, 64]) or null")):
        with pytest.raises(InputError, match=rf"^\(dict\): resolution: {re.escape(said)}$"):
            tlm.load_config({"resolution": value})


def test_a_render_of_the_config_keeps_its_settings(cfg):
    res = tlm.render_image(cfg)
    assert res.cfg is cfg.settings and res.cfg.resolution == (8, 8)
    assert res.composite.shape[:2] == (8, 8)
