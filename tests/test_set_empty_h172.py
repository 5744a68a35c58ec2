"""An empty mapping given for a section sets nothing, and is said so (h172).

Since a mapping given for a section merges into it (h155, :func:`tlm.config_words.laid_over`),
``--set render={}`` (a sweep's ``set: {render: {}}``, a factor's value ``{}``, the API's
``{"render": {}}``) keeps the section as it was, where it used to give the section at its
defaults. A researcher who reset a section so was told nothing: ``tlm run cornell --mode rcast
--set 'render={}'`` printed no line, though the same run warned of ``--set estimate={k: 9}``. Now
one line says it sets nothing and that ``render=null`` gives the section at its defaults, once per
command: ``tlm run`` (and ``results.json``), the API's overrides, ``tlm sweep`` (``--set``, ``set:``
and factor values, before its points, not in each point), and ``tlm thesis`` (once for the study,
not in each cell's ``results.json``).
"""

from __future__ import annotations

import json

import pytest

import tlm
from tests.helpers_yaml import yaml_file as _file
from tlm.cli import main
from tlm.experiments.sweep_file import load_sweep

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 9},
        "arch": {"frames": 1, "images_in_flight": 1, "trace": False}}
WHY = "sets nothing (a mapping given for a section merges into it key by key, and this one names no key)"
RUN = "--set render={} has no effect in this run: it " + WHY + "; --set render=null gives the section at its defaults"
QUIET = ["--no-report", "--no-progress", "--outputs", "images"]


pytestmark = pytest.mark.usefixtures("cache")  # a cache folder of the test's own (tests/conftest.py)


def _said(err: str, text: str) -> int:
    return sum(text in line for line in err.splitlines())


def test_tlm_run_says_an_empty_section_once_beside_the_unread_key(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["run", str(_file(tmp_path, "c.yaml", BASE)), "--out", str(out), *QUIET, "--set", "render={}",
                 "--set", "estimate={k: 9}", "--set", "render={}", "--set", "bsp=null", "--set", "arch={frames: 1}",
                 "--set", "render={spp: 2}"]) == 0
    err = capsys.readouterr().err
    warnings = json.loads((out / "results.json").read_text())["warnings"]
    # (given twice: said once; a section given null or by its keys: not said)
    assert [w for w in warnings if "sets nothing" in w] == [RUN]
    assert _said(err, "sets nothing") == 1 and _said(err, f"tlm: warning: {RUN}") == 1
    assert _said(err, "--set estimate={k: 9} has no effect in this run") == 1  # (the unread key's line, as before)


def test_the_apis_overrides_are_named_as_the_overrides(tmp_path):
    cfg = tlm.load_config(_file(tmp_path, "c.yaml", BASE), {"render": {}, "cache": {}})
    assert cfg.render.light_samples == 9  # (the section kept: what the line says)
    warnings = tlm.run(cfg, tmp_path / "o", progress=False)["warnings"]
    for key in ("render", "cache"):
        assert (f"{key}={{}} (in the overrides) has no effect in this run: it {WHY}; {key}=null gives the section "
                "at its defaults") in warnings, warnings


def test_a_sweep_says_its_empty_set_set_entry_and_factor_value_before_its_points(tmp_path):
    base = {**BASE, "photons": {"count": 2000}}  # (not the default: null is another point than {})
    path = _file(tmp_path, "sw.yaml", {"base": base, "set": {"render": {}, "estimate": None, "bsp": {"levels": 3}},
                                       "grid": {"photons": [{}, {"count": 1000}, None]}})
    sweep = load_sweep(path, ["arch={}", "bsp={memory_factor: 5}", "arch={}", "cache=null"])
    assert [p.config["render"]["light_samples"] for p in sweep.points] == [9] * 3  # (the base's render kept)
    # (a section given null or by its keys, anywhere: not said)
    sets = [line for line in sweep.inert_sets() if "sets nothing" in line]
    assert sets == [f"{path}: set.render: {{}} {WHY}; set.render: null gives the section at its defaults",
                    f"{path}: --set arch={{}} {WHY}; --set arch=null gives the section at its defaults"]
    factors = [line for line in sweep.inert_factors() if "sets nothing" in line]
    assert factors == [f"{path}: grid.photons: the value {{}} {WHY}: its points have the base's photons; a value "
                       "null gives the section at its defaults"]


def test_tlm_sweep_says_it_once_for_all_its_points(tmp_path, capsys):
    path = _file(tmp_path, "sw.yaml", {"base": BASE, "grid": {"seed": [0, 1]}})
    out = tmp_path / "sw"
    assert main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-report", "--no-progress",
                 "--set", "render={}"]) == 0
    err = capsys.readouterr().err
    assert _said(err, f"--set render={{}} {WHY}; --set render=null gives the section at its defaults") == 1
    for results in out.glob("points/*/results.json"):  # (the points hold no override: not said in each)
        assert not [w for w in json.loads(results.read_text())["warnings"] if "sets nothing" in w]


def test_tlm_thesis_says_it_once_for_the_study_not_in_each_cell(tmp_path, capsys):
    study = _file(tmp_path, "th.yaml", {"scenes": ["cornell"], "modes": ["rcast", "reflect"],
                                        "base": {k: v for k, v in BASE.items() if k not in ("scene", "mode")}})
    out = tmp_path / "th"
    assert main(["thesis", str(study), "--out", str(out), "--no-report", "--no-progress", "--set", "render={}"]) == 0
    err = capsys.readouterr().err
    assert _said(err, f"--set render={{}} changes nothing in 2 of 2 cells (mode rcast, reflect of every scene): it "
                      f"{WHY}; --set render=null gives the section at its defaults") == 1
    for mode in ("rcast", "reflect"):
        cell = json.loads((out / "cornell" / mode / "results.json").read_text())
        assert cell["overrides"] == ["render={}"] and not [w for w in cell["warnings"] if "sets nothing" in w]
