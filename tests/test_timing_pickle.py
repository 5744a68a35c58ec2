"""A Timing pickles (a process pool returns it): every figure docs/api.md reads and to_dict()
come back equal; the live SimPy model is left out, and reading it says so."""

from __future__ import annotations

import copy
import json
import pickle

import pytest

import tlm
from tlm.arch import model
from tlm.arch.model import Timing

SMALL = {"mode": "rcast", "resolution": [16, 16], "render.spp": 1, "render.light_samples": 1,
         "arch.packet_size": 16}


@pytest.fixture(scope="module")
def res():
    return tlm.render_image(tlm.load_config("cornell", SMALL))


def _figures(t: Timing) -> dict:
    """What docs/api.md reads of a Timing, and the rest of its numbers."""
    return {"pms": {pm: t.cycles[pm] for pm in ("vertex", "traversal", "intersection", "fragment")},
            "throughput": t.cycles["throughput"], "fps": t.fps, "cycles": t.cycles, "units": t.units,
            "frames": t.frames, "events": t.events, "checks": t.checks, "crossbar": t.crossbar,
            "pipelines": t.pipelines, "throughput_estimate": t.throughput_estimate,
            "event_budget": t.event_budget, "granularity": t.granularity}


@pytest.mark.parametrize("arch", [{"trace": False}, {"pipelines": 2, "trace": True}])
def test_a_timing_pickles_with_every_figure_and_its_dict(res, arch):
    t = tlm.simulate(res, arch)
    again = pickle.loads(pickle.dumps(t))
    assert _figures(again) == _figures(t)
    assert again.to_dict() == t.to_dict()
    assert json.dumps(again.to_dict(), sort_keys=True) == json.dumps(t.to_dict(), sort_keys=True)
    assert (again.trace is None) == (t.trace is None) == (not arch["trace"])
    if t.trace is not None:
        assert again.trace.events == t.trace.events
    assert t.model.pms  # (the original keeps its live model)


def test_the_model_of_an_unpickled_timing_says_it_was_not_kept(res):
    t = tlm.simulate(res)
    for again in (pickle.loads(pickle.dumps(t)), copy.deepcopy(t)):
        assert again.model is model.MODEL_NOT_KEPT
        with pytest.raises(AttributeError, match=r"timing\.model: this Timing was pickled .*call tlm\.simulate again"):
            again.model.pms  # noqa: B018
        assert pickle.loads(pickle.dumps(again)).to_dict() == t.to_dict()  # (and pickles again)
        assert "not kept" in repr(again.model)
    assert copy.copy(t).model is t.model  # (a shallow copy keeps it)
