"""A section given as a mapping merges into the config's section, key by key (h155).

``tlm run base.yaml --set 'render={spp: 1}'`` replaced the file's whole ``render`` section: its
``light_samples: 9`` fell back to the default 4, unsaid. A mapping given for a section now merges
into it, as its dotted leaves would (``render={spp: 1}`` is ``render.spp=1``, as OmegaConf and Hydra
merge): ``tlm run --set``, the API's overrides and ``Config.updated``, a study's ``base`` + ``--set``,
a sweep's ``set:`` over its base and a sweep factor whose values are mappings. ``render=null`` still
gives the section at its defaults, and no setting of the config holds a mapping (every mapping-typed
field is a section), so none is merged by mistake.

The studies' refusal of a ``--set`` of a key they set themselves (:func:`tlm.experiments.study.refuse_set`)
looks at the keys a mapping sets: ``arch={fifo_depth: 5}`` sets ``arch.fifo_depth`` alone, and is no
longer refused beside a study's ``arch.packet_size``; ``arch={packet_size: 4}`` and ``arch=null`` still are.
"""

from __future__ import annotations

import dataclasses
import json
import typing

import pytest
import yaml

import tlm
from tests.helpers_yaml import yaml_file as _file
from tlm.cli import main
from tlm.config import SECTIONS, RunConfig, apply_overrides, describe, load_config, to_dict
from tlm.errors import InputError
from tlm.experiments.extreme import load_cases
from tlm.experiments.granularity import load_granularity
from tlm.experiments.study import refuse_set, set_leaves
from tlm.experiments.sweep_file import load_sweep

RENDER = {"spp": 2, "light_samples": 9}  # (light_samples 9: not the default 4)
BASE = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": RENDER,
        "arch": {"frames": 1, "images_in_flight": 1, "trace": False, "pipelines": 2}}


pytestmark = pytest.mark.usefixtures("cache")  # a cache folder of the test's own (tests/conftest.py)


# ------------------------------------------------------------------ tlm run --set, the API


def test_a_section_given_by_set_keeps_the_files_other_keys(tmp_path):
    path = _file(tmp_path, "base.yaml", BASE)
    cfg, _ = load_config(path, ["render={spp: 1}"])
    assert (cfg.render.spp, cfg.render.light_samples) == (1, 9)
    dotted, _ = load_config(path, ["render.spp=1"])
    assert to_dict(cfg) == to_dict(dotted)  # (the same config, so the same run and the same hash)
    # nested in a mapping of the whole config too, and a later --set of one key on top of it
    cfg, _ = load_config(path, ["arch={fifo_depth: 16}", "render={spp: 1}", "render.light_samples=1"])
    assert (cfg.arch.fifo_depth, cfg.arch.pipelines, cfg.render.spp, cfg.render.light_samples) == (16, 2, 1, 1)
    # null still gives the section at its defaults; an empty mapping changes nothing
    assert load_config(path, ["render=null"])[0].render == RunConfig().render
    assert load_config(path, ["render={}"])[0].render == load_config(path)[0].render
    # a bad key inside the mapping is still named
    with pytest.raises(InputError, match=r"render\.spq: unknown key"):
        load_config(path, ["render={spq: 1}"])


def test_the_apis_overrides_and_updated_merge_a_section_too(tmp_path):
    path = _file(tmp_path, "base.yaml", BASE)
    for cfg in (tlm.load_config(str(path), {"render": {"spp": 1}}),
                tlm.load_config(str(path), ["render={spp: 1}"]),
                tlm.load_config(str(path)).updated({"render": {"spp": 1}}),
                tlm.load_config(BASE, {"render": {"spp": 1}})):
        assert (cfg.render.spp, cfg.render.light_samples, cfg.arch.pipelines) == (1, 9, 2), cfg


def test_tlm_run_with_a_section_set_writes_the_files_other_keys(tmp_path):
    path = _file(tmp_path, "base.yaml", BASE)
    out = tmp_path / "out"
    assert main(["run", str(path), "--set", "render={spp: 1}", "--out", str(out), "--no-progress", "--no-report",
                 "--no-reference"]) == 0
    resolved = yaml.safe_load((out / "config.resolved.yaml").read_text())
    assert resolved["render"]["spp"] == 1 and resolved["render"]["light_samples"] == 9
    assert json.loads((out / "results.json").read_text())["overrides"] == ["render={spp: 1}"]  # (as typed)


def test_no_setting_holds_a_mapping_so_only_sections_merge():
    """Every field of a mapping type is a section (a dataclass): no setting's value is a mapping,
    which a mapping would have to replace. A mapping given for anything but a section replaces it."""
    for key, _, _ in describe():
        section, name = key.split(".") if "." in key else ("", key)
        owner = RunConfig if not section else typing.get_type_hints(RunConfig)[section]
        tp = typing.get_type_hints(owner)[name]
        assert "dict" not in str(tp) and "Mapping" not in str(tp), key
    sections = {name for name, tp in typing.get_type_hints(RunConfig).items() if dataclasses.is_dataclass(tp)}
    assert set(SECTIONS) == sections
    assert apply_overrides({"render": {"spp": 2}}, ["render.spp={a: 1}"]) == {"render": {"spp": {"a": 1}}}
    assert set_leaves("render={spp: 1, light_samples: 9}") == {"render.spp": 1, "render.light_samples": 9}
    assert set_leaves("render={}") == {} and set_leaves("render=null") == {"render": None}
    assert set_leaves("mode={a: 1}") == {"mode": {"a": 1}}  # (no section: the key's value)


