"""A plug-in's code is in the keys of what it computes (h532, h525's finding): a radiance estimator or a
scheduler registered from outside tlm (a module of the user's, an installed package's entry point) adds its
code's digest to the functional cache key and to a sweep point's hash, and a run's ``results.json`` records it
(``plugins``); a config of tlm's own classes alone keeps the keys it had before (existing caches stay valid).

Before, the one code fingerprint read ``tlm/`` alone: an edit of the plug-in re-swept "0 rendered", same
point hash, the frame of the old code."""

from __future__ import annotations

import importlib
import json
import sys
import textwrap
from pathlib import Path

import pytest
import yaml

from tlm import fingerprint
from tlm.config import config_from_dict, to_dict
from tlm.experiments.frames import functional_key
from tlm.experiments.sweep_file import config_hash
from tlm.registry import ESTIMATORS, SCHEDULERS, Registry

BASE = {"scene": "cornell", "resolution": [16, 12], "mode": "pmap", "photons": {"count": 2000},
        "render": {"spp": 1}, "estimate": {"final_gather": 0}}
INPUTS = {"functional": "f" * 24, "programs": "p" * 16}  # (a point's input files, fixed: config_hash)

MODULE = '''
import dataclasses

from tlm.arch.schedulers import Static
from tlm.registry import ESTIMATORS, SCHEDULERS
from tlm.render.estimators import Disk

SCALE = {scale}


@ESTIMATORS.register("h532scaled")
class Scaled(Disk):
    def __call__(self, g):
        return super().__call__(dataclasses.replace(g, radius=g.radius * SCALE))


@SCHEDULERS.register("h532static")
class Same(Static):
    pass
'''


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """A module of the user's on sys.path (``h532_plug``, not installed) registering an estimator and a
    scheduler; ``plugin(scale)`` writes it with that radius scale and imports it (again)."""
    folder = tmp_path / "plug"
    folder.mkdir()
    monkeypatch.syspath_prepend(str(folder))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)  # (an edit within the second: not an old .pyc)

    def write(scale: float, extra: str = ""):
        (folder / "h532_plug.py").write_text(MODULE.format(scale=scale) + extra)
        importlib.invalidate_caches()
        mod = sys.modules.get("h532_plug")
        return importlib.reload(mod) if mod is not None else importlib.import_module("h532_plug")

    yield write
    sys.modules.pop("h532_plug", None)
    ESTIMATORS._classes.pop("h532scaled", None)
    SCHEDULERS._classes.pop("h532static", None)


def _keys(raw: dict, folder: Path) -> tuple[str, str]:
    """The frame's functional key (of a fixed scene and code) and the point's hash (of fixed inputs)."""
    cfg = config_from_dict(raw, "x.yaml")
    return functional_key(cfg, "s" * 16, "c" * 16), config_hash(to_dict(cfg), INPUTS, folder)


# computed by tlm before h532 (HEAD 928fe5e), tlm's code fingerprint taken as "0123456789abcdef"
PINNED = {"disk": ("bd80f497f7e6e95e8e729f7c", "9d322503eae6a3db"),
          "dynamic": ("5bec5876582439287ac57062", "71f3d2176192e54e")}


def test_an_edit_of_a_plugin_estimator_changes_its_frame_key_and_its_point_hash(plugin, tmp_path, monkeypatch):
    monkeypatch.setattr(fingerprint, "_CODE", "0123456789abcdef")
    raw = {**BASE, "estimate": {**BASE["estimate"], "filter": "h532scaled"}}
    plugin(1.0)
    one = _keys(raw, tmp_path)
    plugin(3.0)
    three = _keys(raw, tmp_path)
    assert one[0] != three[0] and one[1] != three[1]
    plugin(1.0)
    assert _keys(raw, tmp_path) == one  # (the code's content, not when it was read)
    # tlm's own classes alone: the keys of before, byte for byte (a plug-in registered or not)
    assert _keys({**BASE, "estimate": {**BASE["estimate"], "filter": "disk"}}, tmp_path) == PINNED["disk"]
    assert _keys({**BASE, "arch": {"scheduler": "dynamic"}}, tmp_path) == PINNED["dynamic"]


def test_a_plugin_scheduler_is_in_the_point_hash_and_not_in_the_frame_key(plugin, tmp_path):
    raw = {**BASE, "arch": {"scheduler": "h532static"}}
    plugin(1.0)
    before = _keys(raw, tmp_path)
    plugin(1.0, "\n# an edit of the scheduler's module\n")
    after = _keys(raw, tmp_path)
    assert before[1] != after[1]
    assert before[0] == after[0]  # (the frame does not run the timing model: arch is not in its key)


