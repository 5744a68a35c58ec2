"""h367: benchmarks/bench_tlm.py --run-on, the static run-on rule's cost against the same settings with it off."""

from __future__ import annotations

from pathlib import Path


def test_run_on_case_times_a_setting_that_runs_on_and_one_that_does_not(monkeypatch, capsys):
    """Cornell PMap 16x16 (4000 photons), static tiles, two images, 5 frames asked: 3 pipelines run on to 16
    frames and are also simulated with arch.settle_frames 1 (the 5 asked) and at 16 frames asked with it off;
    4 pipelines repeat from the first steady gap and run the 5 asked. The rows and the verdict on the set are
    checked, not the seconds (the bar's PASS/FAIL is the machine's)."""
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_tlm
    import timing

    monkeypatch.setattr(timing, "_FAILED", [])
    settings = (("pmap16", {"pipelines": 3}, True), ("pmap16", {"pipelines": 4}, False))
    three, four = bench_tlm.run_on_case(settings, repeat=1)
    out = capsys.readouterr().out
    assert (three["asked"], three["run"], three["runs_on"]) == (5, 16, True)
    assert three["rule_s"] > 0 and three["off_s"] > 0 and three["off_at_run_s"] > 0
    assert (four["asked"], four["run"], four["runs_on"], four["off_at_run_s"]) == (5, 5, False, None)
    assert "PASS: the set's settings run on, or not, as listed" in out
    assert "pmap16 pipelines=3" in out and "16 frames run for 5 asked" in out
    assert "the rule's own cost: the run-on settings" in out and "bar: at most 1.10x each" in out


def test_run_on_case_fails_where_a_setting_no_longer_runs_on_as_listed(monkeypatch, capsys):
    """A setting listed as running on that runs the frames asked is a FAIL naming it (the set needs new
    settings), and a set with none that runs on measures nothing of the rule: FAIL too."""
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_tlm
    import timing

    monkeypatch.setattr(timing, "_FAILED", [])
    bench_tlm.run_on_case((("pmap16", {"pipelines": 4}, True),), repeat=1)
    out = capsys.readouterr().out
    assert "FAIL: these settings no longer run on as listed, pick new ones: pmap16 pipelines=4" in out
    assert "FAIL: no setting of the set ran on" in out
    assert len(timing._FAILED) == 2
