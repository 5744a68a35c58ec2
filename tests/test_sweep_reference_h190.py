"""``tlm sweep --reference`` holds the references it computed (or chose) for its points.

It computed a reference its cache could not take (read-only, full, ``references/<key>`` a file), said it was
kept in ``<tmp>/tlm-cache-<uid>``, and then measured no point (``error.available: false``): the points read the
cache only. A ``tlm cache prune``/``clear`` between the reference phase and the points cost them their error
too. The sweep now holds a copy of each reference its points are measured against in its output folder for its
duration (``.references``), which the points read first. And two equal references computed at once: the second
said the cache "keeps its reference, not the one computed now" and left a copy in the temporary folder; an equal
one is dropped, and the line says it is the same.

A review (h199) of those copies: their folder ``.held.tmp-<pid>`` carried no host and was not noted as in use, so a
sweep on another machine sharing the folder, or a second sweep in this process, removed it as a killed sweep's; a
killed sweep's copies stayed until a later ``--reference`` sweep with points to run; every reference image stayed
in the sweep's memory for its duration, those whose points were all done too; an interrupt while the copies were
written left them; and where a reference kept nowhere could not be held, the warning said the points read it from
the cache, which had none.
"""

from __future__ import annotations

import gc
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import weakref

import numpy as np
import pytest
import yaml

from tlm import storage
from tlm.errors import EnvironmentFailure
from tlm.experiments import reference_cache, sweep_point
from tlm.experiments import sweep as sweep_module
from tlm.experiments.reference_cache import ReferenceSettings, kept_root, store_reference
from tlm.experiments.reference_cache import cache_dir as reference_dir
from tlm.experiments.sweep import run_sweep

REFERENCE = {"photons": 1500, "k_nearest": 20, "min_rounds": 4, "max_rounds": 4, "spp": 2}
PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "photons": {"count": 1500},
        "render": {"light_samples": 1}, "estimate": {"final_gather": 0},
        "arch": {"frames": 1, "trace": False, "packet_size": 32}, "reference": REFERENCE}


@pytest.fixture
def own_tmp(tmp_path, monkeypatch):
    """The temporary folder (kept_root's parent) of the test's own."""
    folder = tmp_path / "tmp"
    folder.mkdir(mode=0o700)
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


def _sweep(tmp_path, grid=None):
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(PMAP))
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": "base.yaml", "grid": grid or {"estimate.filter": ["disk", "mvoxel"]}}))
    return path, tmp_path / "s-out"


TWO_KEYS = {"photons.max_bounces": [2, 3]}  # (two references: max_bounces is a key a reference's key reads)


def _errors(out, done) -> list[dict]:
    return [json.loads((out / "points" / r["hash"] / "results.json").read_text())["error"] for r in done.rows]


@pytest.mark.parametrize("kept", [True, False])
def test_a_reference_the_cache_cannot_take_still_measures_the_points(tmp_path, monkeypatch, elsewhere, own_tmp, kept):
    blocker = tmp_path / "afile"  # (TLM_CACHE a file: no cache folder can be made)
    blocker.write_text("x\n")
    monkeypatch.setenv("TLM_CACHE", str(blocker))
    if not kept:  # (the temporary folder cannot take it either: kept nowhere but by the sweep)
        shutil.rmtree(own_tmp)
        own_tmp.write_text("x\n")
    path, out = _sweep(tmp_path)
    lines: list[str] = []
    warned: list[str] = []
    done = run_sweep(path, out, jobs=1, reference=True, say=lines.append, warn=warned.append)
    assert done.ok == 2
    errors = _errors(out, done)
    assert all(e["available"] is True for e in errors)  # (was: False, no point measured)
    assert not any("have no photon-map error" in w for w in warned)
    key = errors[0]["reference"]
    if kept:
        meta = json.loads((kept_root() / "references" / key / "meta.json").read_text())
        assert {e["reference_sha256"] for e in errors} == {meta["npy"]["sha256"]}
        assert any(ln.startswith(f"reference {key}: NOT converged") and ln.endswith(key) for ln in lines)
    else:
        assert any(ln.endswith("kept nowhere but for this sweep") for ln in lines)
    assert not (out / ".references").exists()  # (the sweep's own copies: gone with the sweep)


