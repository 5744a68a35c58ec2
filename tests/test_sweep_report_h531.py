"""h531: a sweep report's image-error ranking across references, and three small report defects (h524's probe).

1. A sweep over a factor of the reference's key (``photons.max_bounces``, ``--reference``) measures each point's
   image error against its own reference, yet the summary ranked the points by it ("the best point is
   photons.max_bounces = 2 ..., with the lowest image error", "moves the image error most: 1.21x"). Errors are now
   compared only among points of one reference (results.json ``error.reference``); a filter A/B shares one.
2. "the 2 sweep points run from 27.6 FPS (#0) to 27.6 FPS (#1)": rates that print alike.
3. The points table's host s of a point that reused a render looked like a faster host: now marked.
4. The scaling section's speed-up column was empty unless N = 1 was swept: now against the smallest N swept.
5. A point left by an earlier sweep of other code, the grid grown since, named the grid change first.
"""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

from tlm.report.collect import Inputs, Run, Sweep
from tlm.report.scaling import idle_points, idle_table
from tlm.report.summary_effects import ERROR, error_factor, sweep_findings
from tlm.report.summary_points import fps_of_points
from tlm.report.sweeps import table


def _sweep(grid: dict, rows: list[dict], refs: list[str]) -> Sweep:
    """A sweep of ``rows`` (factors, fps, error), each point's results.json naming its reference ``refs[i]``."""
    rows = [{"point": i, "hash": f"h{i}", "status": "ok", "error": None, **r} for i, r in enumerate(rows)]
    runs = [Run(Path(f"sw/points/h{i}"), f"sw #{i}", "sweep-point", {"error": {"reference": ref}}, {})
            for i, ref in enumerate(refs)]
    return Sweep(Path("sw"), {"grid": grid}, rows, runs)


def test_errors_against_each_points_own_reference_are_not_ranked():
    """h524's sweep_refkey: 2 bounces the faster and of the lower error, but against another reference."""
    sw = _sweep({"photons.max_bounces": [2, 8]}, [{"photons.max_bounces": 2, "fps": 22.65, ERROR: 0.01996},
                                                  {"photons.max_bounces": 8, "fps": 18.88, ERROR: 0.02414}],
                ["38fa6a9355ec1e3653a7", "97fce86dc0524170e6da"])
    (text,) = sweep_findings(Inputs([], sweeps=[sw]))
    assert "lowest image error" not in text and "best point" not in text, text
    assert ("the fastest point is photons.max_bounces = 2 at 22.6 FPS; no point is ranked by its image error: the "
            "points measured it against 2 references (results.json error.reference), the reference changing with "
            "photons.max_bounces, and errors against different references are not comparable.") in text, text
    quality = error_factor(Inputs([], sweeps=[sw]))
    assert "moves the image error most" not in quality and "1.21x" not in quality, quality
    assert quality.startswith(" In sw, no image error is compared across photons.max_bounces: the points measured it "
                              "against 2 references"), quality


def test_a_factor_outside_the_references_key_is_still_compared_within_each_reference():
    """A filter A/B crossed with the bounces: the filter's points share a reference at each bounce count."""
    rows = [{"estimate.filter": f, "photons.max_bounces": b, "fps": fps, ERROR: e}
            for f, b, fps, e in (("mvoxel", 2, 20.0, 0.02), ("kvoxel", 2, 26.0, 0.03),
                                 ("mvoxel", 8, 18.0, 0.024), ("kvoxel", 8, 25.0, 0.036))]
    sw = _sweep({"estimate.filter": ["mvoxel", "kvoxel"], "photons.max_bounces": [2, 8]}, rows,
                ["r2", "r2", "r8", "r8"])
    quality = error_factor(Inputs([], sweeps=[sw]))
    assert "In sw, no image error is compared across photons.max_bounces" in quality, quality
    assert "In sw, estimate.filter moves the image error most: 1.50x" in quality, quality
    one = _sweep({"estimate.filter": ["mvoxel", "kvoxel"]}, [r for r in rows if r["photons.max_bounces"] == 2],
                 ["r2", "r2"])  # (one reference: ranked as before)
    (text,) = sweep_findings(Inputs([], sweeps=[one]))
    assert "the point of the lowest image error (relative MSE 0.02) is estimate.filter = mvoxel" in text, text
    assert "not comparable" not in text and "not comparable" not in error_factor(Inputs([], sweeps=[one]))


