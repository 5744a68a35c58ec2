"""h338: a sweep point's line on ``render.threads`` past the CPUs is its own process's, not replayed from the
frame cache; the report says which host (and Dask worker) ran a sweep's points, where host seconds are shown.

1. :func:`tlm.experiments.frames.cached_render` stored the ``threads_warning`` line in the cached frame's summary,
   although neither ``render.threads`` nor the machine's CPUs are in the frame's key, and
   :func:`tlm.experiments.sweep_point.run_point` copied it into every point of a later sweep of that frame: a sweep
   at ``render.threads=1`` said ``render.threads = 4 is more than the 2 CPUs``, one at 4 after one at null said
   nothing, and a cache shared by two machines gave the CPUs of whichever rendered the frame.
2. ``tlm report`` named no host or worker: host seconds of a mixed cluster could not be traced to a machine.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml

from tlm.config import config_from_dict
from tlm.experiments import frames, sweep_point
from tlm.experiments.sweep import run_sweep
from tlm.kernels import threads as kernel_threads
from tlm.report.collect import read
from tlm.report.provenance import provenance_section
from tlm.report.sweeps import sweeps_section

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False}}
LINE = "render.threads = 4 is more than the"


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py: a TLM_CACHE of the test's own, shared by its sweeps)
    return cache


def _cpus(monkeypatch, n: int) -> None:
    """This process (which runs a --jobs 1 sweep's points) sees ``n`` CPUs, as a machine of ``n`` would."""
    monkeypatch.setattr(kernel_threads, "available", lambda *a, **k: n)


def _sweep(tmp_path: Path, out: str, threads: int | None) -> list[dict]:
    """A two-point sweep of one frame into ``tmp_path/out`` (``--jobs 1``), ``--set render.threads=threads``;
    its points' results.json."""
    path = tmp_path / "sw.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [1, 16]}}))
    done = run_sweep(path, tmp_path / out, jobs=1, overrides=[] if threads is None else [f"render.threads={threads}"])
    assert (done.ok, done.failed) == (2, 0)
    return [json.loads((tmp_path / out / "points" / r["hash"] / "results.json").read_text()) for r in done.rows]


def _said(points: list[dict]) -> list[list[str]]:
    return [[w for w in p["warnings"] if w.startswith("render.threads")] for p in points]


def test_a_cached_frame_does_not_replay_the_threads_line_of_the_sweep_that_rendered_it(tmp_path, monkeypatch):
    _cpus(monkeypatch, 2)
    first = _sweep(tmp_path, "t4", 4)
    assert [len(s) for s in _said(first)] == [1, 1] and LINE in _said(first)[0][0]
    assert "2 CPUs" in _said(first)[0][0]
    again = _sweep(tmp_path, "t1", 1)  # (was: both points said render.threads = 4, the first sweep's)
    assert [p["functional"]["cached"] for p in again] == [True, True]
    assert _said(again) == [[], []]
    # the frame's record keeps no such line
    key = frames.render_key(config_from_dict(BASE), tmp_path)
    side = json.loads((frames.cache_dir() / f"{key}.json").read_text(encoding="utf-8"))
    assert not any(w.startswith("render.threads") for w in side["warnings"]), side["warnings"]


def test_a_point_of_a_cached_frame_says_its_own_threads_past_the_cpus(tmp_path, monkeypatch):
    """The frame rendered at null threads first: a sweep at 4 of its cached frame said nothing (the Dask case)."""
    _cpus(monkeypatch, 2)
    assert _said(_sweep(tmp_path, "null", None)) == [[], []]
    later = _sweep(tmp_path, "t4", 4)
    assert [p["functional"]["cached"] for p in later] == [True, True]
    assert [len(s) for s in _said(later)] == [1, 1] and "2 CPUs" in _said(later)[1][0]


def test_a_cache_shared_by_two_machines_gives_each_its_own_cpus(tmp_path, monkeypatch):
    _cpus(monkeypatch, 2)
    assert "2 CPUs" in _said(_sweep(tmp_path, "small", 4))[0][0]
    _cpus(monkeypatch, 8)  # (another machine, the same cache: 4 threads are no more than its 8 CPUs)
    assert _said(_sweep(tmp_path, "big", 4)) == [[], []]  # (was: the 2 CPUs of the machine that rendered it)
    _cpus(monkeypatch, 3)
    assert "3 CPUs" in _said(_sweep(tmp_path, "three", 4))[0][0]


def test_a_remote_dask_workers_threads_line_names_the_worker(monkeypatch):
    _cpus(monkeypatch, 2)
    config = {**BASE, "render": {**BASE["render"], "threads": 4}}
    task = sweep_point.Task("h", config, {}, ".", "sw.yaml", "/x", {}, code="c0de")
    where = "the Dask worker w7 (tcp://10.0.0.7:4000) on host node7"
    (line,) = sweep_point._threads_lines(task, config_from_dict(config), where)
    assert line.startswith(LINE) and line.endswith(f"(on {where})")
    local = sweep_point.Task("h", config, {}, ".", "sw.yaml", "/x", {})  # (the sweep's own line, said once)
    assert sweep_point._threads_lines(local, config_from_dict(config), None)[0].startswith(LINE)
    null = sweep_point.Task("h", BASE, {}, ".", "sw.yaml", "/x", {}, threads=8)  # (the worker's share: not asked)
    assert sweep_point._threads_lines(null, config_from_dict({**BASE, "render": {"threads": 8}}), where) == []


@pytest.fixture
def swept(tmp_path) -> Path:
    """A three-point sweep folder, run here (one host, no Dask worker)."""
    path = tmp_path / "sw.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [1, 16, 256]}}))
    assert run_sweep(path, tmp_path / "s", jobs=1).ok == 3
    return tmp_path / "s"


def _moved(folder: Path, point: int, worker: str | None, host: str) -> None:
    """Point ``point`` of the sweep in ``folder`` recorded as run by ``worker`` on ``host`` (its row, its
    results.json ``ran``), as a Dask worker of another machine would have."""
    rows = [json.loads(line) for line in (folder / "sweep.jsonl").read_text().splitlines()]
    for r in rows:
        if r["point"] == point:
            r.update(worker=worker, host=host)
            res = folder / "points" / r["hash"] / "results.json"
            res.write_text(json.dumps({**json.loads(res.read_text()), "ran": {"worker": worker, "host": host,
                                                                               "pid": r["pid"]}}))
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))