def test_a_prune_while_the_sweep_runs_costs_no_point_its_error(tmp_path, monkeypatch, cache, elsewhere):
    real = sweep_point.cached_render

    def pruned(*args, **kwargs):  # ('tlm cache prune --max-size 0' or 'tlm cache clear' just before the point)
        shutil.rmtree(reference_dir(), ignore_errors=True)
        return real(*args, **kwargs)

    monkeypatch.setattr(sweep_point, "cached_render", pruned)
    path, out = _sweep(tmp_path)
    warned: list[str] = []
    done = run_sweep(path, out, jobs=1, reference=True, warn=warned.append)
    assert done.ok == 2
    errors = _errors(out, done)
    assert all(e["available"] is True for e in errors)  # (was: False, "a line above says why", none did)
    assert len({e["reference_sha256"] for e in errors}) == 1 and errors[0]["reference_sha256"]
    assert not any("have no photon-map error" in w for w in warned)
    assert not (out / ".references").exists()
    assert not reference_dir().exists()  # (pruned: the points read the sweep's own copy)


def test_an_equal_reference_computed_at_once_is_dropped_and_said_the_same(tmp_path, cache, own_tmp):
    settings = ReferenceSettings(photons=100, tolerance=0.02, min_rounds=4, max_rounds=8, spp=4)
    image = np.random.default_rng(0).random((4, 5, 3))
    meta = {"rounds": 8, "relative_standard_error": 0.17, "cycles": 2, "rounds_per_cycle": 4,
            "standard_error_per_cycle": [0.17], "tolerance": 0.02, "min_rounds": 4, "max_rounds": 8, "spp": 4,
            "converged": False}
    first = store_reference("k" * 20, image, meta, settings)
    assert first.replaced
    second = store_reference("k" * 20, image, dict(meta, host_seconds=1.5), settings)  # (the other sweep's)
    assert not second.replaced
    assert "kept in" not in second.line  # (was: "the one computed now is kept in <tmp>/tlm-cache-<uid>/...")
    assert not os.path.exists(kept_root())
    assert "the same reference as the one computed now" in second.line and "dropped" in second.line
    assert second.same
    assert second.meta["npy"] == first.meta["npy"]


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_the_held_copies_carry_host_pid_and_writer_and_no_other_sweep_removes_them(tmp_path, monkeypatch, cache,
                                                                                     elsewhere):
    real = sweep_point.cached_render
    seen: list[str] = []

    def others_clean_then_prune(*args, **kwargs):
        parent = tmp_path / "s-out" / ".references"
        seen.extend(d.name for d in parent.iterdir())
        with monkeypatch.context() as m:  # (a sweep on another machine sharing the folder: our pid is not its)
            m.setattr(storage, "_host", lambda: "hElsewhereBox")
            m.setattr(storage, "pid_alive", lambda pid: False)
            storage.clean_stale(parent, "held")
        storage.clean_stale(parent, "held")  # (a second sweep in this process into the folder: API, threads)
        shutil.rmtree(reference_dir(), ignore_errors=True)  # ('tlm cache prune' meanwhile)
        return real(*args, **kwargs)

    monkeypatch.setattr(sweep_point, "cached_render", others_clean_then_prune)
    path, out = _sweep(tmp_path)
    done = run_sweep(path, out, jobs=1, reference=True)
    assert all(e["available"] is True for e in _errors(out, done))  # (was: False, the copy removed, the cache pruned)
    assert seen and all(re.fullmatch(rf"\.held\.tmp-{storage.process_tag()}-\d+", n) for n in seen)  # (was: tmp-<pid>)
    assert not (out / ".references").exists()
    from tlm.experiments.sweep_reference import drop_references, held_root

    a, b = held_root(out), held_root(out)  # (two sweeps of one process into one folder: two names, both in use)
    assert a != b and a.parent == b.parent == out.absolute() / ".references"
    a.mkdir(parents=True)
    b.mkdir()
    storage.clean_stale(a.parent, "held")
    assert a.is_dir() and b.is_dir()
    drop_references(a)
    assert not a.exists() and b.is_dir()
    drop_references(b)
    assert not a.parent.exists()


