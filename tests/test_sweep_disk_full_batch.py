"""A full disk at one point of a batch: the points of the same batch that finished are counted in the stop line
(they were written as rows but said undone)."""

from __future__ import annotations

import yaml

import tlm.experiments.sweep as sweep_mod
from tlm.cli import main
from tlm.errors import EnvironmentFailure
from tlm.experiments.sweep_point import error_record

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 1, "images_in_flight": 1, "trace": False, "packet_size": 16}}


def test_points_done_beside_a_full_disk_are_counted(tmp_path, monkeypatch, capsys, cache):
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [1, 16, 256]}}, sort_keys=False))
    out = tmp_path / "o"
    calls, real_point, real_take, held = [], sweep_mod.run_point, sweep_mod.take_finished, []

    def point(task):
        calls.append(task.hash)
        if len(calls) == 2:
            full = EnvironmentFailure("cannot write: no space left on device", source=task.out)
            return {"status": "failed", "error": error_record(full, "write", ""), "worker": None}
        return real_point(task)

    def take(finished, timeout=None):  # (the full disk's point and the next, done, taken in one batch)
        got = held + real_take(finished, timeout)
        held.clear()
        if len(calls) == 2:
            held.extend(got)
            return []
        return got

    monkeypatch.setattr(sweep_mod, "run_point", point)
    monkeypatch.setattr(sweep_mod, "take_finished", take)
    assert main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-progress", "--no-report"]) == 1
    err = capsys.readouterr().err
    rows = (out / "sweep.jsonl").read_text().splitlines()
    print(err, len(rows))
    assert f"stopped with {len(rows)} of 3 points done" in err, (err, rows)
