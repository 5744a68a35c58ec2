"""The specular walk's settings a mode never reads (``render.reflect_depth``, ``render.refract_depth``,
``render.fresnel``, ``render.min_weight``: the reflect, refract and photon-map passes read them,
:func:`tlm.render.walk.specular_walk`; the ray-cast pass none) were never called unread: ``--set
render.reflect_depth=2 --mode rcast`` said nothing, a sweep of it under rcast did not say its points
were one run, and each point rendered its frame again (the key held the depth).
:func:`tlm.render.planner.walk_inert_settings` names them, in :func:`~tlm.render.planner.inert_settings`,
the one list the warnings, the sweep and the frame key use."""

from __future__ import annotations

import json

import pytest
import yaml

from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments.frames import functional_key
from tlm.experiments.run import render
from tlm.experiments.sweep import run_sweep
from tlm.render.planner import inert_settings

WALK = {"reflect_depth": 2, "refract_depth": 1, "fresnel": False, "min_weight": 0.01}
BASE = {"scene": "cornell", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False}}
SMALL = ["--set", "resolution=[16,16]", "--set", "arch.packet_size=16", "--set", "arch.frames=2",
         "--no-report", "--no-progress", "--outputs", "images", "--no-reference"]


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def test_the_walk_keys_are_inert_in_the_modes_without_their_passes():
    def walk_keys(mode):
        return sorted(k for k in inert_settings(config_from_dict({"mode": mode})) if k.startswith("render."))

    assert walk_keys("rcast") == [f"render.{k}" for k in sorted(WALK)]
    assert walk_keys("reflect") == ["render.refract_depth"]  # (the mirror walk splits at glass: fresnel read)
    assert walk_keys("refract") == walk_keys("pmap") == []


def key(mode: str, **render_keys) -> str:
    return functional_key(config_from_dict({"mode": mode, "render": render_keys}), "scene", "code")


def test_the_frame_key_leaves_out_what_the_mode_never_reads_and_keeps_what_it_reads():
    # (what lets the key leave them out: the ray-cast frame reads none of them)
    one = render(config_from_dict({**BASE, "mode": "rcast"}))
    other = render(config_from_dict({**BASE, "mode": "rcast", "render": {**BASE["render"], **WALK}}))
    assert one.radiance["rcast"].tobytes() == other.radiance["rcast"].tobytes()
    assert all(one.work["rcast"][k].tobytes() == other.work["rcast"][k].tobytes() for k in one.work["rcast"])
    for name, value in WALK.items():
        assert key("rcast", **{name: value}) == key("rcast"), name
        assert key("refract", **{name: value}) != key("refract"), name
        assert key("pmap", **{name: value}) != key("pmap"), name
    assert key("reflect", refract_depth=1) == key("reflect")
    assert key("reflect", reflect_depth=2) != key("reflect")
    assert key("reflect", fresnel=False) != key("reflect")
    assert key("rcast", spp=2) != key("rcast")
    assert key("rcast", light_samples=9) != key("rcast")


def test_a_walk_key_set_for_a_mode_that_never_reads_it_is_warned_of_as_given(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["run", "configs/cornell.yaml", "--out", str(out), *SMALL, "--mode", "rcast",
                 "--set", "render.reflect_depth=2", "--set", "render.refract_depth=1",
                 "--set", "render={fresnel: false, spp: 1}", "--set", "render.light_samples=1"]) == 0
    warnings = json.loads((out / "results.json").read_text())["warnings"]
    err = capsys.readouterr().err
    why = ("has no effect in this run: mode 'rcast' traces no mirror or glass paths (the reflect, refract and pmap "
           "passes do)")
    for line in (f"--set render.reflect_depth=2 {why}", f"--set render.refract_depth=1 {why}",
                 f"--set render={{fresnel: false, spp: 1}}: render.fresnel {why}"):
        assert line in warnings
        assert f"tlm: warning: {line}" in err
    assert not [w for w in warnings if "light_samples" in w]
    out = tmp_path / "r"
    assert main(["run", "configs/cornell.yaml", "--out", str(out), *SMALL, "--mode", "reflect",
                 "--set", "render.reflect_depth=2", "--set", "render.refract_depth=1"]) == 0
    warnings = [w for w in json.loads((out / "results.json").read_text())["warnings"] if "_depth" in w]
    assert warnings == ["--set render.refract_depth=1 has no effect in this run: mode 'reflect' does not include "
                        "the refract pass (the refract and pmap passes read it)"]


def test_a_depth_sweep_under_rcast_says_its_points_are_one_run(tmp_path):
    path = tmp_path / "depth.yaml"
    path.write_text(yaml.safe_dump({"base": {**BASE, "mode": "rcast"}, "grid": {"render.reflect_depth": [1, 2]}}))
    done = run_sweep(path, tmp_path / "s", jobs=1)
    assert (done.ok, done.failed, done.renders) == (2, 0, 1)  # (was 2 rendered: the depth in the key)
    assert any("the factor render.reflect_depth changes nothing in any point: mode 'rcast'" in w
               for w in done.warnings)
