"""h430: three small honesty fixes.

* ``tlm thesis``: a scene with no table (``bunny.yaml``, a user's ``room.yaml``) has its ``thesis`` and
  ``rel_error`` blank, but its rcast TVert/TTrav/TFrag rows still said ``calibrated: true``, though nothing
  was fitted to them: now false (:func:`tlm.experiments.thesis.table_rows`, and
  :func:`~tlm.experiments.thesis_tables.comparison_rows` of a scene the tables lack).
* ``tlm error-vs-cost``: a row of a filter that uses no radius (``knn``) recorded the config's
  ``radius_fraction``, which does nothing there; it is null now (an empty cell in rows.csv, not ``null``,
  which is the density rule's value), as a knn run records its radius since 7085725.
* Through the Python API a study's refusal of ``base.render.spp=2`` said ``... and overrides sets what base
  holds (the run config): overrides render.spp=2`` (the command line's ``--set`` rewritten word for word);
  it reads ``overrides=["render.spp=2"]`` now. The command line's text is unchanged
  (tests/test_leftovers_h423.py pins it).
"""

from __future__ import annotations

import csv
import json

import pytest

import tlm
from tlm.api_common import arguments_text
from tlm.experiments.error_cost import Truth, run_error_vs_cost
from tlm.experiments.thesis import CALIBRATED, comparison_rows, table_rows
from tlm.report.tradeoff import _point_name

OURS = {"TVert": 1.0, "TTrav": 20.0, "Tisct": 10.0, "TFrag": 5.0, "TThru": 21.0, "FPS": 30.0}


def test_a_scene_with_no_table_has_no_calibrated_cell():
    for rows in (table_rows("bunny", None, "rcast", OURS), table_rows("ring", None, "rcast", OURS),
                 comparison_rows("bunny", "rcast", OURS)):
        assert [r["calibrated"] for r in rows] == [False] * len(rows), rows  # (the old code: True for 3 of them)
        assert all(r["thesis"] is None and r["rel_error"] is None for r in rows)
    # a table's scene keeps its calibrated cells
    fitted = {r["metric"] for r in table_rows("ring", "ring", "rcast", OURS) if r["calibrated"]}
    assert fitted == {m for mode, m in CALIBRATED if mode == "rcast"} == {"TVert", "TTrav", "TFrag"}
    assert not any(r["calibrated"] for r in table_rows("ring", "ring", "pmap", OURS))


BASE = {"scene": "cornell", "seed": 0, "resolution": [8, 8], "render": {"spp": 1}, "photons": {"count": 400},
        "reference": {"photons": 400, "k_nearest": 20, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 2,
                      "spp": 1}}
POINTS = [{"estimate.filter": ["knn", "disk"], "estimate.radius_fraction": [0.03]},
          {"estimate.filter": ["disk"]}]


def test_an_error_vs_cost_row_of_knn_records_no_radius_fraction(tmp_path, cache):
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({"base": BASE, "points": POINTS}))
    rows = run_error_vs_cost(exp, tmp_path / "out", truth=Truth(spp=0))
    assert [(r["filter"], r["radius_fraction"]) for r in rows] == [("knn", None), ("disk", 0.03), ("disk", None)]
    saved = [json.loads(line) for line in (tmp_path / "out" / "rows.jsonl").read_text().splitlines()]
    assert [r["radius_fraction"] for r in saved] == [None, 0.03, None]
    with open(tmp_path / "out" / "rows.csv", newline="") as fh:
        cells = [r["radius_fraction"] for r in csv.DictReader(fh)]
    # (knn: of no meaning, an empty cell; the disk's null is the density rule, a setting: 'null')
    assert cells == ["", "0.03", "null"]
    # the report's point names: no radius for knn, the disk's fraction
    knn, disk = _point_name(saved[0]), _point_name(saved[1])
    assert knn.startswith("knn") and f", k={saved[0]['k_nearest']}" in knn and "r=" not in knn, knn
    assert disk.startswith("disk") and ", r=0.03" in disk, disk


SWEEP = {"base": {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "arch": {"frames": 1}},
         "grid": {"arch.fifo_depth": [4, 8]}}


@pytest.mark.parametrize("call", ["granularity", "sweep"])
def test_the_api_is_told_the_overrides_item_that_sets_a_key_under_base(tmp_path, cache, call):
    text = {**SWEEP, "packet_sizes": [4, 16]} if call == "granularity" else SWEEP
    if call == "granularity":
        text.pop("grid")
    study = tmp_path / "s.yaml"
    study.write_text(json.dumps(text))
    out = tmp_path / "o"
    with pytest.raises(tlm.InputError) as e:
        getattr(tlm, call)(study, out=out, overrides=["base.render.spp=2"])
    said = str(e.value)
    assert said.endswith(': overrides=["render.spp=2"]'), said  # (the old code: 'overrides render.spp=2')
    assert "overrides set what base holds" in said and "--set" not in said, said
    assert e.value.key == "overrides base.render.spp=2"
    assert not out.exists()


def test_set_items_are_named_as_python_passes_them():
    names = {"overrides", "out"}
    assert arguments_text("give them one by one: --set a=1 --set 'b={c: 2}'", names) == \
        'give them one by one: overrides=["a=1", "b={c: 2}"]'
    assert arguments_text("leave --set mode out", names) == "leave overrides mode out"  # (no item: the argument)
    # a command shown whole, and a config's label, keep the flag
    assert arguments_text("run tlm run cornell --set scene=x.yaml", names) == "run tlm run cornell --set scene=x.yaml"
    assert arguments_text("cornell.yaml, with --set: render.spp: bad", names) == \
        "cornell.yaml, with --set: render.spp: bad"
    assert arguments_text("--set render.spp=2", {"out"}) == "--set render.spp=2"  # (no overrides argument)


def test_an_error_vs_cost_row_with_a_radius_given_records_no_radius_fraction(tmp_path, cache):
    """(lead, stop 68) A row whose base gives ``estimate.radius`` (scene units, which comes first) recorded its
    ``radius_fraction`` as if the fraction had sized the gather, and the report named the point ``r=0.03``: it is
    null now, an empty cell in rows.csv, as under knn; a kvoxel point keeps both its k and its fraction."""
    exp = tmp_path / "evc.yaml"
    base = {**BASE, "estimate": {"radius": 0.05}}
    points = [{"estimate.filter": ["disk"], "estimate.radius_fraction": [0.03]}]
    exp.write_text(json.dumps({"base": base, "points": points}))
    rows = run_error_vs_cost(exp, tmp_path / "out", truth=Truth(spp=0))
    assert [(r["radius_fraction"], r["radius"], r["radius_rule"]) for r in rows] == [(None, 0.05, "radius")]
    with open(tmp_path / "out" / "rows.csv", newline="") as fh:
        assert [r["radius_fraction"] for r in csv.DictReader(fh)] == [""]  # (not 'null', the density rule)
    name = _point_name(rows[0])
    assert "r=" not in name and name.startswith("disk"), name
    kvoxel = _point_name({"filter": "kvoxel", "photons": 1000, "k": 8, "radius_fraction": 0.02})
    assert kvoxel == "kvoxel, 1,000 ph, k=8, r=0.02", kvoxel
    density = _point_name({"filter": "kvoxel", "photons": 1000, "k": 8, "radius_fraction": None})
    assert density == "kvoxel, 1,000 ph, k=8", density  # (the old code: 'r=nan')
