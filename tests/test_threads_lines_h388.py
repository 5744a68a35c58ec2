"""Two follow-ups of the Dask and ``--jobs`` oversubscription lines (h382, h385).

``tlm sweep`` says a Dask machine's ``render.threads`` line once per machine as it ends (``machine_lines``); the
points' warnings it folds after its summary (``print_point_warnings``) no longer say that machine again through a
point's line of another count there, or another worker's (``tlm.api.machine_key``: each machine once in all). And
the local ``--jobs`` x ``render.threads`` line (``sweep_jobs_line``) says nothing for a count of 1, whose advice to
leave the count null would change nothing (a null gets 1 thread there too, as ``dask_oversubscribed`` leaves it)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
import yaml

from tlm import api, storage
from tlm.cli_tables import print_point_warnings
from tlm.config import config_from_dict, to_dict
from tlm.experiments import dask_workers, sweep_point
from tlm.experiments.run_warnings import sweep_jobs_line
from tlm.experiments.sweep_file import Point
from tlm.kernels import threads


def _at_once(t: int, host: str, n: int, cpus: int = 8) -> str:
    return (f"render.threads = {t} on host {host} with {n} points at once (the task slots of its Dask workers) "
            f"oversubscribes its {cpus} CPUs available ({t * n} kernel threads): they take turns on them")


def _alone(t: int, worker: str, host: str, cpus: int = 4) -> str:
    return (f"render.threads = {t} is more than the {cpus} CPUs available to this process (its affinity mask): "
            f"slower, not faster (on the Dask worker {worker} (tcp://10.0.0.7:4000) on host {host})")


def _points(tmp_path: Path, warnings: list[list[str]]) -> list[dict]:
    rows = []
    for i, lines in enumerate(warnings):
        folder = tmp_path / "points" / f"h{i}"
        folder.mkdir(parents=True)
        (folder / "results.json").write_text(json.dumps({"warnings": lines}))
        rows.append({"point": i, "hash": f"h{i}", "status": "ok"})
    return rows


def test_the_key_of_a_machine_line_is_its_kind_and_host():
    assert api.machine_key(_at_once(2, "10.0.0.5", 8)) == ("at once", "10.0.0.5")
    assert api.machine_key(_alone(8, "w1 (x)", "node7")) == ("alone", "node7")
    assert api.machine_key("render.threads = 9 is more than the 8 CPUs available to this process (...)") is None
    assert api.machine_key("another warning") is None and api.machine_key(None) is None
    assert api.machine_key is dask_workers.machine_key


def test_a_machine_the_sweep_said_is_not_said_again_after_its_summary(tmp_path, capsys, monkeypatch):
    """Host a: two counts (2 and 4 threads); node7: two workers. The sweep said one line of each (machine_lines);
    the old code then said "1 of 4 points: render.threads = 2 on host a ..." and the other worker's line too."""
    monkeypatch.setattr(storage, "SAID", set())
    lines = [[_at_once(2, "a", 8), "another warning"], [_at_once(4, "a", 8)],
             [_alone(8, "w1-0", "node7"), "another warning"], [_alone(6, "w1-1", "node7")]]
    said = dask_workers.machine_lines(w for point in lines for w in point)
    assert said == [_at_once(4, "a", 8), _alone(8, "w1-0", "node7")]
    print_point_warnings(_points(tmp_path, lines), tmp_path, said)
    assert capsys.readouterr().err == "tlm: warning: 2 of 4 points: another warning\n"


def test_a_machine_the_sweep_did_not_say_is_still_counted(tmp_path, capsys, monkeypatch):
    """(A resumed point's line of a machine none of this run's points ran on: the sweep did not say it.)"""
    monkeypatch.setattr(storage, "SAID", set())
    rows = _points(tmp_path, [[_at_once(4, "a", 8)], [_at_once(2, "b", 8)], [_alone(8, "w2", "node8")]])
    print_point_warnings(rows, tmp_path, [_at_once(4, "a", 8), _alone(8, "w1-0", "node7")])
    err = capsys.readouterr().err
    assert err.count("tlm: warning: 1 of 3 points: ") == 2, err
    assert "on host b with 8 points" in err and "on host node8)" in err and "on host a " not in err


def test_a_sweep_of_two_workers_on_one_machine_says_it_once_in_all(tmp_path, capsys, monkeypatch):
    """tlm sweep, two points, each as a remote Dask worker's of its own on one machine (its _threads_lines as a
    remote worker's, the points run in this process): the line is said once, at the sweep's end, not once more
    folded after the summary (the old code: twice, the other worker's as "1 of 2 points: ...")."""
    from tlm.cli import main

    monkeypatch.setattr(storage, "SAID", set())
    monkeypatch.setattr(threads, "available", lambda: 1)
    own = sweep_point._threads_lines

    def remote(task, cfg, _):
        where = f"the Dask worker w{task.config['seed']} (tcp://10.0.0.7:400{task.config['seed']}) on host node7"
        return own(dataclasses.replace(task, code="c0de"), cfg, where)

    monkeypatch.setattr(sweep_point, "_threads_lines", remote)
    base = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "threads": 2},
            "arch": {"trace": False}}
    path = tmp_path / "sw.yaml"
    path.write_text(yaml.safe_dump({"base": base, "grid": {"seed": [0, 1]}}, sort_keys=False))
    out = tmp_path / "o"
    assert main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-progress", "--no-report"]) == 0
    err = capsys.readouterr().err
    # (the sweep's own line as it starts, of this machine, is the local one: not a worker's)
    assert err.count("on host node7)\n") == 1 and " of 2 points: render.threads" not in err, err


def _point(i: int, count: int | None) -> Point:
    return Point(i, {}, to_dict(config_from_dict({"scene": "cornell", "render": {"threads": count}})), f"{i:016x}")


@pytest.mark.parametrize("workers, cpus", [(8, 2), (3, 2), (16, 4)])
def test_a_count_of_one_past_the_cpus_by_jobs_alone_says_nothing(workers, cpus):
    """--jobs past the CPUs with render.threads = 1: a null gets 1 thread there too (kernel_threads), so "leave
    render.threads null" would change nothing, and --jobs past the CPUs by itself is not said (old: the line)."""
    assert sweep_jobs_line([_point(0, 1)], workers, cpus=cpus) == []
    assert sweep_jobs_line([_point(0, 1), _point(1, None)], workers, cpus=cpus) == []


def test_a_count_of_two_is_still_said():
    (line,) = sweep_jobs_line([_point(0, 1), _point(1, 2)], 8, cpus=2)
    assert line.startswith("--jobs: 8 worker processes, each with render.threads = 2, run 16 kernel threads on the "
                           "2 CPUs"), line
    assert "lower --jobs, or leave render.threads null" in line
