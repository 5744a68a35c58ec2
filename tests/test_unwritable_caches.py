"""Caches tlm cannot write: where they are, one line that says so, and nothing lost.

A read-only install with a read-only home (a locked-down container, a batch node) made
every render fail with numba's "no locator available"; a cache that could not be written
was silent, and ``tlm reference`` threw the reference it had computed away. A path under a
regular file stands for a folder that cannot be made: it fails even for root, whom a
read-only mode does not stop.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np
import pytest
import yaml

from tlm import api, caches, storage
from tlm.experiments import reference_cache
from tlm.fingerprint import fingerprint
from tlm.scenes import meshes

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def blocked(tmp_path):
    """A folder that cannot be made: under a regular file."""
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    return afile / "cache"


def _lines(err: str, start: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith(f"tlm: warning: {start}")]


# ---------------------------------------------------------------- where the caches are


def test_the_cache_folder_is_tlm_cache_then_xdg_cache_home_then_home(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "own"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert caches.cache_root("tracebacks") == tmp_path / "own" / "tracebacks"
    monkeypatch.setenv("TLM_CACHE", "")  # (empty: unset)
    assert caches.cache_root("tracebacks") == tmp_path / "xdg" / "tlm" / "tracebacks"
    monkeypatch.delenv("TLM_CACHE")
    assert caches.cache_root("tracebacks") == tmp_path / "xdg" / "tlm" / "tracebacks"
    for ignored in ("", "relative/xdg"):  # (the XDG spec: a relative path is ignored)
        monkeypatch.setenv("XDG_CACHE_HOME", ignored)
        assert caches.cache_root("tracebacks") == tmp_path / "home" / ".cache" / "tlm" / "tracebacks"


# ---------------------------------------------------------------- one line, once


def test_a_cache_that_cannot_be_written_is_said_once_naming_it_why_and_the_cost(tmp_path, blocked, monkeypatch,
                                                                                 capsys):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "not" / "made" / "yet"))  # (writable: made on the first write)
    for kind in ("functional", "scenes", "references", "oracle"):
        caches.cache_root(kind)
    assert "cannot write" not in capsys.readouterr().err
    assert not (tmp_path / "not").exists()  # (looked at, nothing made)

    monkeypatch.setenv("TLM_CACHE", str(blocked))
    mesh = tmp_path / "box.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    first = meshes.load_mesh(mesh)
    second = meshes.load_mesh(mesh)  # (parsed again: nothing was kept)
    np.testing.assert_array_equal(first.triangles, second.triangles)
    caches.cache_root("scenes")
    err = capsys.readouterr().err
    said = _lines(err, "cannot write tlm's scene cache")
    assert said == [f"tlm: warning: cannot write tlm's scene cache {blocked / 'scenes'} ({blocked.parent} is a "
                    "file, not a folder): large meshes are parsed again on every load, and no scene's fingerprint is "
                    "remembered: each process (a finished sweep's rerun too) parses its mesh scenes again; set "
                    "TLM_CACHE to a writable folder"], err
    assert caches.cache_warnings()[-1] == said[0].removeprefix("tlm: warning: ")


def test_a_failed_write_into_a_cache_is_said_once(tmp_path, monkeypatch, capsys):
    """A cache the first look took for writable (a full disk, a quota): its first failed
    write says the line, the next ones nothing."""
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "c"))
    entry = caches.cache_root("functional") / "k.json"
    entry.parent.mkdir(parents=True)
    (entry.parent / f".{entry.name}.tmp{storage._host()}-{os.getpid()}").mkdir()  # (write_atomic cannot open it)
    for _ in range(2):
        with pytest.raises(OSError):
            storage.write_file(entry, "{}")
    said = _lines(capsys.readouterr().err, "cannot write tlm's functional cache")
    assert len(said) == 1 and "a frame not in it is rendered again" in said[0]


SWEEP = {"description": "two points of one frame", "base": {"scene": "cornell", "mode": "rcast",
                                                           "resolution": [8, 8], "render": {"spp": 1}},
         "grid": {"arch.pipelines": [1, 2]}}


def test_a_sweep_says_an_unwritable_functional_cache_once_and_each_point_records_it(tmp_path, blocked,
                                                                                   monkeypatch, capsys):
    monkeypatch.setenv("TLM_CACHE", str(blocked))
    path = tmp_path / "sw.yaml"
    path.write_text(yaml.safe_dump(SWEEP))
    done = api.run_sweep(path, tmp_path / "out", jobs=1)
    assert done.ok == 2 and done.renders == 2  # (each point rendered the frame: nothing was cached)
    said = _lines(capsys.readouterr().err, "cannot write tlm's functional cache")
    assert len(said) == 1, said
    line = said[0].removeprefix("tlm: warning: ")
    assert line in done.warnings
    for res in (tmp_path / "out" / "points").glob("*/results.json"):
        assert line in json.loads(res.read_text())["warnings"]


@pytest.mark.slow
def test_a_sweep_of_worker_processes_says_it_once(tmp_path, blocked):
    """Two worker processes each meet the cache: the sweep says it once, not once a worker."""
    path = tmp_path / "sw.yaml"
    path.write_text(yaml.safe_dump({**SWEEP, "grid": {"arch.pipelines": [1, 2], "arch.fifo_depth": [4, 8]}}))
    env = {**os.environ, "TLM_CACHE": str(blocked)}
    done = subprocess.run([sys.executable, "-m", "tlm", "sweep", str(path), "--out", str(tmp_path / "out"),
                           "--jobs", "2", "--no-progress", "--no-report"], capture_output=True, text=True,
                          env=env, cwd=tmp_path, timeout=300)
    assert done.returncode == 0, done.stderr
    assert len(_lines(done.stderr, "cannot write tlm's functional cache")) == 1, done.stderr
    assert "4 rendered" in done.stdout


# ---------------------------------------------------------------- the reference is kept


PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "render": {"spp": 1},
        "photons": {"count": 500}, "reference": {"photons": 500, "min_rounds": 2, "max_rounds": 2, "spp": 1}}


def test_tlm_reference_with_a_cache_it_cannot_write_keeps_the_reference(tmp_path, blocked, monkeypatch, capsys):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "ok"))
    cached = api.reference(PMAP)
    assert cached.computed and cached.folder.parent == tmp_path / "ok" / "references"
    capsys.readouterr()

    monkeypatch.setenv("TLM_CACHE", str(blocked))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    kept = tmp_path / "tmp" / f"tlm-cache-{os.getuid()}"  # (where the line says it is kept)
    made = api.reference(PMAP)  # (no exception: the rounds' result is not thrown away)
    same = {k: v for k, v in cached.meta.items() if k != "host_seconds"}
    assert made.computed and made.key == cached.key and {k: made.meta[k] for k in same} == same
    assert made.meta["converged"] is False  # (2 rounds: `tlm reference` exits 1, as with a writable cache)
    assert made.folder == kept / "references" / made.key
    np.testing.assert_array_equal(np.load(made.folder / "reference.npy"), np.load(cached.folder / "reference.npy"))
    err = capsys.readouterr().err
    said = _lines(err, f"reference {made.key}: not cached (")
    assert len(said) == 1 and said[0].endswith(f"kept in {made.folder} instead, which later runs read with "
                                               f"TLM_CACHE={kept}"), err
    assert f"{blocked.parent} is a file, not a folder" in said[0]
    assert len(_lines(err, "cannot write tlm's reference cache")) == 1  # (said at the start, before the rounds)

    monkeypatch.setenv("TLM_CACHE", str(kept))  # what the line says: later runs read it
    image, meta = reference_cache.load_reference(made.key)
    assert meta["rounds"] == made.meta["rounds"] and image.shape == (8, 8, 3)


def test_tlm_run_with_a_reference_cache_under_a_file_uses_its_reference_for_the_run(tmp_path, blocked, monkeypatch,
                                                                                    capsys):
    """The cache's folder under a file was refused as a bad ``--out`` (exit 2) once the
    reference had been computed."""
    monkeypatch.setenv("TLM_CACHE", str(blocked))
    lines = []
    results = api.run(PMAP, tmp_path / "run", outputs=(), say=lines.append)
    assert results["error"]["available"]
    assert any("not cached (" in line and line.endswith("used by this run only") for line in lines), lines


# ---------------------------------------------------------------- numba's compiled kernels

NUMBA = """import os
import numba.core.caching as caching

