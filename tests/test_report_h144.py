"""The report says what ran and all it measured (probe h140's defects 2, 3, 6, 9 and 11):

- a sweep, study or run made with ``--set`` is captioned by what its points resolved to and the
  overrides, §9 lists each input's overrides, two error-vs-cost studies that differ only by
  ``--set`` are two series of the summary's figure, and its numbers name the input they are from;
- a sweep's points' image error (sweep.csv ``error.rel_mse``, ``error.rmse``) is a column of the
  points table and is counted by the summary's error sentence;
- "What quality costs" with one series ends with a full stop, not ``; .``;
- "What limits it" says the sweep points' bottleneck beside the runs' (and where it moves);
- a table column of measured numbers is written to one count of decimals (``102.0`` beside
  ``101.6``), and "Does it scale" marks an out-of-date eq. 5.2 fit as §3 does.
"""

from __future__ import annotations

from pathlib import Path

from tests.helpers_figures import capture
from tlm.report import summary as summary_mod
from tlm.report.collect import Inputs, Run, Study, Sweep
from tlm.report.provenance import provenance_section
from tlm.report.scaling import idle_table
from tlm.report.summary import PMS, summary_section
from tlm.report.sweep_lines import column_decimals
from tlm.report.sweeps import sweeps_section

SPEC = {"sweep": "scaling_cornell.yaml", "description": "pipelines x scheduler, cornell RCast (thesis Figs. 18-20)",
        "overrides": ["scene=cbox.yaml", "mode=pmap", "resolution=[32,32]"], "grid": {"cache.block_words": [256, 1024]}}


def _busy(top: str) -> dict:
    units = {f"pipe0.{pm}": {"fractions": {"busy": 0.9 if pm == top else 0.2}} for pm in PMS}
    return {"timing": {"units": units}}


def _point(i: int, n: int, top: str, rel_mse: float | None = None) -> tuple[dict, Run]:
    row = {"point": i, "hash": f"h{i}", "status": "ok", "error": None, "cache.block_words": 256 * n,
           "scene": "cbox.yaml", "mode": "pmap", "fps": 10.0 * n, "cycles.throughput": 1e6 / n, "cycles.vertex": 1,
           "cycles.traversal": 2, "cycles.intersection": 1, "cycles.fragment": 1, "seconds.functional": 1.0,
           "seconds.simulate": 0.1}
    if rel_mse is not None:
        row |= {"error.rel_mse": rel_mse, "error.rmse": rel_mse / 10}
    run = Run(Path(f"sw/points/h{i}"), f"sw #{i}", "sweep-point",
              {"scene": {"name": "cbox"}, "mode": "pmap", "fps": 10.0 * n, **_busy(top)}, {"scene": "cbox.yaml"},
              factors={"cache.block_words": 256 * n}, sweep_overrides=list(SPEC["overrides"]))
    return row, run


def _sweep(tops=("vertex", "vertex"), errors=(None, None)) -> Sweep:
    made = [_point(i, n, top, e) for i, (n, top, e) in enumerate(zip((1, 4), tops, errors, strict=True))]
    return Sweep(Path("runs/sw"), dict(SPEC), [r for r, _ in made], [run for _, run in made])


def test_a_sweep_made_with_set_is_captioned_by_what_its_points_ran(tmp_path):
    sw = _sweep()
    sec = sweeps_section(Inputs([], runs=list(sw.runs), sweeps=[sw]), tmp_path)
    said = "scene cbox.yaml, mode pmap, with --set scene=cbox.yaml, mode=pmap, resolution=[32,32]"
    assert said in sec.html  # (the description, which names cornell RCast, no longer stands alone)
    assert all(said in f.caption for f in sec.figures) and sec.figures
    assert "“pipelines x scheduler, cornell RCast (thesis Figs. 18-20)”" in sec.html
    found = summary_section(Inputs([], runs=list(sw.runs), sweeps=[sw]), tmp_path).lead
    assert "Sweep sw</b> (2 of 2 points ok, with --set scene=cbox.yaml, mode=pmap, resolution=[32,32])" in found


def test_provenance_lists_the_overrides_of_each_input(tmp_path):
    sw = _sweep()
    run = Run(Path("runs/base"), "base: cbox/pmap", "run",
              {"scene": {"name": "cbox"}, "overrides": ["arch.pipelines=2", "mode=pmap"]}, {})  # (mode=: --mode's)
    ev = Study("error-vs-cost", Path("runs/ev"), [], {"provenance": {"study": "ev.yaml",
                                                                     "overrides": ["arch.pipelines=2"]}})
    html = provenance_section(Inputs([], runs=[run, *sw.runs], sweeps=[sw], studies=[ev]), tmp_path).html
    assert "<th class=\"l\">--set</th>" in html and '<td class="l">arch.pipelines=2</td>' in html
    assert '<td class="l">scene=cbox.yaml, mode=pmap, resolution=[32,32]</td>' in html  # (a point: its sweep's)
    assert "sweep folder runs/sw: sweep file scaling_cornell.yaml, with --set scene=cbox.yaml" in html
    assert "study ev.yaml, with --set arch.pipelines=2," in html


def _evc(name: str, overrides: list[str], seconds: float) -> Study:
    rows = [{"filter": "mvoxel", "rel_mse": 0.01, "frame_seconds": seconds},
            {"filter": "mvoxel", "rel_mse": 0.02, "frame_seconds": seconds / 2}]
    return Study("error-vs-cost", Path(f"runs/{name}"), rows, {"provenance": {"overrides": overrides}})