def test_an_edit_of_another_module_of_the_plugin_package_changes_the_key(tmp_path, monkeypatch):
    """A package's class: what it may import from its package is keyed too (the whole top-level package)."""
    pkg = tmp_path / "h532pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "helper.py").write_text("SCALE = 1.0\n")
    (pkg / "est.py").write_text(textwrap.dedent('''
        from tlm.registry import ESTIMATORS
        from tlm.render.estimators import Disk
        from h532pkg import helper


        @ESTIMATORS.register("h532pkg")
        class Pkg(Disk):
            scale = helper.SCALE
    '''))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    raw = {**BASE, "estimate": {**BASE["estimate"], "filter": "h532pkg"}}
    try:
        importlib.import_module("h532pkg.est")
        before = _keys(raw, tmp_path)
        (pkg / "helper.py").write_text("SCALE = 3.0\n")
        for name in ("h532pkg.helper", "h532pkg.est"):
            importlib.reload(sys.modules[name])
        assert _keys(raw, tmp_path) != before
    finally:
        for name in ("h532pkg.est", "h532pkg.helper", "h532pkg"):
            sys.modules.pop(name, None)
        ESTIMATORS._classes.pop("h532pkg", None)


def test_an_entry_point_plugin_is_recorded_with_its_distribution(tmp_path, monkeypatch):
    """As h525 installed its own: a module and a ``.dist-info`` with an entry point of the registry's group."""
    (tmp_path / "h532ep.py").write_text("class Bright:\n    RADIUS = 1.0\n")
    info = tmp_path / "h532ep-0.3.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: h532ep\nVersion: 0.3\n")
    (info / "entry_points.txt").write_text("[tlm.h532-test]\nbright = h532ep:Bright\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    try:
        reg = Registry("thing", (), "tlm.h532-test")
        got = reg.plugin("bright")
        assert {k: got[k] for k in ("name", "module", "class", "distribution", "version")} == {
            "name": "bright", "module": "h532ep", "class": "Bright", "distribution": "h532ep", "version": "0.3"}
        (tmp_path / "h532ep.py").write_text("class Bright:\n    RADIUS = 3.0\n")
        importlib.reload(sys.modules["h532ep"])
        again = Registry("thing", (), "tlm.h532-test")
        assert again.plugin("bright")["digest"] != got["digest"]
    finally:
        sys.modules.pop("h532ep", None)


@pytest.mark.slow
def test_a_sweep_renders_again_after_the_plugin_edit_and_a_run_says_which(plugin, tmp_path, monkeypatch):
    """h525's probe, in-process: the edit's sweep renders its frame again (before: '0 rendered', the frame
    of the old code, the points' hashes the same); a run's results.json records the plug-in, a built-in run's
    none."""
    from tlm import api

    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    base = {**BASE, "estimate": {**BASE["estimate"], "filter": "h532scaled"}, "reference": {"auto": False},
            "arch": {"trace": False}}
    sweep = tmp_path / "sw.yaml"
    sweep.write_text(yaml.safe_dump({"base": base, "grid": {"arch.pipelines": [1, 2]}}))
    done = {}
    for scale in (1.0, 3.0):
        plugin(scale)
        done[scale] = api.run_sweep(sweep, tmp_path / f"sw-{scale}", jobs=1)
    assert done[1.0].renders == 1 and done[3.0].renders == 1
    assert [r["cycles.fragment"] for r in done[1.0].rows] != [r["cycles.fragment"] for r in done[3.0].rows]
    assert {r["hash"] for r in done[1.0].rows}.isdisjoint(r["hash"] for r in done[3.0].rows)
    assert api.run_sweep(sweep, tmp_path / "sw-again", jobs=1).renders == 0  # (the same code: read from the cache)
    from tlm.registry import plugins  # (since h532)

    api.run(base, tmp_path / "mine", outputs=())
    got = json.loads((tmp_path / "mine" / "results.json").read_text())["plugins"]
    assert got == plugins(to_dict(config_from_dict(base))) and [
        (r["setting"], r["name"], r["module"], r["class"]) for r in got] == [
        ("estimate.filter", "h532scaled", "h532_plug", "Scaled")]
    api.run({**base, "estimate": BASE["estimate"]}, tmp_path / "own", outputs=())
    assert json.loads((tmp_path / "own" / "results.json").read_text())["plugins"] == []
