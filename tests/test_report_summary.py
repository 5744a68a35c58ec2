"""The report's first screen (:mod:`tlm.report.summary`): each question answered in words
and one figure from what the inputs hold, or said to have no answer in them."""

from __future__ import annotations

from pathlib import Path

from tlm.report.collect import Inputs, Run, Study, Sweep
from tlm.report.summary import PMS, summary_section, sweep_findings

REPO = Path(__file__).resolve().parents[1]


def _run(scene: str, mode: str, fps: float, busy: dict[str, float] | None = None) -> Run:
    units = {f"pipe0.{pm}": {"fractions": {"busy": b}} for pm, b in (busy or {}).items()}
    return Run(Path(f"runs/{scene}-{mode}"), f"{scene}/{mode}", "run",
               {"scene": {"name": scene}, "mode": mode, "fps": fps, "timing": {"units": units}}, {})


def test_no_inputs_no_answers(tmp_path):
    sec = summary_section(Inputs([]), tmp_path)
    assert sec.figures == [] and sec.absent.startswith("the inputs hold no frame rates")
    for said in ("no frame rate to show", "no bottleneck to show", "no scaling to show", "no error to show"):
        assert said in sec.lead
    assert list(tmp_path.iterdir()) == []


def test_how_fast_and_what_limits_it(tmp_path):
    busy = dict(zip(PMS, (0.1, 0.9, 0.5, 0.2), strict=True))
    runs = [_run("cornell", "pmap", 0.5, busy), _run("ring", "rcast", 40.0, {**busy, "traversal": 0.6}),
            _run("room", "reflect", 0.0, {"vertex": 1.0})]  # no frame rate, not every PM: left out
    sec = summary_section(Inputs([], runs=runs), tmp_path)
    assert [f.file for f in sec.figures] == ["summary_fps.png", "summary_bottleneck.png"] and sec.absent is None
    assert sec.shown == 2 and all((tmp_path / f.file).stat().st_size > 1000 for f in sec.figures)
    assert "<b>How fast:</b> from 0.5 FPS (cornell PMap) to 40 FPS (ring RCast) at one pipeline." in sec.lead
    assert ("<b>What limits it:</b> the TTrav PM is the bottleneck in 2 of 2 scene-modes, busy 60–90% of the time."
            in sec.lead)
    assert "no scaling to show" in sec.lead and "no error to show" in sec.lead


def test_does_it_scale_and_what_quality_costs(tmp_path):
    scaling = Study("scaling", Path("sc"), [
        {"target": "throughput", "scheduler": "static", "scene": "ring", "pipelines": n, "simulated": s}
        for n, s in ((4, 40.0), (1, 100.0), (2, 50.0))] + [
        {"target": "throughput", "scheduler": "dynamic", "scene": "ring", "pipelines": 8, "simulated": 1.0}])
    cost = Study("error-vs-cost", Path("ec"), [
        {"filter": "knn", "rel_mse": 0.02, "frame_seconds": 0.5},
        {"filter": "knn", "rel_mse": 0.01, "frame_seconds": 2.0},
        {"filter": "cone", "rel_mse": 0.03, "frame_seconds": 0.25},
        {"filter": "cone", "rel_mse": None, "frame_seconds": 0.1}])
    sec = summary_section(Inputs([], studies=[scaling, cost]), tmp_path)
    assert [f.file for f in sec.figures] == ["summary_scaling.png", "summary_tradeoff.png"]
    assert "<b>Does it scale:</b> ring 2.5x at N = 4 (static tiles;" in sec.lead  # the dynamic row is not drawn
    assert ("<b>What quality costs:</b> the lowest error of a filter whose search is modelled is cone's, relative "
            "MSE 0.03 at 0.25 s a frame against our reference; the k-NN reference, not ranked as its frame time "
            "leaves out its search (not modelled): knn 0.01.") in sec.lead, sec.lead