def _point(i: int, fps: float) -> Run:
    return Run(Path(f"sw/points/{i}"), f"sw #{i}", "sweep-point", {"scene": {"name": "cornell"}, "fps": fps}, {})


def test_sweep_points_whose_rates_print_alike_are_told_apart_and_said_to_tie():
    text = fps_of_points(Inputs([], runs=[_point(0, 27.561), _point(1, 27.623)]))
    assert "27.6 FPS (sw #0) to 27.6 FPS" not in text, text
    assert "from 27.56 FPS (sw #0) to 27.62 FPS (sw #1), within 1% of each other (a tie" in text, text
    apart = fps_of_points(Inputs([], runs=[_point(0, 18.88), _point(1, 22.65)]))
    assert "from 18.9 FPS (sw #0) to 22.6 FPS (sw #1) (§4" in apart, apart  # (apart by more than 1%: no tie)


def test_a_point_that_reused_a_render_is_marked_in_the_points_table():
    rows = [{"point": i, "hash": f"h{i}", "status": "ok", "error": None, "seed": i, "fps": 27.6,
             "cycles.throughput": 2e7, "seconds.functional": s, "seconds.simulate": 0.02, "seconds.write": 0.002,
             "functional_cached": cached} for i, (s, cached) in enumerate(((0.63, False), (0.002, True)))]
    html = table(Sweep(Path("sw"), {"grid": {"seed": [0, 1]}}, rows, []))
    cells = [line for line in html.splitlines() if line.startswith("<tr><td>")]
    assert "<th>render</th><th>host s</th>" in html, html
    assert "<td>done</td><td>0.6520</td>" in cells[0] and "<td>reused</td><td>0.0240</td>" in cells[1], cells
    assert "render reused: the point took its frame from the functional cache" in html, html
    alone = table(Sweep(Path("sw"), {"grid": {"seed": [0, 1]}}, [{**rows[0], "point": 1, "hash": "h1"}, rows[0]], []))
    assert "render" not in alone  # (no point reused one: no column)


def test_the_speed_up_is_measured_against_the_smallest_n_swept():
    idle = {f"idle.{pm}": 0.1 for pm in ("vertex", "traversal", "intersection", "fragment")}
    rows = [{"point": i, "hash": f"h{i}", "status": "ok", "scene": "cornell", "mode": "rcast", "arch.pipelines": n,
             "arch.scheduler": "static", "cycles.throughput": t, **idle}
            for i, (n, t) in enumerate(((4, 8_000_000), (8, 5_000_000)))]
    groups = idle_points(Sweep(Path("sw"), {"grid": {"arch.pipelines": [4, 8]}}, rows, []), [])
    (g,) = groups.values()
    html = idle_table("t", g["pms"], g["points"])
    assert "<th>speed-up over N = 4</th>" in html, html
    assert "<td>1.000</td>" in html and "<td>1.600</td>" in html, html


def test_a_point_of_other_code_names_the_code_before_the_grid_change(tmp_path):
    from tlm.experiments.sweep_folder import _why

    folder = tmp_path / "points" / "old"
    folder.mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps({"code_fingerprint": "aaaa"}))
    then = {"base": "cornell", "set": {}, "grid": {"arch.pipelines": [4]}, "zip": {}}
    now = SimpleNamespace(to_dict=lambda: {**then, "grid": {"arch.pipelines": [4, 8]}, "points": []},
                          path=tmp_path / "s.yaml")
    said = _why(then, now, [folder], "bbbb")
    assert said.index("run by other tlm code") < said.index("grid's arch.pipelines"), said
    assert said == ("a point of the folder's earlier sweep (its sweep.yaml before this one's), run by other tlm code "
                    "(code_fingerprint aaaa in their results.json, this tlm's bbbb), which alone leaves it behind (a "
                    "point's hash holds the code's fingerprint); the sweep changed since too: grid's arch.pipelines "
                    "was [4], now [4, 8]"), said
