"""The checks that still read a section given as a mapping as "the whole section" (h163).

A mapping given for a section merges into it (``render={spp: 1}`` is ``render.spp=1``: h155,
:func:`tlm.config_words.laid_over`), so it sets the keys it names alone
(:func:`tlm.experiments.study.set_leaves`); these checks now judge it so:

1. ``results.json``'s line on an override no pass reads (:func:`tlm.experiments.run_warnings.unread_overrides`):
   ``estimate={}`` sets nothing, ``estimate={k: 9}`` reads as ``estimate.k=9``, and ``estimate=null``, the
   whole photon-map section at its defaults, is said in a run without the photon-map pass, as the override
   that set each key of it last.
2. A sweep file's ``set:`` and factors overlap by the keys they set: ``set: {render: {spp: 1}}`` beside a
   factor ``render.light_samples`` is taken (was: ``overlaps set.render``), one that sets the factor's key
   is refused in those words.
3. ``tlm error-vs-cost --set`` is refused for the keys a point's section mapping sets, not for its whole
   section (``--set estimate.filter=disk`` beside points ``estimate: [{k: 9}, {k: 16}]``), and a point's
   ``render: {spp: 4}`` is not said to replace the base's whole section.
4. ``tlm extreme --set`` beside a case's empty section (``arch: {}``, which changes nothing) is taken.
"""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest
import yaml

from tests.helpers_yaml import yaml_file as _file
from tlm.cli import main
from tlm.config import apply_overrides, deep_merge
from tlm.errors import InputError
from tlm.experiments.error_cost import load_experiment
from tlm.experiments.extreme import load_cases
from tlm.experiments.run_warnings import unread_overrides
from tlm.experiments.sweep_file import load_sweep

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 2, "light_samples": 9},
        "arch": {"frames": 1, "images_in_flight": 1, "trace": False}}


pytestmark = pytest.mark.usefixtures("cache")  # a cache folder of the test's own (tests/conftest.py)


# ------------------------------------------------------------------ 1. the unread-override lines


def _left_out(by=None):
    """What unread_overrides reads of a run whose photon-map pass is left out (``by``: the key that did it)."""
    left = SimpleNamespace(name="pmap", run=False, reason="why", by=by)
    return SimpleNamespace(plan=SimpleNamespace(run_names=["rcast"], passes=[left]))


def test_an_unread_override_of_a_section_is_judged_by_the_keys_it_sets():
    res = _left_out()
    said = "has no effect in this run: the photon-map pass is left out (why)"
    # a mapping: the keys it names, its line as the dotted key's
    assert unread_overrides(res, ["estimate={k: 9}"]) == [f"--set estimate={{k: 9}} {said}"]
    assert unread_overrides(res, ["estimate.k=9"]) == [f"--set estimate.k=9 {said}"]
    # (sets nothing: it merges; said so, h172)
    empty = ("--set estimate={} has no effect in this run: it sets nothing (a mapping given for a section merges into "
             "it key by key, and this one names no key); --set estimate=null gives the section at its defaults")
    assert unread_overrides(res, ["estimate={}"]) == [empty]
    # null: the whole section at its defaults, said as such (was: not said at all), and as the last to set its keys
    assert unread_overrides(res, ["estimate=null"]) == [f"--set estimate=null {said}"]
    assert unread_overrides(res, ["estimate.k=9", "estimate=null"]) == [f"--set estimate=null {said}"]
    assert unread_overrides(res, ["estimate=null", "estimate.k=9"]) == [f"--set estimate=null {said}",
                                                                         f"--set estimate.k=9 {said}"]
    assert unread_overrides(res, ["estimate={k: 9}", "estimate={}"]) == [f"--set estimate={{k: 9}} {said}", empty]
    # not the key that left the pass out, nor its section given whole
    by = _left_out(by="photons.count")
    assert unread_overrides(by, ["photons={count: 0}"]) == []
    assert unread_overrides(by, ["photons=null"]) == []
    assert unread_overrides(by, ["photons={count: 0, max_bounces: 4}"]) == [
        f"--set photons={{count: 0, max_bounces: 4}}: photons.max_bounces {said}"]


