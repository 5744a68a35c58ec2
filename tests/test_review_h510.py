"""A review of 844380c, e7e46dc and a977f1b (h510):

* ``tlm.to_srgb(res)`` made the composite twice (once for its pixels, once more in ``res.exposure``): now once.
* ``tlm.load_config(cfg)`` of a ``Config`` whose settings the checks never made (a Config unpickled from a tlm of
  before the checks: dataclasses' unpickling calls no ``__post_init__``) gave it back as it was, its resolution a
  list (``hash(cfg)`` a TypeError) and a bad value unsaid: now checked, as a RunConfig of such a pickle is.
* ``report_style``'s end put back every setting as it was when the report began, so a setting another thread set
  meanwhile (a notebook's ``plt.style.use`` while a report is written in a thread) was lost: now kept.
"""

from __future__ import annotations

import copy
import dataclasses
import threading

import matplotlib
import pytest

import tlm
import tlm.report.common as common
from tlm.config import RunConfig
from tlm.errors import InputError
from tlm.experiments import run as runs

SMALL = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1}}


def test_to_srgb_of_a_result_makes_its_composite_once(cache, monkeypatch):
    res = tlm.render_image(SMALL)
    made = []
    composite = runs.RenderResult.composite.fget
    monkeypatch.setattr(runs.RenderResult, "composite", property(lambda self: made.append(1) or composite(self)))
    rgb = tlm.to_srgb(res)
    assert len(made) == 1  # (was 2: res.exposure made it again)
    made.clear()
    assert (rgb == tlm.to_srgb(res.composite, res.exposure)).all()
    assert (tlm.to_srgb(res, 0.5) == tlm.to_srgb(res.composite, 0.5)).all()


def _unpickled(cfg: tlm.Config, settings: RunConfig) -> tlm.Config:
    """``cfg`` with ``settings`` as an unpickled Config holds them: set without ``__post_init__``."""
    out = copy.copy(cfg)
    object.__setattr__(out, "settings", settings)
    return out


def test_a_config_whose_settings_were_never_checked_is_checked():
    cfg = tlm.load_config(SMALL)
    older = RunConfig(**{f.name: getattr(cfg.settings, f.name) for f in dataclasses.fields(RunConfig)})
    object.__setattr__(older, "resolution", [8, 8])  # (as a tlm before e7e46dc held it)
    got = tlm.load_config(_unpickled(cfg, older))
    assert got.resolution == (8, 8) and hash(got) == hash(cfg) and got == cfg  # (was: [8, 8], hash a TypeError)
    bad = _unpickled(cfg, dataclasses.replace(cfg.settings, seed=-3))
    with pytest.raises(InputError, match=r"^\(RunConfig\): seed: -3 must be >= 0$"):
        tlm.load_config(bad)
    assert tlm.load_config(cfg) is cfg  # (checked: as it is)


def test_a_setting_another_thread_sets_while_a_report_draws_is_kept():
    with matplotlib.rc_context({"font.size": 14, "axes.facecolor": "black", "lines.linewidth": 3}):
        inside, done = threading.Event(), threading.Event()

        def report():
            try:
                with common.report_style():
                    inside.set()
                    done.wait()
            finally:
                inside.set()  # (a report_style that failed: no wait for it)

        writer = threading.Thread(target=report, daemon=True)
        writer.start()
        inside.wait()
        try:
            assert matplotlib.rcParams["font.size"] == 10  # (the report's)
            matplotlib.rcParams["font.size"] = 20  # (a notebook's cell meanwhile)
        finally:
            done.set()
            writer.join()
        assert matplotlib.rcParams["font.size"] == 20  # (was 14: the value before the report, put back)
        assert matplotlib.rcParams["axes.facecolor"] == "black" and matplotlib.rcParams["lines.linewidth"] == 3
