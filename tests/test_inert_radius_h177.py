"""``estimate.radius_photons`` under final gathering (``estimate.final_gather`` > 0, the default) sizes
the indirect map, which is then not gathered: the final-gather rays gather the global map, sized by
``estimate.final_gather_photons`` (or ``radius`` / ``radius_fraction`` when given). It changes neither
the image nor the work nor the cycles, yet a sweep of it rendered every value and said nothing, a run's
``--set`` of it got no "has no effect" line, and a thesis cell was marked not comparable for it.
:func:`tlm.render.planner.inert_settings` now names it; the functional key keeps it
(:func:`tlm.render.planner.recorded_inert_settings`), since ``results.json`` records the indirect
map's radius it sizes (``photons.radius``, ``photons.radius_photons``)."""

from __future__ import annotations

import dataclasses

import yaml

from tlm.config import RunConfig, config_from_dict, to_dict
from tlm.experiments.frames import functional_key
from tlm.experiments.sweep_file import load_sweep
from tlm.experiments.thesis_setting import setting_mismatches, thesis_setting
from tlm.render.planner import inert_changes, inert_settings

KEY = "estimate.radius_photons"


def cfg(mode: str = "pmap", **estimate) -> RunConfig:
    return config_from_dict({"scene": "cornell", "mode": mode, "estimate": estimate})


def test_inert_under_final_gathering_with_the_density_rule():
    assert RunConfig().estimate.final_gather > 0  # (the default: final gathering)
    why = inert_settings(cfg())[KEY]
    assert "final_gather" in why and "final_gather_photons" in why
    assert KEY not in inert_settings(cfg(final_gather=0))  # (the indirect map is gathered: it reads)
    # a radius or fraction given comes first, and says so (under final gathering too)
    assert "comes first" in inert_settings(cfg(radius_fraction=0.02))[KEY]
    assert "comes first" in inert_settings(cfg(radius=3.0))[KEY]
    assert "comes first" in inert_settings(cfg(final_gather=0, radius_fraction=0.02))[KEY]
    # the caustic map is gathered at every point under final gathering too
    assert "estimate.caustic_radius_photons" not in inert_settings(cfg())
    assert "estimate.final_gather_photons" not in inert_settings(cfg())


def test_a_set_of_it_has_no_effect_in_a_final_gathering_run():
    lines = inert_changes(cfg(radius_photons=25))
    assert [ln for ln in lines if ln.startswith(f"{KEY} = 25 has no effect in this run: ")], lines
    assert not [ln for ln in inert_changes(cfg(radius_photons=25, final_gather=0)) if KEY in ln]


def test_the_functional_key_keeps_it_for_the_recorded_radius():
    """Inert, yet in the key: a frame's summary records the indirect radius it sizes, so points of
    other values must not share one frame (their results.json would record another's radius)."""
    assert KEY in inert_settings(cfg())

    def key(c: RunConfig) -> str:
        return functional_key(c, "scene", "code")

    assert key(cfg(radius_photons=25)) != key(cfg())
    assert key(cfg(radius_photons=25, final_gather=0)) != key(cfg(final_gather=0))
    assert key(cfg(radius_photons=25, radius_fraction=0.02)) == key(cfg(radius_fraction=0.02))  # (as before)
    assert key(cfg("rcast", radius_photons=25)) == key(cfg("rcast"))
    assert key(cfg()) == functional_key(to_dict(cfg()), "scene", "code")


def sweep_file(tmp_path, **estimate):
    path = tmp_path / "sw.yaml"
    path.write_text(yaml.safe_dump({
        "base": {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "estimate": estimate},
        "grid": {KEY: [25, 100, 400]}}))
    return load_sweep(path)


def test_a_sweep_of_it_under_final_gathering_says_it_changes_nothing(tmp_path):
    lines = sweep_file(tmp_path).inert_factors()
    assert [ln for ln in lines if f"the factor {KEY} changes nothing in any point" in ln
            and "final_gather_photons" in ln], lines
    assert not [ln for ln in sweep_file(tmp_path, final_gather=0).inert_factors() if KEY in ln]


def test_a_thesis_cell_is_not_marked_for_it_under_final_gathering():
    thesis = config_from_dict(thesis_setting("cornell", "pmap"))
    assert thesis.estimate.final_gather == 0  # (the thesis's pipeline: the indirect map is gathered)

    def found(**estimate) -> list[str]:  # (the density rule: the thesis study's radius_fraction left out)
        est = dataclasses.replace(thesis.estimate, radius_fraction=None, **estimate)
        return setting_mismatches("cornell", to_dict(dataclasses.replace(thesis, estimate=est)))

    under = found(final_gather=16, radius_photons=25)
    assert any(m.startswith("estimate.final_gather ") for m in under), under  # (that one does change the image)
    assert not any(m.startswith(f"{KEY} ") for m in under), under
    assert any(m.startswith(f"{KEY} 25") for m in found(radius_photons=25))  # (gathered without it: named)
