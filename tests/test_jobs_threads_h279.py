"""--jobs x a given render.threads past the CPUs (h279's patch): tlm sweep says it once as it starts
(run_warnings.sweep_jobs_line), where da48cd3 said only a count past the CPUs by itself."""

from __future__ import annotations

from tlm.config import config_from_dict, to_dict
from tlm.experiments.run_warnings import sweep_jobs_line
from tlm.experiments.sweep_file import Point


def _point(i: int, threads: int | None) -> Point:
    return Point(i, {}, to_dict(config_from_dict({"scene": "cornell", "render": {"threads": threads}})), f"{i:016x}")


def test_workers_times_the_most_threads_past_the_cpus_is_said_once():
    points = [_point(0, 2), _point(1, None), _point(2, 1)]
    (line,) = sweep_jobs_line(points, 3, cpus=4)
    assert line.startswith("--jobs: 3 worker processes, each with render.threads = 2, run 6 kernel threads on the 4")
    assert sweep_jobs_line(points, 2, cpus=4) == []  # (4 threads on 4 CPUs)
    assert sweep_jobs_line(points, 1, cpus=1) == []  # (one worker: sweep_threads_line's case)
    assert sweep_jobs_line([_point(0, None)], 8, cpus=2) == []  # (null: the worker's share)
    assert sweep_jobs_line([_point(0, 8)], 2, cpus=4) == []  # (past the CPUs alone: sweep_threads_line says it)
