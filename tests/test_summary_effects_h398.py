"""A sweep's findings rank no k-NN reference point by frame rate (h398, after h395): ``knn``'s simulated frame
time leaves out its search (:func:`tlm.report.tradeoff.unmodelled_cost`), so a sweep over ``estimate.filter``
(or one whose points all ran knn, from its base config or a --set) does not name a knn point its fastest or
best point, nor knn the best value of the factor that moves the frame rate most; a short clause says why. And
a factor's text values are written as YAML writes them (``cone``, not ``'cone'`` or ``&#x27;cone&#x27;``), a
text YAML would read as another type quoted."""

from __future__ import annotations

from pathlib import Path

from tlm.report import summary
from tlm.report.collect import Inputs, Run, Sweep
from tlm.report.summary import sweep_findings

APART_RAW = "the k-NN reference's frame rate is not ranked, its search not modelled"


def _sweep(grid: dict, points: list[tuple], configs: list[dict] | None = None) -> Sweep:
    """A sweep of ``grid`` whose points are ``(*values, fps, rel_mse)``; ``configs``: each point's
    config.resolved.yaml (its run folder), where given."""
    rows = []
    for i, (*values, fps, err) in enumerate(points):
        rows.append({"point": i, "hash": f"h{i}", "status": "ok", "error": None,
                     **dict(zip(grid, values, strict=True)), "fps": fps, "error.rel_mse": err})
    runs = [Run(Path(f"sweeps/sw/points/h{i}"), f"sw #{i}", "sweep-point", {}, c) for i, c in enumerate(configs or [])]
    return Sweep(Path("sweeps/sw"), {"grid": grid}, rows, runs)


def _said(sw: Sweep) -> str:
    (text,) = sweep_findings(Inputs([], sweeps=[sw]))
    return text.replace("&#x27;", "'")


# knn the fastest and of the lowest error at each photon count (as on CornellBox-Sphere)
FILTERS = _sweep({"estimate.filter": ["disk", "knn", "cone"], "photons.count": [5000, 20000]},
                 [("disk", 5000, 3.0, 0.05), ("disk", 20000, 2.0, 0.03), ("knn", 5000, 4.0, 0.01),
                  ("knn", 20000, 3.5, 0.005), ("cone", 5000, 2.5, 0.04), ("cone", 20000, 1.5, 0.02)])


def test_a_filter_sweep_names_no_knn_point_by_frame_rate():
    text = _said(FILTERS)
    # (the old code: "the best point is estimate.filter = 'knn', photons.count = 5000 at 4 FPS")
    assert "the best point" not in text and "= knn, photons" not in text, text
    assert ("the fastest point is estimate.filter = disk, photons.count = 5000 at 3 FPS (relative MSE 0.05); the "
            "point of the lowest image error of the points ranked (relative MSE 0.02) is estimate.filter = cone, "
            "photons.count = 20000 at 1.5 FPS; " + APART_RAW + " (the 2 points of estimate.filter = knn, the lowest "
            "relative MSE 0.005).") in text, text


def test_knn_is_not_the_best_value_of_the_factor_that_moves_the_frame_rate():
    sw = _sweep({"estimate.filter": ["knn", "disk", "cone"]},
                [("knn", 9.0, 0.01), ("disk", 3.0, 0.05), ("cone", 2.0, 0.04)])
    text = _said(sw)
    # (the old code: "estimate.filter moves the frame rate most, 4.50x between its best value ('knn')")
    assert "estimate.filter moves the frame rate most, 1.50x between its best value (disk) and its worst (cone)" \
        in text, text
    assert text.endswith("the fastest point is estimate.filter = disk at 3 FPS (relative MSE 0.05); the point of "
                         "the lowest image error of the points ranked (relative MSE 0.04) is estimate.filter = cone at "
                         "2 FPS; " + APART_RAW + " (the point of estimate.filter = knn, relative MSE 0.01)."), text


def test_a_sweep_whose_points_all_ran_knn_ranks_none_and_another_mode_ranks_them():
    points = [(5000, 4.0, 0.01), (20000, 3.5, 0.005)]
    knn = [{"mode": "pmap", "estimate": {"filter": "knn"}}] * 2
    text = _said(_sweep({"photons.count": [5000, 20000]}, points, knn))  # (knn from the config, not a factor)
    assert text == ("<b>Sweep sw</b> (2 of 2 points ok): " + APART_RAW + ": every point is of estimate.filter = knn "
                    "(the lowest relative MSE 0.005)."), text
    # in a mode without a photon map the filter gathers nothing: its frame time is modelled in full
    rcast = [{"mode": "rcast", "estimate": {"filter": "knn"}}] * 2
    text = _said(_sweep({"photons.count": [5000, 20000]}, points, rcast))
    assert "k-NN" not in text and "the fastest point is photons.count = 5000 at 4 FPS" in text, text
    # a filter of the model's search (mvoxel, from the config) is ranked as before
    text = _said(_sweep({"photons.count": [5000, 20000]}, points, [{"mode": "pmap", "estimate": {"filter": "mvoxel"}}]
                        * 2))
    assert "k-NN" not in text and "photons.count moves the frame rate most, 1.14x" in text, text


def test_text_values_are_written_as_yaml_writes_them():
    names = _sweep({"estimate.filter": ["cone", "gauss", "box"]}, [("cone", 2.0, 0.1), ("gauss", 2.0, 0.02),
                                                                  ("box", 2.0, 0.05)])
    said = summary._other_errors(Inputs([], sweeps=[names]))
    assert said.endswith("estimate.filter moves the image error most: 5.00x, relative MSE 0.1 at cone → 0.02 at "
                         "gauss."), said  # (the old code: "at &#x27;cone&#x27;")
    assert "&#x27;" not in said
    (text,) = sweep_findings(Inputs([], sweeps=[names]))
    assert "estimate.filter changes the image error (relative MSE 0.1 at cone → 0.02 at gauss)" in text, text
    assert "the best point is estimate.filter = gauss at 2 FPS" in text and "&#x27;" not in text, text
    # a text YAML would read as another type stays quoted, in a list too; null, true and numbers as before
    odd = _sweep({"tag": ["true", "1.5", ["a", "no"], None]},
                 [("true", 1.0, None), ("1.5", 2.0, None), (["a", "no"], 3.0, None), (None, 4.0, None)])
    text = _said(odd)
    assert "its best value (null) and its worst ('true')" in text, text
    assert "the best point is tag = null at 4 FPS" in text, text
    from tlm.report.summary_effects import _as_yaml
    assert [_as_yaml("tag", repr(v)) for v in ("true", "1.5", ["a", "no"], "scene/sphere.yaml", 0.5, "a: b")] == \
        ["'true'", "'1.5'", "[a, 'no']", "scene/sphere.yaml", "0.5", "'a: b'"]