def test_a_killed_sweeps_held_copies_go_with_the_next_sweep_into_the_folder(tmp_path, cache, elsewhere):
    path, out = _sweep(tmp_path)
    run_sweep(path, out, jobs=1)
    host, dead = storage.process_tag().rsplit("-", 1)[0], _dead_pid()
    left = [f".held.tmp-{host}-{dead}-3", f".held.tmp-{dead}"]  # (killed sweeps': this machine's, an older name)
    for name in left:
        (out / ".references" / name / ("k" * 20)).mkdir(parents=True)
        (out / ".references" / name / ("k" * 20) / "reference.npy").write_bytes(b"x" * 1000)
    done = run_sweep(path, out, jobs=1)  # (no --reference, and no point to run)
    assert done.skipped == 2
    assert not (out / ".references").exists()  # (was: left for ever)
    kept = [f".held.tmp-hElsewhereBox-{dead}-0", f".held.tmp-{host}-{os.getppid()}-0"]  # (another machine's, a live
    for name in [*kept, *left]:  # process's)
        (out / ".references" / name).mkdir(parents=True)
    run_sweep(path, out, jobs=1)
    assert sorted(d.name for d in (out / ".references").iterdir()) == sorted(kept)


def test_no_reference_image_stays_in_the_sweeps_memory_while_its_points_run(tmp_path, monkeypatch, cache,
                                                                             elsewhere):
    path, out = _sweep(tmp_path, TWO_KEYS)
    first = run_sweep(path, out, jobs=1, reference=True)
    assert first.ok == 2 and not any(e["reference_converged"] for e in _errors(out, first))  # (so both are held
    redo = first.rows[1]["hash"]  # again below: "again", measured against one that misses its tolerance)
    keys = {r["hash"]: e["reference"] for r, e in zip(first.rows, _errors(out, first), strict=True)}
    assert len(set(keys.values())) == 2
    shutil.rmtree(out / "points" / redo)  # (one point to run; the other's reference: its points all done)
    images: list[weakref.ref] = []
    real_refs, real_render = sweep_module.sweep_references, sweep_point.cached_render

    def phase(*args, **kwargs):
        lines = real_refs(*args, **kwargs)
        hold = args[4]
        images.extend(weakref.ref(h[0] if isinstance(h, tuple) else h.image) for h in hold.values())
        return lines

    during: list[tuple[int, set[str]]] = []

    def point(*args, **kwargs):
        gc.collect()
        during.append((sum(r() is not None for r in images), set(reference_cache._HELD.get() or {})))
        return real_render(*args, **kwargs)

    monkeypatch.setattr(sweep_module, "sweep_references", phase)
    monkeypatch.setattr(sweep_point, "cached_render", point)
    done = run_sweep(path, out, jobs=1, reference=True)
    assert done.ok == 1 and done.skipped == 1
    assert len(images) == 2  # (both were read for the phase)
    assert during == [(0, {keys[redo]})]  # (was: both images alive, both held)


def test_an_interrupt_while_the_copies_are_written_leaves_none(tmp_path, monkeypatch, cache, elsewhere):
    real = reference_cache.save_reference
    written: list[str] = []

    def cut(key, image, meta, root=None, private=True):
        if root is not None and ".references" in str(root) and written:
            raise KeyboardInterrupt
        folder = real(key, image, meta, root, private)
        if root is not None and ".references" in str(root):
            written.append(key)
        return folder

    monkeypatch.setattr(reference_cache, "save_reference", cut)
    path, out = _sweep(tmp_path, TWO_KEYS)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(path, out, jobs=1, reference=True)
    assert written
    assert not (out / ".references").exists()  # (was: the first copy left, its removal not registered yet)


def test_a_reference_kept_nowhere_that_cannot_be_held_says_its_points_run_without_their_error(
        tmp_path, monkeypatch, elsewhere, own_tmp):
    blocker = tmp_path / "afile"
    blocker.write_text("x\n")
    monkeypatch.setenv("TLM_CACHE", str(blocker))
    shutil.rmtree(own_tmp)
    own_tmp.write_text("x\n")
    real = reference_cache.save_reference

    def full(key, image, meta, root=None, private=True):
        if root is not None and ".references" in str(root):
            raise EnvironmentFailure("cannot write: no space left on device", source=str(root))
        return real(key, image, meta, root, private)

    monkeypatch.setattr(reference_cache, "save_reference", full)
    path, out = _sweep(tmp_path)
    warned: list[str] = []
    done = run_sweep(path, out, jobs=1, reference=True, warn=warned.append)
    assert all(e["available"] is False for e in _errors(out, done))
    line = next(w for w in warned if w.startswith("sweep --reference: cannot hold a copy"))
    assert "from the cache" not in line  # (was: "they read it from the cache", which had none)
    assert line.endswith("it is kept nowhere else: they run without the photon-map error")
