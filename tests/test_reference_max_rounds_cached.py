"""A cached reference that stopped at ``reference.max_rounds`` is kept by a run that would stop it there too.

The rounds are seeded alike whatever the stopping rule, so a reference that ran all its
``reference.max_rounds`` short of its tolerance is what computing it again gives wherever the
settings allow as many cycles of the same length and no earlier cycle meets their tolerance: a
stricter tolerance, or a ``max_rounds`` that is no whole cycle more. ``tlm reference`` computed
those again (the same rounds, the same error, the seconds lost) because the settings were not
the ones stored; now it keeps the cached one without computing, as it does for the same settings.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.helpers_reference import held_reference
from tlm.cli import main
from tlm.experiments import reference
from tlm.experiments.reference_cache import ReferenceSettings, repeats

# 2 cycles of 2 rounds, far short of the tolerance: not converged (exit status 1)
SHORT = {"photons": 500, "k_nearest": 20, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 4, "spp": 2}
PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "render": {"spp": 1}, "photons": {"count": 500}}


def _config(tmp_path, ref: dict) -> str:
    path = tmp_path / "cfg.json"
    path.write_text(json.dumps({**PMAP, "reference": ref}))
    return str(path)


@pytest.mark.parametrize("asked", [{"tolerance": 1e-7}, {"max_rounds": 5}, {"tolerance": 1e-7, "min_rounds": 3}],
                         ids=["stricter-tolerance", "max-rounds-no-whole-cycle-more", "stricter-and-min-rounds"])
def test_a_reference_at_max_rounds_is_kept_where_computing_it_would_stop_at_the_same_round(
        tmp_path, cache, capsys, monkeypatch, asked):
    assert main(["reference", _config(tmp_path, SHORT), "--no-progress"]) == 1
    capsys.readouterr()
    old, image = held_reference(cache)
    assert old["rounds"] == 4 and old["cycles"] == 2 and old["converged"] is False

    monkeypatch.setattr(reference, "compute_reference", lambda *a, **k: pytest.fail("computed the same rounds again"))
    assert main(["reference", _config(tmp_path, {**SHORT, **asked}), "--no-progress"]) == 1
    out = capsys.readouterr().out
    said = [line for line in out.splitlines() if "would repeat the same rounds, so it is kept" in line]
    assert len(said) == 1 and f"reference {old['key']} is cached with 4 rounds" in said[0]
    assert "these reference settings stop it too (cycles of 2 rounds, at most 2 of them" in said[0]
    assert "NOT converged (max_rounds reached) after 4 rounds" in out
    meta, now = held_reference(cache)
    assert meta == old
    np.testing.assert_array_equal(now, image)


def test_repeats_only_where_the_same_rounds_would_come_again():
    """Not where the settings allow more cycles, cut them otherwise (another ``spp``), or would stop
    at an earlier cycle that meets their tolerance (converged: better than the cached one)."""
    meta = {"tolerance": 0.01, "min_rounds": 4, "max_rounds": 16, "spp": 4, "rounds": 16, "rounds_per_cycle": 4,
            "cycles": 4, "relative_standard_error": 0.05, "standard_error_per_cycle": [0.2, 0.03, 0.05],
            "converged": False}
    at = ReferenceSettings(photons=100, tolerance=0.01, min_rounds=4, max_rounds=16, spp=4)
    assert repeats(meta, at)  # (its own stopping rule)
    assert repeats(meta, ReferenceSettings(photons=100, tolerance=0.005, min_rounds=4, max_rounds=19, spp=4))
    assert not repeats(meta, ReferenceSettings(photons=100, tolerance=0.01, min_rounds=4, max_rounds=20, spp=4))
    assert not repeats(meta, ReferenceSettings(photons=100, tolerance=0.01, min_rounds=4, max_rounds=16, spp=2))
    # tolerance 0.04: cycle 3 (error 0.03) meets it, so computing again stops there, converged
    assert not repeats(meta, ReferenceSettings(photons=100, tolerance=0.04, min_rounds=4, max_rounds=16, spp=4))
    # ... unless min_rounds keeps it going past cycle 3: then all 4 cycles again, the last missing 0.04
    assert repeats(meta, ReferenceSettings(photons=100, tolerance=0.04, min_rounds=16, max_rounds=16, spp=4))
    # tolerance 0.06: it meets it as it is (used, not computed)
    assert not repeats(meta, ReferenceSettings(photons=100, tolerance=0.06, min_rounds=4, max_rounds=16, spp=4))
    old = {k: v for k, v in meta.items() if k != "standard_error_per_cycle"}  # (no errors per cycle: rule only)
    assert repeats(old, at)
    assert not repeats(old, ReferenceSettings(photons=100, tolerance=0.005, min_rounds=4, max_rounds=16, spp=4))
