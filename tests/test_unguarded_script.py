"""A script that calls ``tlm.sweep`` at import, not under ``if __name__ == "__main__":``.

Each of a local pool's worker processes (forkserver, spawn; Dask's too) runs the main script
again as it starts. There the sweep asked for another pool: Python refused it, each worker
printed the RuntimeError's traceback (300 to 430 lines for two points), the script ran six times,
and the sweep returned every point failed (``WorkerDied``) with exit status 0. Now the sweep
raises one InputError naming the script and the guard (``tlm sweep``: exit status 2), before it
writes anything, and the worker ends at once, quietly.

Each test is a fresh Python running a small script (the fork server is one per process).
"""

from __future__ import annotations

import importlib.util
import multiprocessing
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.slow  # (a fresh Python each, and its worker processes)

GUARD = 'under `if __name__ == "__main__":`'

API = """
import sys
with open({log!r}, "a") as f:
    f.write(__name__ + "\\n")
import tlm
try:
    tlm.sweep({sweep!r}, {out!r}, jobs=2, dask={dask!r}, progress=False)
except tlm.InputError as e:
    sys.exit(f"InputError: {{e}}")
"""

CLI = """
import sys
with open({log!r}, "a") as f:
    f.write(__name__ + "\\n")
from tlm.cli import main
sys.exit(main(["sweep", {sweep!r}, "--out", {out!r}, "--jobs", "2", "--no-progress", "--no-report"]))
"""

# the sweep's process does not check before it starts the pool (as where the script's first sweep
# passed the check and a later one asks again): the workers' exit status alone says why they died
UNCHECKED = """
import sys
from tlm.experiments import executors
if __name__ == "__main__":
    executors._check_guarded = lambda context: None
""" + API

PRELOAD = """
import multiprocessing, sys


def modules(names):
    return [n in sys.modules for n in names]


if __name__ == "__main__":
    multiprocessing.set_forkserver_preload(["colorsys"])
    from tlm.experiments.executors import LocalPool

    pool = LocalPool(1)
    f = pool.submit(modules, ["colorsys", "tlm.experiments.run"])
    pool.run_next()
    print(f.result(timeout=60), pool.context.get_start_method())
    pool.shutdown()
    from multiprocessing import forkserver

    print(forkserver._forkserver._preload_modules)
"""


def run_script(tmp_path: Path, text: str, **fields) -> tuple[subprocess.CompletedProcess, Path, list[str]]:
    """Run the script ``text`` (its fields: ``log``, ``sweep``, ``out`` and ``fields``) in a fresh
    Python; its result, its ``--out`` and the ``__name__`` of each run of the script."""
    sweep = tmp_path / "sw.yaml"
    base = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"spp": 1, "light_samples": 1}}
    sweep.write_text(yaml.safe_dump({"base": base, "grid": {"arch.pipelines": [1, 2]}}))
    out, log = tmp_path / "out", tmp_path / "runs.log"
    script = tmp_path / "study.py"
    script.write_text(text.format(log=str(log), sweep=str(sweep), out=str(out), **fields))
    env = {**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(tmp_path / "cache")}
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=300)
    runs = log.read_text().split() if log.exists() else []
    return proc, out, runs


def one_line(err: str, script: Path) -> str:
    lines = err.splitlines()
    assert len(lines) == 1, err[-3000:]
    assert f"{script}: the script starts a sweep as it is imported" in lines[0] and GUARD in lines[0], lines[0]
    return lines[0]


DASK = [None, pytest.param("local", marks=pytest.mark.skipif(importlib.util.find_spec("distributed") is None,
                                                             reason="no distributed"))]


@pytest.mark.parametrize("dask", DASK, ids=["local-pool", "dask-local"])
def test_a_script_that_sweeps_at_import_gets_one_error_and_writes_nothing(tmp_path, dask):
    proc, out, runs = run_script(tmp_path, API, dask=dask)
    line = one_line(proc.stderr, tmp_path / "study.py")
    assert line.startswith("InputError: ") and proc.returncode == 1, proc.stderr
    assert runs.count("__main__") == 1 and set(runs) <= {"__main__", "__mp_main__"}, runs  # (the script ran once)
    assert not out.exists()  # (refused before the sweep claimed its folder)


def test_tlm_sweep_started_at_import_exits_2_with_one_line(tmp_path):
    proc, out, runs = run_script(tmp_path, CLI)
    line = one_line(proc.stderr, tmp_path / "study.py")
    assert line.startswith("tlm: error: ") and proc.returncode == 2, proc.stderr
    assert runs.count("__main__") == 1, runs
    assert not out.exists()


def test_workers_that_end_as_they_start_the_script_are_one_error_too(tmp_path):
    """The pool's own workers end with the distinct exit status: the sweep's first break
    raises the same error (the points were not run, so no row of theirs is written)."""
    proc, out, runs = run_script(tmp_path, UNCHECKED, dask=None)
    line = one_line(proc.stderr, tmp_path / "study.py")
    assert line.startswith("InputError: ") and proc.returncode == 1, proc.stderr
    assert runs.count("__main__") == 1, runs
    jsonl = out / "sweep.jsonl"
    assert not jsonl.exists() or jsonl.read_text() == ""
    assert not list(out.glob("points/*"))


@pytest.mark.skipif("forkserver" not in multiprocessing.get_all_start_methods(), reason="no forkserver")
def test_a_local_pool_keeps_the_host_programs_forkserver_preload(tmp_path):
    """The host's list stays its own (tlm's replaced it: ``['colorsys']`` became tlm's two
    modules), and the fork server tlm started imports both the host's modules and tlm's."""
    proc, _, _ = run_script(tmp_path, PRELOAD)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == ["[True, True] forkserver", "['colorsys']"], proc.stdout


# a script whose in-process sweep (jobs=1) runs at import, then a pool of its own (guarded): each
# of its own processes runs the script again, and the sweep with it, as before; only tlm's own
# processes leave as they start (a reviewer: they all left, and the host's pool broke)
OWN_POOL = """
import multiprocessing, sys
from concurrent.futures import ProcessPoolExecutor
with open({log!r}, "a") as f:
    f.write(__name__ + "\\n")
import tlm
rows = tlm.sweep({sweep!r}, {out!r}, jobs=1, progress=False)


def square(x):
    return x * x


if __name__ == "__main__":
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as ex:
        print(list(ex.map(square, [1, 2])), list(rows["status"]))
"""


def test_a_pool_of_the_host_s_own_runs_the_script_as_before(tmp_path):
    proc, out, runs = run_script(tmp_path, OWN_POOL)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.splitlines() == ["[1, 4] ['ok', 'ok']"], proc.stdout
    assert runs.count("__main__") == 1 and runs.count("__mp_main__") >= 1, runs
    assert (out / "sweep.csv").is_file()