first = caching._CacheLocator.ensure_cache_path

def ensure(self):  # tlm's __pycache__ read-only, as in a read-only install (root is not stopped by a mode)
    if os.path.basename(self.get_cache_path()) == "__pycache__":
        raise PermissionError(13, "Permission denied", self.get_cache_path())
    return first(self)

caching._CacheLocator.ensure_cache_path = ensure
import tlm.kernels._jit_leaf  # (its 16 functions decorated: one line for all)
from tlm.kernels._jit_leaf import _mn
print(_mn(3.0, 2.0), type(_mn._cache).__name__)
"""


def _numba(tmp_path: Path, tlm_cache: Path) -> subprocess.CompletedProcess:
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(afile / "numba"), "XDG_CACHE_HOME": str(afile / "xdg"),
           "HOME": str(afile / "home"), "TLM_CACHE": str(tlm_cache)}
    env.pop("NUMBA_DISABLE_JIT", None)
    return subprocess.run([sys.executable, "-c", NUMBA], capture_output=True, text=True, env=env, cwd=REPO,
                          timeout=300)


def test_numba_with_no_folder_of_its_own_caches_under_tlm_s_cache(tmp_path):
    done = _numba(tmp_path, tmp_path / "tlm")
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["2.0", "FunctionCache"]
    assert "numba cannot write" not in done.stderr
    assert list((tmp_path / "tlm" / "numba").glob("*/_jit_leaf._mn-*.nbi"))


def test_numba_with_no_folder_at_all_compiles_without_a_cache_and_says_so_once(tmp_path):
    done = _numba(tmp_path, tmp_path / "afile" / "tlm")
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["2.0", "NullCache"]
    said = _lines(done.stderr, "numba cannot write its compiled kernels anywhere (")
    assert len(said) == 1, done.stderr  # (one line, for the dozens of functions decorated)
    assert str(tmp_path / "afile" / "tlm" / "numba") in said[0] and "__pycache__" in said[0]
    assert said[0].endswith("they are compiled again in each process; set NUMBA_CACHE_DIR to a writable folder")


RENDER = """import sys
import numpy as np
from tlm.experiments.run import render
from tlm.config import config_from_dict
res = render(config_from_dict({"scene": "cornell", "mode": "refract", "resolution": [16, 16],
                               "render": {"spp": 1, "light_samples": 1}}, "x.yaml"))