# ------------------------------------------------------------------ a sweep's set:, factors and --set


def test_a_sweeps_set_and_a_factor_of_sections_merge_into_the_base(tmp_path):
    path = _file(tmp_path, "sw.yaml", {"base": BASE, "set": {"render": {"spp": 1}}, "grid": {"seed": [0, 1]}})
    assert [(p.config["render"]["spp"], p.config["render"]["light_samples"]) for p in load_sweep(path).points] \
        == [(1, 9), (1, 9)]
    path = _file(tmp_path, "sw.yaml", {"base": BASE, "grid": {"render": [{"spp": 1}, {"spp": 4}]}})
    sw = load_sweep(path)
    assert [(p.config["render"]["spp"], p.config["render"]["light_samples"]) for p in sw.points] == [(1, 9), (4, 9)]
    dotted = load_sweep(_file(tmp_path, "dotted.yaml", {"base": BASE, "grid": {"render.spp": [1, 4]}}))
    assert [p.hash for p in sw.points] == [p.hash for p in dotted.points]  # (the same points: one run each)


def test_a_sweeps_set_of_a_section_keeps_the_bases_keys_and_hashes_as_the_dotted_keys(tmp_path):
    path = _file(tmp_path, "sw.yaml", {"base": BASE, "grid": {"bsp.levels": [4, 5]}})
    sw = load_sweep(path, ["bsp={memory_factor: 5}", "arch={page_miss_cycles: 5}"])
    assert [(p.config["bsp"]["levels"], p.config["bsp"]["memory_factor"]) for p in sw.points] == [(4, 5), (5, 5)]
    assert all(p.config["arch"]["pipelines"] == 2 and p.config["arch"]["page_miss_cycles"] == 5 for p in sw.points)
    dotted = load_sweep(path, ["bsp.memory_factor=5", "arch.page_miss_cycles=5"])
    assert [p.hash for p in sw.points] == [p.hash for p in dotted.points]
    assert [p.hash for p in load_sweep(path, ["bsp={memory_factor: 5}", "arch={page_miss_cycles: 5}"]).points] \
        == [p.hash for p in sw.points]  # (a rerun with the same --set: the same points)
    with pytest.raises(InputError, match=r"bsp holds bsp.levels, a factor of the sweep \(grid.bsp.levels\)"):
        load_sweep(path, ["bsp={levels: 3}"])


# ------------------------------------------------------------------ the studies' refusal: by the keys set


def test_refuse_set_looks_at_the_keys_a_mapping_sets():
    taken = {"bsp.levels": "a factor of the sweep (grid.bsp.levels)"}
    refuse_set(["bsp={memory_factor: 5}", "bsp={}", "seed=1"], taken, "s.yaml")  # (none sets bsp.levels)
    for item, said in (("bsp={levels: 3}", "bsp holds bsp.levels,"), ("bsp=null", "bsp holds bsp.levels,"),
                       ("bsp.levels=3", "bsp.levels is"), ("bsp={memory_factor: 5, levels: 3}", "bsp holds")):
        with pytest.raises(InputError) as e:
            refuse_set([item], taken, "s.yaml")
        assert str(e.value).startswith(f"s.yaml: --set {item}: {said}"), str(e.value)


def test_a_studys_set_of_a_section_beside_its_own_key_is_taken_where_it_leaves_that_key(tmp_path):
    gran = _file(tmp_path, "gr.yaml", {"base": BASE, "packet_sizes": [1, 16]})
    cfg, _, _ = load_granularity(gran, ("arch={fifo_depth: 5}",))
    assert (cfg.arch.fifo_depth, cfg.arch.pipelines) == (5, 2)  # (the base's arch.pipelines kept)
    for item in ("arch={packet_size: 4}", "arch=null"):
        with pytest.raises(InputError, match=r"arch holds arch.packet_size, set by the study's packet_sizes"):
            load_granularity(gran, (item,))
    cases = _file(tmp_path, "ex.yaml", {"base": {k: v for k, v in BASE.items() if k != "scene"}, "cases": [
        {"name": "a", "category": "c", "expect": "runs", "config": {"scene": "cornell", "arch": {"fifo_depth": 2}},
         "checks": ["finite"]}]})
    base, _, _ = load_cases(cases, ("arch={pipelines: 3}",))
    assert base["arch"]["pipelines"] == 3 and base["arch"]["frames"] == 1
    with pytest.raises(InputError, match=r"arch holds arch.fifo_depth, set by the case 'a'"):
        load_cases(cases, ("arch={fifo_depth: 3}",))
