"""The studies say an empty section mapping once, and ``tlm extreme`` says its ``--set`` warnings (h174).

h172 warned of ``--set render={}`` (a mapping for a section merges into it, so an empty one sets
nothing) in ``tlm run``, the API, ``tlm sweep`` and ``tlm thesis``; ``tlm extreme``, ``tlm
granularity``, ``tlm error-vs-cost`` (its ``--set`` and a points value ``{}``) and ``tlm reference``
said nothing. Now each says it once per command, in ``tlm run``'s words. ``tlm extreme`` printed
no warning at all (each case's ``results.json`` held them): now a ``--set`` that sets nothing is
said before its cases, and one some cases never read after them, once, with which cases and why.
"""

from __future__ import annotations

import pytest

from tests.helpers_yaml import yaml_file as _file
from tlm.cli import main

WHY = "sets nothing (a mapping given for a section merges into it key by key, and this one names no key)"


def _run(key: str, via: str = "--set") -> str:
    null = f"{via} {key}=null" if via == "--set" else f"{key}=null"
    given = f"--set {key}={{}}" if via == "--set" else f"{key}={{}} (in {via})"
    return f"{given} has no effect in this run: it {WHY}; {null} gives the section at its defaults"


BASE = {"resolution": [8, 8], "render": {"spp": 1, "light_samples": 9},
        "arch": {"frames": 1, "images_in_flight": 1, "trace": False}}
REFERENCE = {"photons": 800, "k_nearest": 20, "tolerance": 0.5, "min_rounds": 2, "max_rounds": 2, "spp": 1}
QUIET = ["--no-report"]

pytestmark = pytest.mark.usefixtures("cache")  # a cache folder of the test's own (tests/conftest.py)


def _said(err: str, text: str) -> int:
    return sum(text in line for line in err.splitlines())


def test_tlm_extreme_says_its_set_warnings_once_for_the_study(tmp_path, capsys):
    case = {"category": "c", "expect": "e", "checks": ["finite"]}
    cases = _file(tmp_path, "ext.yaml", {"base": BASE, "cases": [
        {"name": "a", **case, "config": {"scene": "cornell", "mode": "rcast"}},
        {"name": "b", **case, "config": {"scene": "cornell", "mode": "reflect"}}]})
    assert main(["extreme", str(cases), "--out", str(tmp_path / "o"), *QUIET, "--set", "render={}",
                 "--set", "estimate={k: 9}", "--set", "render={}", "--set", "arch={frames: 1}"]) == 0
    err = capsys.readouterr().err
    assert _said(err, "sets nothing") == 1 and _said(err, f"tlm: warning: {_run('render')}") == 1
    # (the key no case reads: one line for both, not one per case; arch.frames is read: not said)
    assert _said(err, "estimate={k: 9}") == 1
    assert ("tlm: warning: --set estimate={k: 9} has no effect in 2 of 2 cases: the photon-map pass is left out "
            "(its mode does not include the pmap (photon-map) pass) (cases a, b)") in err.splitlines()
    assert "arch" not in err and "packet" not in err  # (a case's own warnings: its results.json's, not said)


def test_tlm_granularity_says_an_empty_set_once(tmp_path, capsys):
    study = _file(tmp_path, "g.yaml", {"base": {**BASE, "scene": "cornell", "mode": "rcast"}, "packet_sizes": [1, 4]})
    assert main(["granularity", str(study), "--out", str(tmp_path / "o"), *QUIET, "--set", "arch={}",
                 "--set", "render={spp: 1}", "--set", "arch={}"]) == 0
    err = capsys.readouterr().err
    assert _said(err, "sets nothing") == 1 and _said(err, f"tlm: warning: {_run('arch')}") == 1


def test_tlm_error_vs_cost_says_an_empty_set_and_points_value_once(tmp_path, capsys):
    import tlm

    exp = _file(tmp_path, "evc.yaml", {
        "base": {"scene": "cornell", "resolution": [8, 8], "reference": REFERENCE, "photons": {"count": 800},
                 "estimate": {"final_gather": 0}},
        "points": [{"estimate.filter": ["disk"], "render": [{}, {"light_samples": 9}]},
                   {"estimate.filter": "mvoxel", "render": [{}]}]})
    assert main(["error-vs-cost", str(exp), "--out", str(tmp_path / "o"), "--truth-spp", "0", *QUIET,
                 "--set", "estimate={}", "--set", "estimate={}", "--set", "photons={count: 800}"]) == 0
    err = capsys.readouterr().err
    assert _said(err, "sets nothing") == 3 and _said(err, f"tlm: warning: {_run('estimate')}") == 1
    for i in (0, 1):  # (a grid's value, as tlm sweep says a factor's; the one that sets a key: not said)
        assert _said(err, f"tlm: warning: {exp}: points[{i}].render: the value {{}} {WHY}: its points have the "
                          "base's render; a value null gives the section at its defaults") == 1
    rows = tlm.error_vs_cost(exp, tmp_path / "api", truth_spp=0, overrides=["cache={}"])
    assert len([w for w in rows.attrs["warnings"] if "sets nothing" in w]) == 3  # (the API's record too)


def test_make_reference_says_an_empty_override_once(tmp_path, capsys):
    from tlm.config import config_from_dict
    from tlm.experiments.reference import make_reference

    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "reference": REFERENCE})
    make_reference(cfg, overrides=("render={}", "render={}", "reference={photons: 800}"))
    make_reference(cfg, overrides=("cache={}",), via="the overrides")  # (cached now: said all the same)
    err = capsys.readouterr().err
    assert _said(err, "sets nothing") == 2 and _said(err, f"tlm: warning: {_run('render')}") == 1
    assert _said(err, f"tlm: warning: {_run('cache', 'the overrides')}") == 1