np.save(sys.argv[1], np.stack([res.radiance[n] for n in sorted(res.radiance)]))
"""


@pytest.mark.slow
def test_kernels_compiled_without_a_cache_render_the_same_image(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    patch = NUMBA.split("import tlm.kernels._jit")[0]
    env = {**os.environ, "TLM_CACHE": str(tmp_path / "c")}
    env.pop("NUMBA_DISABLE_JIT", None)
    subprocess.run([sys.executable, "-c", RENDER, str(tmp_path / "cached.npy")], env=env, cwd=REPO, check=True,
                   timeout=600)
    env.update(NUMBA_CACHE_DIR=str(afile / "n"), XDG_CACHE_HOME=str(afile / "x"), HOME=str(afile / "h"),
               TLM_CACHE=str(afile / "t"))
    done = subprocess.run([sys.executable, "-c", patch + RENDER, str(tmp_path / "uncached.npy")], env=env,
                          cwd=REPO, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert len(_lines(done.stderr, "numba cannot write")) == 1, done.stderr
    np.testing.assert_array_equal(np.load(tmp_path / "uncached.npy"), np.load(tmp_path / "cached.npy"))


# ---------------------------------------------------------------- one fingerprint, one licence


def test_the_fingerprint_of_a_wheel_s_layout_is_the_checkout_s(tmp_path):
    """The wheel puts the repository's scenes/ (and configs/) inside the package, as
    tlm/_scenes (tlm/_configs): the same code, the same fingerprint."""
    checkout = tmp_path / "checkout" / "tlm"
    shutil.copytree(REPO / "tlm", checkout, ignore=shutil.ignore_patterns("__pycache__", "_scenes", "_configs"))
    wheel = tmp_path / "wheel" / "tlm"
    shutil.copytree(checkout, wheel)
    shutil.copytree(REPO / "scenes", wheel / "_scenes", ignore=shutil.ignore_patterns("*.xz", "*.obj", "*.ply"))
    assert list((wheel / "_scenes").rglob("*.yaml"))
    assert fingerprint(wheel) == fingerprint(checkout)
    (wheel / "kernels" / "new.py").write_text("X = 1\n")  # (the code still counts)
    assert fingerprint(wheel) != fingerprint(checkout)


def test_the_licence_pyproject_names_ships_as_a_file():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    assert project["license"] == {"text": "MIT"}
    assert project["license-files"] == ["LICENSE", "scenes/meshes/COPYRIGHT-*.txt"]  # (the meshes' notices too)
    text = (REPO / "LICENSE").read_text()
    assert text.startswith("MIT License\n\nCopyright (c) 2026 the tlm developers\n")
    assert "Permission is hereby granted, free of charge" in text and 'THE SOFTWARE IS PROVIDED "AS IS"' in text
