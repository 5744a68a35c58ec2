"""``render.threads`` past the CPUs in a sweep (h276): ``tlm sweep`` says it once on stderr as it
starts (tlm.experiments.sweep.threads_line, run_warnings.threads_warning's line), where HEAD said
nothing (its points record it in their own results.json only, and points done before not again)."""

from __future__ import annotations

import yaml

from tlm.cli import main
from tlm.config import config_from_dict, to_dict
from tlm.experiments.sweep import threads_line
from tlm.experiments.sweep_file import Point


def _point(i: int, threads: int | None) -> Point:
    return Point(i, {}, to_dict(config_from_dict({"scene": "cornell", "render": {"threads": threads}})), f"{i:016x}")


def test_the_line_names_the_most_threads_a_point_asks_for_once():
    points = [_point(0, 2), _point(1, 6), _point(2, None), _point(3, 3)]
    (line,) = threads_line(points, "s.yaml", cpus=4)
    assert line.startswith("render.threads = 6 is more than the 4 CPUs available to this process")
    assert threads_line(points, "s.yaml", cpus=6) == []  # (no more than the CPUs: none)
    assert threads_line([_point(0, None)], "s.yaml", cpus=1) == []  # (null: the CPUs available)
    assert threads_line([], "s.yaml", cpus=1) == []


def test_a_sweep_whose_points_are_done_before_says_it_on_stderr(tmp_path, cache, monkeypatch, capsys):
    """The probe's case: the points done (render.threads is no part of a point's hash), a rerun
    with render.threads = 1,024 runs none, and HEAD said nothing of it."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.yaml").write_text(yaml.safe_dump({
        "base": {"scene": "cornell", "mode": "rcast", "resolution": [8, 8],
                 "render": {"light_samples": 1, "spp": 1}},
        "grid": {"arch.packet_size": [16, 256]}}))
    assert main(["sweep", "s.yaml", "--out", "o", "--no-progress", "--no-report"]) == 0
    assert "render.threads" not in capsys.readouterr().err
    assert main(["sweep", "s.yaml", "--out", "o", "--no-progress", "--no-report",
                 "--set", "render.threads=1024"]) == 0
    got = capsys.readouterr()
    said = [ln for ln in got.err.splitlines() if ln.startswith("tlm: warning: render.threads = 1024 is more than")]
    assert len(said) == 1, got.err
    assert "2 skipped (done before)" in got.out, got.out
