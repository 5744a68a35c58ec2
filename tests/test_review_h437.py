"""h437, a review of 574d920 (an error-vs-cost row whose ``estimate.radius`` is given records no
``radius_fraction``): rows.csv decided its empty cell by the row's ``radius_rule``, which is empty where the
indirect map is not gathered (``photons.count: 0``), so such a point's cell read ``null``, the density rule's
value, though its radius was given; it is decided by the point's own config now."""

from __future__ import annotations

import csv
import json

from tlm.experiments.error_cost import Truth, run_error_vs_cost

BASE = {"scene": "cornell", "seed": 0, "resolution": [8, 8], "render": {"spp": 1}, "photons": {"count": 400},
        "reference": {"photons": 400, "k_nearest": 20, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 2,
                      "spp": 1}}


def test_a_point_with_a_radius_given_and_no_map_gathered_has_an_empty_radius_fraction_cell(tmp_path, cache):
    exp = tmp_path / "evc.yaml"
    points = [{"estimate.filter": ["disk"], "photons.count": [0, 400], "estimate.radius": [0.05, None]}]
    exp.write_text(json.dumps({"base": BASE, "points": points}))
    rows = run_error_vs_cost(exp, tmp_path / "out", truth=Truth(spp=0))
    got = [(r["photons"], r["radius_fraction"], r["radius_rule"]) for r in rows]
    assert got == [(0, None, None), (0, None, None), (400, None, "radius"), (400, None, "density")], got
    with open(tmp_path / "out" / "rows.csv", newline="") as fh:
        cells = [(r["factors"], r["radius_fraction"]) for r in csv.DictReader(fh)]
    # (given: of no meaning, empty; not given, null: the density rule, the setting's value, as before)
    assert [c for _, c in cells] == ["", "null", "", "null"], cells  # (the old code: 'null' for the first)
