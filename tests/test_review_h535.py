"""h535, a review of h529 (error-vs-cost's ``cut_share`` and the study's line on it).

``study_cut_line`` named every point past the share joined by commas: ``configs/error_vs_cost.yaml`` at a low
``photons.max_bounces`` (every one of its 66 points past 5%) said all 66 numbers in one warning line, and
``points 0, 1`` where every other line of tlm says ``points 0 and 1``. It now lists them as tlm's notes and the
report do (:func:`tlm.config_words.listing`): of many, the first :data:`NAMED_POINTS` and how many more.

With a black reference (``photons.max_bounces`` 1: the reference's indirect map stores nothing) the line said of
its final-gathering points that "its rmse and rel_mse carry part of that share", beside the study's line that every
rel_mse is empty: the clause is now said only where an error is measured, as ``tlm run``'s own line does."""

from __future__ import annotations

import json

from tests.test_installed_copy_leftovers import REFERENCE
from tlm.config import config_from_dict
from tlm.experiments import error_cost as ec
from tlm.experiments.photon_warnings import NAMED_POINTS, study_cut_line


def _rows(n: int, gathered: bool) -> list[dict]:
    return [{"point": i, "factors": f"photons.count={1000 * (i + 1)}", "cut_share": 0.06 + 0.001 * i,
             "final_gather": 4 if gathered else 0} for i in range(n)]


def test_a_study_of_many_points_past_the_share_names_the_first_and_how_many_more():
    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "photons": {"max_bounces": 2}})
    line = study_cut_line(_rows(66, gathered=True), cfg, "abc")
    assert NAMED_POINTS == 7
    assert "(rows' cut_share), points 0, 1, 2, 3, 4, 5, 6 and 59 more; the most, point 65 " in line
    assert "with final gathering (points 0, 1, 2, 3, 4, 5, 6 and 59 more) a point gathers" in line
    assert ", 7," not in line and "65" not in line.split("; the most")[0]  # (no point past the seventh listed)
    assert "\n" not in line


def test_a_few_points_are_listed_as_tlm_lists_them():
    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "photons": {"max_bounces": 2}})
    assert "points 0 and 1; the most, point 1 " in study_cut_line(_rows(2, gathered=False), cfg, "abc")
    # (eight: all named, never "and 1 more")
    assert "points 0, 1, 2, 3, 4, 5, 6 and 7; the most" in study_cut_line(_rows(8, gathered=False), cfg, "abc")


def test_a_black_reference_gets_no_words_on_the_error_of_the_gathering_points(tmp_path, cache):
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({
        "base": {"scene": "cornell", "resolution": [8, 8], "photons": {"count": 2000, "max_bounces": 1},
                 "reference": REFERENCE, "render": {"spp": 1}},
        "points": [{"estimate.final_gather": [0, 4]}],
    }))
    said: list[str] = []
    rows = ec.run_error_vs_cost(exp, tmp_path / "out", truth=ec.Truth(spp=0), warned=said.append)
    assert all(r["rel_mse"] is None for r in rows)  # (the reference black: nothing measured)
    assert [w for w in said if " is black (every pixel 0)" in w]
    [line] = [w for w in said if "photons.max_bounces 1 ends" in w]
    assert line.startswith("error-vs-cost: 2 of the 2 points are traced with photon paths")
    assert line.endswith("raise the base's photons.max_bounces")  # (no clause on rmse and rel_mse)