def test_the_report_says_once_which_host_ran_a_sweep(swept, tmp_path):
    import socket

    host = socket.gethostname()
    inputs = read([swept])
    sec = sweeps_section(inputs, tmp_path)
    assert f"All 3 points ran on host {host}." in sec.html  # (was: no host anywhere)
    assert "<th>ran on</th>" not in sec.html  # (one machine: no column)
    prov = provenance_section(inputs, tmp_path)
    assert f"all 3 points ran on host {host}</p>" in prov.html
    assert "ran on</th>" not in prov.html


def test_the_report_gives_a_column_where_more_than_one_host_or_worker_ran_the_points(swept, tmp_path):
    import socket

    host = socket.gethostname()
    mixed = tmp_path / "mixed"
    shutil.copytree(swept, mixed)
    _moved(mixed, 2, "w7", "node7")
    inputs = read([mixed])
    sec = sweeps_section(inputs, tmp_path)
    assert "<th>host s</th><th>ran on</th>" in sec.html
    assert "<td>w7 on node7</td></tr>" in sec.html and f"<td>{host}</td></tr>" in sec.html
    said = (f"The 3 points ran on 1 Dask worker and local processes on 2 hosts: {host} (2 points) and w7 on node7 "
            "(1 point)")
    assert said in sec.html
    prov = provenance_section(inputs, tmp_path)
    assert '<th class="l">ran on</th>' in prov.html and '<td class="l">w7 on node7</td>' in prov.html
    assert said[0].lower() + said[1:] in prov.html
