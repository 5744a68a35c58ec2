"""A sweep whose frames are all cached runs no kernel, and imports no numba for it (0.2 - 0.5 s of
CPU a sweep): its points record the engine the kernels would run (``versions()["kernels"]``) from
numba's metadata where numba is sure to import (:func:`tlm.experiments.provenance.kernels_here`),
and the one-off clock puts numba's listener on as numba's first import ends instead of importing
it (:mod:`tlm.experiments.error_cost_clock`). A module named numba that shadows the installed one
is imported to decide, as before: it fails, and the numpy kernels are recorded."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytest.importorskip("numba")

ROOT = Path(__file__).resolve().parents[1]
BASE = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1},
        "arch": {"trace": False}}
SWEEP = ("import sys\nfrom tlm.cli import main\n"
         "status = main(['sweep', sys.argv[1], '--out', sys.argv[2], '--jobs', '1', '--no-progress', '--no-report'])\n"
         "print('numba' in sys.modules)\nsys.exit(status)\n")


def _python(code: str, *args, env: dict, cwd: Path) -> str:
    done = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True, env=env,
                          cwd=cwd, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.split()[-1]


@pytest.mark.slow
def test_a_cached_sweep_imports_no_numba_and_records_the_engine_a_shadowed_numba_still_decides(tmp_path):
    sweep = tmp_path / "sw.yaml"
    sweep.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [4, 16]}}))
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TLM_CACHE": str(tmp_path / "cache"), "TLM_KERNELS": ""}
    assert _python(SWEEP, sweep, tmp_path / "first", env=env, cwd=tmp_path) == "True"  # (renders: numba ran)
    assert _python(SWEEP, sweep, tmp_path / "again", env=env, cwd=tmp_path) == "False"  # (all cached: none)
    for point in (tmp_path / "again" / "points").iterdir():
        v = json.loads((point / "results.json").read_text())["versions"]
        assert v["kernels"] == "numba", v  # (numba imports here: what engine() says, as the first sweep's points)
    first = {p.name: json.loads((p / "results.json").read_text())["versions"]
             for p in (tmp_path / "first" / "points").iterdir()}
    assert all(v["kernels"] == "numba" for v in first.values())
    # a module named numba first on the path (it raises ImportError): imported to decide, the numpy kernels
    shim = tmp_path / "nonumba" / "numba"
    shim.mkdir(parents=True)
    (shim / "__init__.py").write_text('raise ImportError("no numba")\n')
    shadowed = {**env, "PYTHONPATH": os.pathsep.join([str(tmp_path / "nonumba"), str(ROOT)])}
    code = "from tlm.experiments.provenance import versions\nprint(versions()['kernels'])\n"
    assert _python(code, env=shadowed, cwd=tmp_path) == "numpy"
    _python(SWEEP, sweep, tmp_path / "shadowed", env=shadowed, cwd=tmp_path)  # (the shim tried, failed: not kept)
    for point in (tmp_path / "shadowed" / "points").iterdir():
        assert json.loads((point / "results.json").read_text())["versions"]["kernels"] == "numpy"


@pytest.mark.slow
def test_the_one_off_clock_imports_no_numba_and_times_a_compile_after_numba_is_imported(tmp_path):
    """The clock imported numba to put its listener on (engine() == "numba"); now it puts it on as numba's
    first import ends while it runs, and a compile after that is still timed."""
    script = ("import sys, time\nimport tlm.experiments.error_cost_clock as ecc\nclock = ecc.CompileClock()\n"
              "with clock.running():\n"
              "    before = 'numba' in sys.modules\n"
              "    from numba import njit\n"
              "    listening = ecc._LISTENER is not None\n"
              "    f = njit(lambda x: x + 1)\n"
              "    t0 = time.perf_counter()\n"
              "    import numba.core.event  # (imported already: no first import, the compile alone is timed)\n"
              "    f(1)\n"
              "    t1 = time.perf_counter()\n"
              "print(before, listening, clock.within(t0, t1) > 0.5 * (t1 - t0))\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TLM_KERNELS": "", "NUMBA_CACHE_DIR": str(tmp_path / "nb")}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, cwd=tmp_path,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["False", "True", "True"]
