"""The words of the warnings on settings that change nothing.

* ``--set photons.count=0`` in mode pmap left the photon-map pass out, as asked, and was then
  called a setting of no effect ("the photon-map pass is left out (photons.count is 0)"): the key
  the plan's reason names is not (:func:`tlm.experiments.run_warnings.unread_overrides`).
* A sweep's factor that changed nothing said the same clause once per value ("alone at depth 1
  and at 1024 ...; ... depth 16 and at 1024 ...; ..."): once now, the values listed
  (:func:`tlm.experiments.sweep_file.said_once`)."""

from __future__ import annotations

import pytest
import yaml

from tlm.config import config_from_dict
from tlm.experiments.run_warnings import unread_overrides
from tlm.experiments.sweep import run_sweep
from tlm.render.planner import plan
from tlm.scenes.loader import load_scene


class Ran:  # (what unread_overrides reads of a render: its plan)
    def __init__(self, **raw):
        self.plan = plan(load_scene("cornell", None, [8, 8]), config_from_dict(raw))


def test_the_key_that_left_the_pass_out_is_not_called_inert():
    ran = Ran(mode="pmap", photons={"count": 0, "max_bounces": 4})
    assert unread_overrides(ran, ["photons.count=0"]) == []  # (was: "... (photons.count is 0)")
    (line,) = unread_overrides(ran, ["photons.count=0", "photons.max_bounces=4"])
    assert line.startswith("--set photons.max_bounces=4 has no effect") and line.endswith("(photons.count is 0)")
    bounces = Ran(mode="pmap", photons={"max_bounces": 1})
    assert unread_overrides(bounces, ["photons.max_bounces=1"]) == []
    assert len(unread_overrides(bounces, ["photons.count=100"])) == 1
    assert len(unread_overrides(Ran(mode="rcast"), ["photons.count=0"])) == 1  # (the mode left it out)


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def test_a_factor_that_changed_nothing_says_its_reason_once(tmp_path):
    # (h349: at 16x16 the depths 1, 16 and 256 left the cycles alone but moved the packets-of-one estimate,
    # timing.granularity share 0.0566, 0.0566, 0.0605 against 0.0668 at 1024: no longer called unread; a 2x2
    # frame's phases fit in 1024 entries together, a ray or pixel an entry at least, at each depth above it)
    base = {"scene": "cornell", "mode": "rcast", "resolution": [2, 2], "render": {"light_samples": 1, "spp": 1},
            "arch": {"frames": 2, "trace": False}}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": base, "grid": {"arch.fifo_depth": [2048, 4096, 8192]}}))
    done = run_sweep(path, tmp_path / "o", jobs=1)
    (line,) = [w for w in done.warnings if "arch.fifo_depth changed nothing" in w]
    assert line.count("the FIFO never fills") == 1, line  # (was 3: one per value)
    assert "fit in 1024 FIFO entries together" in line, line