def test_tlm_run_says_a_section_set_as_its_dotted_keys(tmp_path):
    path = _file(tmp_path, "base.yaml", {**BASE, "estimate": {"k": 9}})
    lines = {}
    for name, sets in (("mapping", ["render={spp: 1, reflect_depth: 3}", "estimate=null"]),
                       ("dotted", ["render.spp=1", "render.reflect_depth=3", "estimate=null"])):
        out = tmp_path / name
        args = [a for item in sets for a in ("--set", item)]
        assert main(["run", str(path), *args, "--out", str(out), "--no-progress", "--no-report",
                     "--no-reference"]) == 0
        lines[name] = [w for w in json.loads((out / "results.json").read_text())["warnings"] if w.startswith("--set")]
    walk = "has no effect in this run: mode 'rcast' traces no mirror or glass paths"
    assert [w.split(" has no effect")[0] for w in lines["mapping"]] == [
        "--set render={spp: 1, reflect_depth: 3}: render.reflect_depth", "--set estimate=null"], lines
    assert [w.split(" has no effect")[0] for w in lines["dotted"]] == [
        "--set render.reflect_depth=3", "--set estimate=null"], lines
    assert walk in lines["mapping"][0] and walk in lines["dotted"][0]
    assert lines["mapping"][1] == lines["dotted"][1]


# ------------------------------------------------------------------ 2. a sweep file's set: and factors


def test_a_sweeps_set_of_a_section_overlaps_a_factor_only_by_the_keys_it_sets(tmp_path):
    path = _file(tmp_path, "sw.yaml", {"base": BASE, "set": {"render": {"spp": 1}},
                                       "grid": {"render.light_samples": [1, 4]}})
    sw = load_sweep(path)  # (was: grid.render.light_samples: overlaps set.render)
    assert [(p.config["render"]["spp"], p.config["render"]["light_samples"]) for p in sw.points] == [(1, 1), (1, 4)]
    dotted = load_sweep(_file(tmp_path, "dotted.yaml", {"base": BASE, "set": {"render.spp": 1},
                                                         "grid": {"render.light_samples": [1, 4]}}))
    assert [p.hash for p in sw.points] == [p.hash for p in dotted.points]
    assert len(load_sweep(_file(tmp_path, "empty.yaml", {"base": BASE, "set": {"render": {}},
                                                          "grid": {"render.light_samples": [1, 4]}})).points) == 2
    # a factor of mappings beside a factor of a key it leaves: taken, the points those of the dotted keys
    both = load_sweep(_file(tmp_path, "both.yaml", {"base": BASE, "grid": {
        "render": [{"spp": 1}, {"spp": 4}], "render.light_samples": [1, 4]}}))
    flat = load_sweep(_file(tmp_path, "flat.yaml", {"base": BASE, "grid": {
        "render.spp": [1, 4], "render.light_samples": [1, 4]}}))
    assert [p.hash for p in both.points] == [p.hash for p in flat.points]
    # a --set of a key such a factor leaves is kept in every point (was: render.light_samples is in render, ...)
    path = _file(tmp_path, "zip.yaml", {"base": BASE, "grid": {"seed": [0, 1]}, "zip": {"render": [{"spp": 1},
                                                                                                   {"spp": 4}]}})
    for item in ("render.light_samples=4", "render={light_samples: 4}"):
        assert [(p.config["render"]["spp"], p.config["render"]["light_samples"])
                for p in load_sweep(path, [item]).points] == [(1, 4), (4, 4), (1, 4), (4, 4)]
    for item, said in (("render.spp=3", "render.spp is in render,"), ("render=null", "render is")):
        with pytest.raises(InputError) as e:
            load_sweep(path, [item])
        assert str(e.value) == (f"{path}: --set {item}: {said} a factor of the sweep (zip.render), which gives each "
                                "point its value: change its values in the sweep file, not by --set")
    # a real overlap is refused, in its words
    for content, said in (({"set": {"render": {"light_samples": 1}}, "grid": {"render.light_samples": [1, 4]}},
                           "grid.render.light_samples: overlaps set.render"),
                          ({"set": {"render": None}, "grid": {"render.light_samples": [1, 4]}},
                           "grid.render.light_samples: overlaps set.render"),
                          ({"set": {"render.light_samples": 1}, "grid": {"render": [{"spp": 1}, {"light_samples": 4}]}},
                           "grid.render: overlaps set.render.light_samples"),
                          ({"grid": {"render": [{"spp": 1}, {"spp": 4, "light_samples": 4}]},
                            "zip": {"render.light_samples": [1, 4]}},
                           "zip.render.light_samples: overlaps grid.render")):
        path = _file(tmp_path, "bad.yaml", {"base": BASE, **content})
        with pytest.raises(InputError) as e:
            load_sweep(path)
        assert str(e.value) == f"{path}: {said}"


