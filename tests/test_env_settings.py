"""The environment variables a run reads (``TLM_KERNELS``, ``TLM_FORK_WORKERS``): a value
they do not take is bad input, refused in one line naming the variable, exit status 2, no
traceback file and nothing written; it was an internal error (``TLM_KERNELS``) or silently
taken as off (``TLM_FORK_WORKERS``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tlm.cli import main
from tlm.errors import InputError
from tlm.kernels import engine, threads

from .scenes import sphere_scene

ROOT = Path(__file__).resolve().parents[1]


def _config(tmp_path, threads_: int = 1) -> str:
    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(json.dumps({"scene": "furnace.yaml", "mode": "rcast", "resolution": [8, 8],
                               "render": {"threads": threads_}}))
    return str(cfg)


def _run(tmp_path, cfg: str) -> int:
    return main(["run", cfg, "--out", str(tmp_path / "out"), "--no-progress", "--no-report", "--outputs", "images"])


def test_an_unknown_engine_is_bad_input_through_python_m_tlm(tmp_path):
    """``TLM_KERNELS=foo python -m tlm run ...``: one line, exit 2, no traceback file saved."""
    cfg = _config(tmp_path)
    env = {**os.environ, "TLM_KERNELS": "foo", "TLM_CACHE": str(tmp_path / "cache")}
    done = subprocess.run([sys.executable, "-m", "tlm", "run", cfg, "--out", str(tmp_path / "out"), "--no-progress",
                           "--no-report"], capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip() == ("tlm: error: environment: TLM_KERNELS: 'foo' is not an engine: expected numba or "
                                   "numpy (unset or empty: numba where it imports, else numpy)")
    assert not (tmp_path / "cache" / "tracebacks").exists() and not (tmp_path / "out").exists()


@pytest.mark.parametrize("value", ["yes", "true", "2", "on", " 1x"])
@pytest.mark.parametrize("n_threads", [1, 2])
def test_a_fork_workers_value_other_than_0_or_1_is_bad_input(tmp_path, cache, capsys, monkeypatch, value, n_threads):
    """``TLM_FORK_WORKERS=yes`` was taken as off without a word; it is refused, at one thread
    (where the variable is not read) as at two."""
    monkeypatch.setenv("TLM_FORK_WORKERS", value)
    assert _run(tmp_path, _config(tmp_path, n_threads)) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"tlm: error: environment: TLM_FORK_WORKERS: {value!r} is not 0 or 1 (1: forked worker "
                   "processes; 0: threads; empty or unset: forked worker processes past 8 threads)")
    assert not (cache / "tracebacks").exists() and not (tmp_path / "out").exists()


@pytest.mark.parametrize("value", [None, "", "0", "1"])
def test_fork_workers_takes_0_1_empty_and_unset(monkeypatch, value):
    if value is None:
        monkeypatch.delenv("TLM_FORK_WORKERS", raising=False)
    else:
        monkeypatch.setenv("TLM_FORK_WORKERS", value)
    assert threads.fork_workers() is {None: None, "": None, "0": False, "1": True}[value]
    with threads.using(2) as n:
        assert n == 2
        if value != "1":
            assert not threads.can_fork()  # (unset or empty: threads up to DEFAULT_MAX_THREADS)


def test_an_unknown_engine_is_an_input_error_naming_the_variable(monkeypatch):
    monkeypatch.setenv("TLM_KERNELS", "cuda")
    with pytest.raises(InputError, match=r"^environment: TLM_KERNELS: 'cuda' is not an engine: expected numba or "):
        engine.engine()
    for ok in ("", "numpy", " NumPy "):
        monkeypatch.setenv("TLM_KERNELS", ok)
        assert engine.engine() in engine.ENGINES



@pytest.mark.parametrize(("var", "value"), [("TLM_KERNELS", "foo"), ("TLM_FORK_WORKERS", "yes")])
def test_a_sweep_refuses_a_bad_setting_once_before_any_point(tmp_path, cache, capsys, monkeypatch, var, value):
    """A sweep failed every point with the setting's line and exited 1; it is refused once,
    exit 2, with nothing written."""
    sweep = tmp_path / "s.yaml"
    sweep.write_text("base: {scene: cornell, mode: rcast, resolution: [8, 8]}\ngrid: {seed: [1, 2]}\n")
    monkeypatch.setenv(var, value)
    from tlm.cli import main

    assert main(["sweep", str(sweep), "--out", str(tmp_path / "sw"), "--jobs", "1", "--no-progress",
                 "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"tlm: error: environment: {var}: {value!r} is not")
    assert not (tmp_path / "sw").exists()
