"""Review of 599fb0a (h266): the kernels' engine told from numba's metadata without importing it
(:func:`tlm.experiments.provenance.kernels_here`) said ``numba`` for a numba whose import fails, a wheel
with a compiled file deleted or a source tree whose extensions are not built, where the kernels ran numpy:
a rendered sweep point recorded ``numba``. Each installed file is now checked against the wheel's
``RECORD`` (no ``RECORD``: not sure, the import decides). The benchmark's fresh sweep that failed said
only its stderr (empty: a failed point says why on stdout). ``packaging``, imported for the check, is
declared."""

from __future__ import annotations

import importlib.metadata as md
import importlib.util
import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]


def _fake_numba(root: Path, *, record: bool, whole: bool) -> Path:
    """A distribution named numba under ``root``: ``numba/__init__.py`` imports ``numba._speedups`` (its
    compiled part's stand-in). ``record``: a wheel's ``dist-info`` whose ``RECORD`` lists both files with their
    sizes; else a source tree's ``egg-info`` (no ``RECORD``). ``whole``: ``_speedups`` there."""
    pkg = root / "numba"
    pkg.mkdir(parents=True)
    files = {"numba/__init__.py": "from numba import _speedups  # noqa\n", "numba/_speedups.py": "X = 1\n"}
    for name, text in files.items():
        (root / name).write_text(text)
    meta = "Metadata-Version: 2.1\nName: numba\nVersion: 0.68.1\nRequires-Python: >=3.10\n"
    if record:
        info = root / "numba-0.68.1.dist-info"
        info.mkdir()
        (info / "METADATA").write_text(meta)
        rows = [f"{name},sha256=x,{len(text.encode())}" for name, text in files.items()]
        (info / "RECORD").write_text("\n".join([*rows, "numba-0.68.1.dist-info/RECORD,,"]) + "\n")
    else:
        info = root / "numba.egg-info"
        info.mkdir()
        (info / "PKG-INFO").write_text(meta)
    if not whole:
        (pkg / "_speedups.py").unlink()
    return root


def _sound(monkeypatch, root: Path) -> bool:
    """``_numba_sound``'s answer (not remembered) with ``root`` first on the path, numba not imported."""
    from tlm.experiments.provenance import _numba_sound

    monkeypatch.syspath_prepend(str(root))
    monkeypatch.delitem(sys.modules, "numba", raising=False)  # (find_spec would answer the imported one's)
    importlib.invalidate_caches()
    assert importlib.util.find_spec("numba").origin == str(root / "numba" / "__init__.py")
    return _numba_sound.__wrapped__()


@pytest.mark.parametrize(("record", "whole", "sound"), [
    (True, True, True),  # (a wheel's files all there: sure, numba not imported)
    (True, False, False),  # (a file of the wheel deleted: its import fails)
    (False, True, False),  # (a source tree's egg-info: its extensions may not be built)
])
def test_numba_is_sure_to_import_only_where_its_wheels_files_are_all_there(tmp_path, monkeypatch, record, whole,
                                                                          sound):
    pytest.importorskip("packaging")
    try:
        llvmlite_record = md.distribution("llvmlite").read_text("RECORD")
    except md.PackageNotFoundError:
        llvmlite_record = None
    if sound and llvmlite_record is None:
        pytest.skip("llvmlite is not installed from a wheel here: never sure")
    assert _sound(monkeypatch, _fake_numba(tmp_path / "site", record=record, whole=whole)) is sound


def _python(code: str, *args, env: dict, cwd: Path) -> str:
    done = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True, env=env,
                          cwd=cwd, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.strip()


@pytest.mark.slow
def test_a_sweep_point_rendered_under_a_numba_that_does_not_import_records_the_numpy_kernels(tmp_path):
    site = _fake_numba(tmp_path / "site", record=True, whole=False)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), str(ROOT)]), "TLM_CACHE": str(tmp_path / "cache"),
           "TLM_KERNELS": ""}
    code = ("from tlm.experiments.provenance import versions\nfrom tlm.kernels.engine import engine\n"
            "print(versions()['kernels'], engine())\n")
    assert _python(code, env=env, cwd=tmp_path) == "numpy numpy"  # (it said numba numpy)
    sweep = tmp_path / "sw.yaml"
    sweep.write_text(yaml.safe_dump({"base": {"scene": "cornell", "mode": "rcast", "resolution": [8, 8],
                                              "render": {"spp": 1, "light_samples": 1}, "arch": {"trace": False}},
                                     "grid": {"arch.fifo_depth": [4, 16]}}))
    code = ("import sys\nfrom tlm.cli import main\n"
            "sys.exit(main(['sweep', sys.argv[1], '--out', sys.argv[2], '--jobs', '1', '--no-progress', "
            "'--no-report']))\n")
    _python(code, sweep, tmp_path / "out", env=env, cwd=tmp_path)
    got = [json.loads((p / "results.json").read_text()) for p in (tmp_path / "out" / "points").iterdir()]
    assert any(not r["functional"]["cached"] for r in got)  # (rendered here: with the numpy kernels)
    assert [r["versions"]["kernels"] for r in got] == ["numpy", "numpy"]


def test_the_benchmarks_failed_fresh_sweep_says_what_the_sweep_said_and_its_exit_status(tmp_path):
    spec = importlib.util.spec_from_file_location("bench_sweep_points_h266", ROOT / "benchmarks" /
                                                  "bench_sweep_points.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    fake = tmp_path / "tree"
    (fake / "tlm").mkdir(parents=True)
    (fake / "tlm" / "__init__.py").write_text("")
    (fake / "tlm" / "cli.py").write_text("def main(argv):\n    print('  point 1 (ab12) failed: boom')\n"
                                         "    return 1\n")  # (as a sweep with a failed point: stdout, exit 1)
    (tmp_path / "sw.yaml").write_text("{}\n")
    with pytest.raises(SystemExit) as e:
        bench._command(fake, tmp_path / "sw.yaml", tmp_path / "out")
    assert "(exit status 1)" in str(e.value) and "point 1 (ab12) failed: boom" in str(e.value)


def test_packaging_which_provenance_imports_is_a_declared_dependency():
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    assert any(d.split(">")[0].split("=")[0].split("<")[0].strip() == "packaging" for d in deps), deps
    assert "from packaging." in (ROOT / "tlm" / "experiments" / "provenance.py").read_text()