def test_a_sweeps_set_of_a_section_no_point_reads_is_said_by_the_keys_it_sets(tmp_path):
    path = _file(tmp_path, "sw.yaml", {"base": BASE, "grid": {"bsp.levels": [4, 5]}})
    no_pmap = "the photon-map pass does not run (mode 'rcast' does not include the pmap (photon-map) pass)"
    said = (f"changes nothing in any point (though in every point's config and hash: a rerun into a folder swept "
            f"without it runs its points again): {no_pmap}")
    assert load_sweep(path, ["estimate=null"]).inert_sets() == [f"{path}: --set estimate=null {said}"]  # (was: none)
    assert load_sweep(path, ["estimate.k=5", "estimate=null"]).inert_sets() == [f"{path}: --set estimate=null {said}"]
    assert load_sweep(path, ["estimate={}"]).inert_sets() == [  # (sets nothing: said so, h172)
        f"{path}: --set estimate={{}} sets nothing (a mapping given for a section merges into it key by key, and this "
        "one names no key); --set estimate=null gives the section at its defaults"]
    assert load_sweep(path, ["estimate={k: 5}"]).inert_sets() == [f"{path}: --set estimate={{k: 5}} {said}"]
    assert load_sweep(path, ["render=null"]).inert_sets() == []  # (render.spp is read)


# ------------------------------------------------------------------ 3. error-vs-cost


def test_error_vs_cost_refuses_a_set_by_the_keys_a_points_section_sets(tmp_path):
    base = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "render": {"spp": 2},
            "photons": {"count": 500}}
    path = _file(tmp_path, "ec.yaml", {"base": base, "points": [{"estimate": [{"k": 9}, {"k": 16}]}]})
    for item in ("estimate.filter=disk", "estimate={filter: disk}"):  # (was: estimate.filter is in estimate, ...)
        got, points, _ = load_experiment(path, (item,))
        assert got["estimate"] == {"filter": "disk"}
        assert [apply_overrides(got, [f"estimate={json.dumps(p['estimate'])}"])["estimate"] for p in points] == [
            {"filter": "disk", "k": 9}, {"filter": "disk", "k": 16}]
    for item, said in (("estimate.k=4", "estimate.k is"), ("estimate={k: 4}", "estimate holds estimate.k,"),
                       ("estimate=null", "estimate holds estimate.k,")):
        with pytest.raises(InputError) as e:
            load_experiment(path, (item,))
        assert str(e.value) == (f"{path}: --set {item}: {said} varied by the study's points (points[0].estimate): "
                                "change its values in the experiment file, not by --set")
    # a point's section mapping that sets a shared key is refused as setting it, not as replacing the section
    path = _file(tmp_path, "spp.yaml", {"base": base, "points": [{"render": [{"spp": 4}]}]})
    with pytest.raises(InputError) as e:
        load_experiment(path)
    assert str(e.value) == (f"{path}: points: {{'render': {{'spp': 4}}}}: a point cannot vary render.spp: every point "
                            "shares the base's eye rays (the point's render sets it); set it under base, and run one "
                            "experiment per value")
    path = _file(tmp_path, "null.yaml", {"base": base, "points": [{"render": [None]}]})
    with pytest.raises(InputError, match=r"\(the point's render: replaces the base's whole section: give "
                                         r"render\.<key> for what it changes\)"):
        load_experiment(path)
    load_experiment(_file(tmp_path, "ls.yaml", {"base": base, "points": [{"render": [{"light_samples": 4}]}]}))


# ------------------------------------------------------------------ 4. extreme (granularity: refuse_set already)


def test_extreme_takes_a_set_beside_a_cases_empty_section(tmp_path):
    cases = _file(tmp_path, "ex.yaml", {"base": {k: v for k, v in BASE.items() if k != "scene"}, "cases": [
        {"name": "a", "category": "c", "expect": "runs", "config": {"scene": "cornell", "arch": {}},
         "checks": ["finite"]},
        {"name": "b", "category": "c", "expect": "runs", "config": {"scene": "cornell", "arch": {"fifo_depth": 2}},
         "checks": ["finite"]}]})
    with pytest.raises(InputError) as e:  # (the case 'a' sets nothing of arch: case 'b' is what refuses it)
        load_cases(cases, ("arch.fifo_depth=4",))
    assert "set by the case 'b' (cases[1].config.arch.fifo_depth)" in str(e.value), str(e.value)
    raw = yaml.safe_load(cases.read_text())
    raw["cases"] = raw["cases"][:1]
    base, got, _ = load_cases(_file(tmp_path, "a.yaml", raw), ("arch.fifo_depth=4", "arch={pipelines: 3}"))
    merged = deep_merge(base, got[0]["config"])
    assert (merged["arch"]["fifo_depth"], merged["arch"]["pipelines"], merged["arch"]["frames"]) == (4, 3, 1)
    raw["cases"][0]["config"]["mode"] = {}  # (not a section: an empty mapping replaces the mode, so it is given)
    raw["cases"][0]["expect"] = "error"
    raw["cases"][0]["checks"] = [{"error": "not a string"}]
    with pytest.raises(InputError, match=r"--set mode=pmap: mode is set by the case 'a'"):
        load_cases(_file(tmp_path, "m.yaml", raw), ("mode=pmap",))
