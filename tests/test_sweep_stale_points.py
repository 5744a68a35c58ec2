"""A rerun into a sweep's folder after a code edit: the point folders of the old code are counted.

Any edit under ``tlm/`` changes every point's hash (the code's fingerprint is in the key), so
a rerun computes every point again and the old point folders stay in ``points/``. The sweep
said "0 skipped (done before)" and nothing of the folders it left; now it says on stderr, before
its summary line, how many folders in ``points/`` are not this sweep's and what they are, and
its :class:`~tlm.experiments.sweep.Outcome` counts them. Here the edit is a changed fingerprint.
"""

from __future__ import annotations

import pytest
import yaml

import tlm.experiments.sweep_file as sweep_file_mod
from tlm.cli import main
from tlm.experiments.sweep import run_sweep

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1},
        "arch": {"frames": 1, "trace": False, "packet_size": 32}}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def test_a_rerun_after_a_code_edit_says_how_many_old_point_folders_stay(tmp_path, monkeypatch, capsys):
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.page_miss_cycles": [0, 12]}}))
    out = tmp_path / "o"
    monkeypatch.setattr(sweep_file_mod, "code_fingerprint", lambda: "0" * 16)
    first = run_sweep(path, out, jobs=1)
    assert (first.ok, first.skipped, first.other_folders) == (2, 0, 0)
    assert "not this sweep's" not in capsys.readouterr().err
    again = run_sweep(path, out, jobs=1)  # the same code: nothing to say
    assert (again.ok, again.skipped, again.other_folders) == (0, 2, 0)
    assert "not this sweep's" not in capsys.readouterr().err

    monkeypatch.setattr(sweep_file_mod, "code_fingerprint", lambda: "1" * 16)  # an edit under tlm/
    (out / "points" / ".x.tmp-h1-999999").mkdir()  # (a writer's temporary folder: not a point's)
    assert main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-progress", "--no-report"]) == 0
    said = capsys.readouterr()
    line = (f"2 point folders in {out / 'points'} are not this sweep's: left by an earlier run into the folder of "
            "other tlm code, another config or a different --set (an edit under tlm/ or to an input file changes "
            "every point's hash); nothing reads them, and removing them changes no result (sweep.yaml lists this "
            "sweep's hashes)")
    assert f"tlm: warning: {line}\n" in said.err
    assert "2 points: 2 ok, 0 failed, 0 skipped (done before)" in said.out
    assert len([p for p in (out / "points").iterdir() if not p.name.startswith(".")]) == 4  # (nothing removed)
    last = run_sweep(path, out, jobs=1)
    assert (last.skipped, last.other_folders) == (2, 2) and last.warnings[-1] == line


def test_one_old_point_folder_is_said_in_the_singular(tmp_path, monkeypatch, capsys):
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.page_miss_cycles": [6]}}))
    out = tmp_path / "o"
    monkeypatch.setattr(sweep_file_mod, "code_fingerprint", lambda: "0" * 16)
    run_sweep(path, out, jobs=1)
    monkeypatch.setattr(sweep_file_mod, "code_fingerprint", lambda: "1" * 16)
    capsys.readouterr()
    done = run_sweep(path, out, jobs=1)
    assert done.other_folders == 1
    assert done.warnings[-1].startswith(f"1 point folder in {out / 'points'} is not this sweep's: ")
    assert "not this sweep's" not in capsys.readouterr().err  # (the library prints none: tlm sweep does)


def test_a_sweep_cut_short_removes_what_its_dead_workers_left_half_written(tmp_path, monkeypatch):
    """A sweep interrupted (or stopped by its cluster) while a worker killed mid-point had left a
    temporary point folder: the folder goes when the sweep ends, as after a whole run (a Dask
    worker killed as its cluster closed left one behind, which only the next sweep removed)."""
    import tlm.experiments.sweep as sweep_mod
    from tlm.storage import pid_alive

    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.page_miss_cycles": [0, 12]}}))
    out = tmp_path / "o"
    dead = next(p for p in range(999_999, 900_000, -1) if not pid_alive(p))
    left = out / "points" / f".{'a' * 16}.tmp-{dead}"  # (no host: this machine's, as older writers named it)

    def killed_mid_point(*_args, **_kwargs):
        left.mkdir()  # (a worker killed while it wrote a point)
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep_mod, "_dispatch", killed_mid_point)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(path, out, jobs=1)
    assert not left.exists()
