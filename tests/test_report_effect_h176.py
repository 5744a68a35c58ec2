"""A sweep's findings judge a factor by the frame rate and, where its points measured it, the image error
(h176): a factor that keeps the frame rate but changes the error does not "change nothing"; among points
tied at the best frame rate the one of least error is the best; "What quality costs" names the factor
that moves the error most."""

from __future__ import annotations

from pathlib import Path

from tlm.report import summary
from tlm.report.collect import Inputs, Sweep
from tlm.report.summary import sweep_findings

# the probe's sweep (/tmp/h175/runs/sw_fg0): the photon count sets the frame rate, the radius only the error
COUNTS = [25000, 25000, 25000, 100000, 100000, 100000]
RADII = [25, 100, 400, 25, 100, 400]
FPS = {25000: 2.012233912667774, 100000: 1.3370723044980009}
ERRORS = [0.05267871683869027, 0.023378030619686, 0.02312246305871306,
          0.05470591733510213, 0.021706238571845872, 0.014366314581577453]


def _sweep(errors: list | None, fps: dict | None = None) -> Sweep:
    fps = fps or FPS
    spec = {"grid": {"photons.count": [25000, 100000], "estimate.radius_photons": [25, 100, 400]}}
    rows = []
    for i, (n, r) in enumerate(zip(COUNTS, RADII, strict=True)):
        row = {"point": i, "hash": f"{i:016x}", "status": "ok", "error": None, "photons.count": n,
               "estimate.radius_photons": r, "fps": fps[n]}
        if errors is not None and errors[i] is not None:
            row["error.rel_mse"] = errors[i]
        rows.append(row)
    return Sweep(Path("sweeps/sw"), spec, rows, [])


def test_a_factor_that_changes_only_the_error_is_said_to_change_it_and_the_least_error_tie_is_best():
    (text,) = sweep_findings(Inputs([], sweeps=[_sweep(ERRORS)]))
    assert "changes nothing" not in text
    assert ("estimate.radius_photons changes the image error (relative MSE 0.0537 at 25 → 0.0187 at 400, averaged "
            "over the other factors), not the frame rate, between points that differ only in it; ") in text
    assert text.endswith("the fastest point is photons.count = 25000, estimate.radius_photons = 400 at 2.01 FPS, the "
                         "least image error (relative MSE 0.0231) of the 3 points tied at that frame rate; the point "
                         "of the lowest image error (relative MSE 0.0144) is photons.count = 100000, "
                         "estimate.radius_photons = 400 at 1.34 FPS.")  # (a slower point's error is lower: h396)


def test_points_tied_in_frame_rate_and_error_are_each_named():
    errors = [0.05, 0.02, 0.02, 0.06, 0.03, 0.01]
    (text,) = sweep_findings(Inputs([], sweeps=[_sweep(errors)]))
    assert text.endswith("the fastest points, tied at 2.01 FPS and at the least image error (relative MSE 0.02) of the "
                         "3 points tied at that frame rate, are (photons.count = 25000, estimate.radius_photons = 100) "
                         "and (photons.count = 25000, estimate.radius_photons = 400); the point of the lowest image "
                         "error (relative MSE 0.01) is photons.count = 100000, estimate.radius_photons = 400 at "
                         "1.34 FPS.")


def test_a_factor_that_changes_neither_says_so():
    errors = [0.05, 0.05, 0.05, 0.02, 0.02, 0.02]
    (text,) = sweep_findings(Inputs([], sweeps=[_sweep(errors)]))
    assert ("estimate.radius_photons changes nothing (neither the frame rate nor the image error) between points "
            "that differ only in it; 3 points tie as the fastest at 2.01 FPS (relative MSE 0.05): photons.count = "
            "25000, any estimate.radius_photons; 3 points tie at the lowest image error (relative MSE 0.02), at 1.34 "
            "FPS: photons.count = 100000, any estimate.radius_photons.") in text


def test_one_frame_rate_everywhere_still_finds_the_error():
    (text,) = sweep_findings(Inputs([], sweeps=[_sweep(ERRORS, {25000: 2.0, 100000: 2.0})]))
    assert text.startswith("<b>Sweep sw</b> (6 of 6 points ok): no factor changes the frame rate (every point runs "
                           "at 2 FPS); ")
    assert "estimate.radius_photons changes the image error (relative MSE 0.0537 at 25 → 0.0187 at 400" in text
    assert "photons.count changes the image error (relative MSE 0.0331 at 25000 → 0.0303 at 100000" in text
    assert text.endswith("the best point is photons.count = 100000, estimate.radius_photons = 400 at 2 FPS, the least "
                         "image error (relative MSE 0.0144) of the 6 points tied at that frame rate.")


def test_an_error_not_measured_where_it_could_be_compared_is_not_called_nothing():
    errors = [0.05, None, None, None, None, 0.01]  # (no two radii measured at one photon count)
    (text,) = sweep_findings(Inputs([], sweeps=[_sweep(errors)]))
    assert "changes nothing" not in text
    assert ("estimate.radius_photons does not change the frame rate between points that differ only in it (the image "
            "error not measured at such points); ") in text


def test_what_quality_costs_names_the_factor_that_moves_the_error_most():
    sw = _sweep(ERRORS)
    text = summary._other_errors(Inputs([], sweeps=[sw]))
    assert text.endswith(" In sw, estimate.radius_photons moves the image error most: 2.86x, relative MSE 0.0537 at "
                         "25 → 0.0187 at 400, averaged over the other factors.")
    # two factors moving it as much: neither is named
    tied = _sweep([0.02, 0.015, 0.01, 0.01, 0.0075, 0.005])  # (each halves it)
    assert "moves the image error most" not in summary._other_errors(Inputs([], sweeps=[tied]))