def test_two_studies_apart_only_by_set_are_two_series_and_the_number_names_its_input(tmp_path, monkeypatch):
    figs = capture(monkeypatch, summary_mod)
    studies = [_evc("ev", ["resolution=[32,32]", "arch.pipelines=2"], 0.125), _evc("ev_p1", ["resolution=[32,32]"],
                                                                                     0.145)]
    lead = summary_section(Inputs([], studies=studies), tmp_path).lead
    (ax,) = figs[-1].axes
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["mvoxel (ev: --set arch.pipelines=2)",
                                                                   "mvoxel (ev_p1)"]
    assert ("the lowest error is mvoxel's (from ev, with --set resolution=[32,32], arch.pipelines=2), relative MSE "
            "0.01 at 0.125 s a frame against our reference; mvoxel (ev_p1) 0.01 at 0.145 s.") in lead


def test_one_series_ends_with_a_full_stop(tmp_path):
    lead = summary_section(Inputs([], studies=[_evc("ev", [], 0.125)]), tmp_path).lead
    assert "relative MSE 0.01 at 0.125 s a frame against our reference." in lead and "; ." not in lead


def test_the_sweep_points_image_error_is_shown(tmp_path):
    sw = _sweep(errors=(0.5560262, 0.0851))
    sec = sweeps_section(Inputs([], runs=list(sw.runs), sweeps=[sw]), tmp_path)
    assert "<th>relative MSE</th><th>RMSE</th>" in sec.html
    assert "<td>0.5560</td><td>0.05560</td>" in sec.html and "<td>0.0851</td><td>0.00851</td>" in sec.html
    lead = summary_section(Inputs([], runs=list(sw.runs), sweeps=[sw]), tmp_path).lead
    assert "no error to show" not in lead
    assert "2 sweep points of sw that measured their image error have a relative MSE of 0.0851–0.556" in lead


def test_the_bottleneck_across_the_sweep_points_is_said_beside_the_runs(tmp_path):
    run = Run(Path("runs/base"), "base: cbox/pmap", "run", {"scene": {"name": "cbox"}, "mode": "pmap", "fps": 2.0,
                                                            **_busy("fragment")}, {})
    sw = _sweep(tops=("vertex", "vertex"))
    lead = summary_section(Inputs([], runs=[run, *sw.runs], sweeps=[sw]), tmp_path).lead
    assert "the TFrag PM is the bottleneck in the only scene-mode" in lead
    assert "Across the sweeps' points (not drawn): sw: TVert in all 2 points, busy 90%." in lead
    moving = _sweep(tops=("traversal", "vertex"))
    lead = summary_section(Inputs([], runs=[run, *moving.runs], sweeps=[moving]), tmp_path).lead
    assert ("sw: the bottleneck moves across its 2 points: TTrav in 1 (busy 90%; first at cache.block_words = 256), "
            "TVert in 1 (busy 90%; first at cache.block_words = 1024)") in lead
    lead = summary_section(Inputs([], runs=list(moving.runs), sweeps=[moving]), tmp_path).lead  # (no run)
    assert "Within a sweep: sw: the bottleneck moves across its 2 points" in lead


def test_a_column_of_measured_numbers_keeps_one_count_of_decimals():
    assert column_decimals([101.96, 101.6, 64.27, 64.1]) == ["102.0", "101.6", "64.3", "64.1"]
    assert column_decimals([4.764, 0.1, 0.129, 0.0]) == ["4.764", "0.100", "0.129", "0"]
    assert column_decimals([0.2348, 1381.0, 34528.4]) == ["0.2348", "1381", "34528"]  # (too wide: 4 digits each)
    assert column_decimals([1, 16, None], str) == ["1", "16", "None"]  # (whole numbers as they are)
    assert column_decimals([340000, 1.2e6, 2e9]) == ["3.4e+05", "1.2e+06", "2e+09"]
    points = [{"pipelines": 1, "scheduler": "static", "throughput": 101.96e6, "speedup": 1.0,
               "idle": dict.fromkeys(PMS, 0.1)},
              {"pipelines": 2, "scheduler": "static", "throughput": 26.36e6, "speedup": 3.868,
               "idle": dict.fromkeys(PMS, 0.1)}]
    html = idle_table("t", list(PMS), points)
    assert "<td>102.0</td>" in html and "<td>26.36</td>" not in html and "<td>26.4</td>" in html


def test_does_it_scale_marks_an_out_of_date_fit(tmp_path, monkeypatch):
    import tlm.experiments.scaling as eq52

    rows = [{"target": "throughput", "scheduler": "static", "scene": "ring", "pipelines": n, "simulated": s}
            for n, s in ((1, 100.0), (4, 40.0))]
    study = Study("scaling", tmp_path / "eq", rows)
    monkeypatch.setattr(eq52, "out_of_date", lambda folder, meta: ["out of date: its sweep holds other points"])
    lead = summary_section(Inputs([], studies=[study]), tmp_path).lead
    assert "ring (out of date) 2.5x at N = 4" in lead and "Out of date: eq's sweep holds other points now" in lead


def test_a_column_s_smallest_number_keeps_three_significant_digits():
    from tlm.report.sweep_lines import column_decimals

    assert column_decimals([29.5, 0.6712, 4.016]) == ["29.500", "0.671", "4.016"]  # (was 0.67 beside 29.50)
    assert column_decimals([102.0, 101.6, 64.3]) == ["102.0", "101.6", "64.3"]
