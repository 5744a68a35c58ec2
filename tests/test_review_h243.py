"""Review of 3e3fbfa (the gather's work item ``photons_weighted``), h243.

``results.json``'s ``photons.gather.<map>`` splits the pmap pass's work between the photon maps;
its photons and leaves summed over the maps are ``work.pmap``'s. ``photons_weighted`` (the accepted
photons whose weight the filter computes) was counted in ``work.pmap`` but left out of the split.
"""

from __future__ import annotations

import pytest

from tlm.config import config_from_dict
from tlm.experiments.run import render, results_dict

# (not gathers: without final gathering every gather point searches both maps, one gather of work.pmap)
TALLIED = ("photons_tested", "photons_accepted", "photons_weighted", "leaves_visited")


def _results(name: str, final_gather: int) -> dict:
    cfg = config_from_dict({"seed": 3, "scene": "cornell", "mode": "pmap", "resolution": [8, 6],
                            "photons": {"count": 600}, "estimate": {"filter": name, "final_gather": final_gather},
                            "arch": {"frames": 1, "trace": False}}, "test")
    return results_dict(render(cfg), 1.0, None)


@pytest.mark.parametrize(("name", "final_gather", "maps"), [
    ("mvoxel", 0, {"caustic", "indirect"}),
    ("disk", 2, {"caustic", "global"}),  # (the global map's gathers: final gathering's)
])
def test_each_maps_tally_has_the_weighted_photons_and_they_sum_to_the_work(name, final_gather, maps, tmp_path,
                                                                             monkeypatch):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    r = _results(name, final_gather)
    per_map, work = r["photons"]["gather"], r["work"]["pmap"]
    assert set(per_map) == maps
    for k in TALLIED:
        assert sum(m[k] for m in per_map.values()) == work[k], k
    assert work["photons_accepted"] > 0
    for m in per_map.values():
        # disk (eq. 3.2) weighs no photon; the m-voxel cone (eq. 3.3) every accepted one
        assert m["photons_weighted"] == (0 if name == "disk" else m["photons_accepted"])