def test_a_sweep_finding_names_the_factor_that_moves_the_frame_rate_most(tmp_path):
    rows = [{"status": "ok", "pipelines": p, "fifo": f, "fps": 10.0 * p + f}
            for p in (1, 4) for f in (2, 8)] + [{"status": "failed", "pipelines": 8, "fifo": 2, "fps": 1e9}]
    sweep = Sweep(Path("sweeps/pipes"), {"grid": {"pipelines": [1, 4, 8], "fifo": [2, 8]}}, rows, [])
    (text,) = sweep_findings(Inputs([], sweeps=[sweep]))
    # pipelines: means 15 (1) and 45 (4), 3.00x; fifo: means 27 (2) and 33 (8), 1.22x
    assert text == ("<b>Sweep pipes</b> (4 of 5 points ok): pipelines moves the frame rate most, 3.00x between its "
                    "best value (4) and its worst (1), averaged over the other factors; the best point is "
                    "pipelines = 4, fifo = 8 at 48 FPS.")
    sec = summary_section(Inputs([], sweeps=[sweep]), tmp_path)
    assert sec.lead.startswith(text + "<br>") and sec.absent is None and sec.figures == []
    assert sweep_findings(Inputs([], sweeps=[Sweep(Path("s"), {}, rows, [])])) == []  # no factors: no finding


def test_a_sweep_whose_factors_change_nothing_says_so(tmp_path):
    """A tie everywhere names no best value and no best point ('best static, worst static')."""
    rows = [{"status": "ok", "arch.scheduler": s, "fps": 414.0} for s in ("static", "dynamic")]
    sweep = Sweep(Path("sw"), {"grid": {"arch.scheduler": ["static", "dynamic"]}}, rows, [])
    (text,) = sweep_findings(Inputs([], sweeps=[sweep]))
    assert text == "<b>Sweep sw</b> (2 of 2 points ok): no factor changes the frame rate: every point runs at 414 FPS."


def test_granularity_and_extreme_studies_are_answered(tmp_path):
    from tlm.report.summary import study_findings

    gran = Study("granularity", Path("g"), [
        {"packet_size": 1, "simulate_seconds": 2.0, "max_abs_rel_error": 0.0},
        {"packet_size": 64, "simulate_seconds": 0.1, "max_abs_rel_error": 0.004},
        {"packet_size": 4096, "simulate_seconds": 0.01, "max_abs_rel_error": 0.2}])
    ext = Study("extreme", Path("x"), [{"case": "a", "passed": True}, {"case": "b", "passed": False}])
    found = study_findings(Inputs([], studies=[gran, ext]))
    assert found == ["<b>Granularity g:</b> packets of 64 stay within 1% of the cycles of packets of 1 (error 0.40%), "
                     "in 0.1 s of simulation against 2 s.",
                     "<b>Extreme cases x:</b> 1 of 2 as expected; <strong>not as expected: b</strong> (§8)."]
    sec = summary_section(Inputs([], studies=[gran, ext]), tmp_path)
    assert sec.lead.startswith(found[0]) and sec.absent is None
    far = Study("granularity", Path("f"), [{**r, "max_abs_rel_error": r["max_abs_rel_error"] * 10} for r in gran.rows])
    assert study_findings(Inputs([], studies=[far])) == [
        "<b>Granularity f:</b> every packet size above 1 is more than 1% off its cycles (the least, 4.00%)."]


def test_a_folder_given_twice_is_read_once(tmp_path, cache):
    from tlm.cli import main

    out = tmp_path / "r"
    assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--out", str(out), "--mode", "rcast",
                 "--set", "resolution=[8,8]",
                 "--set", "render.spp=1", "--outputs", "images", "--no-report", "--no-progress"]) == 0
    assert main(["report", str(out), str(tmp_path / "." / "r"), "--out", str(tmp_path / "rep")]) == 0
    assert f"Inputs: {out}: 1 run, 0 sweeps" in (tmp_path / "rep" / "report.html").read_text()
