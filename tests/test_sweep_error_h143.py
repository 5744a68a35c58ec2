"""A sweep's photon-map error, and the words of --set in sweeps and the thesis study (a probe's findings).

* A PMap sweep's image error was dropped without a word: a sweep computes no reference (``reference.auto``
  is ``tlm run``'s), and the functional cache froze the error measured when the frame was rendered, so a
  reference computed later (``tlm reference``) never reached a sweep of the cached frames. The cache now
  keeps the photon-map frame's image and measures it when the frame is read, against the reference cached
  then (as ``tlm run`` of the point's config would); the sweep says, once, how many points have no error
  and the ``tlm reference`` command (with the ``--set``) that computes their reference, and a rerun into
  the folder measures them from their cached frames.
* A point's bad value that a factor gave was named "FILE, with --set (point ...)"; a --set scene not
  found was named "FILE (point 0)".
* ``sweep.csv``'s ``scene`` of a ``--set scene`` was its path from the sweep file's folder (a built-in
  sweep's: from the package), not the path as given.
* ``tlm thesis --set reference.auto=false`` warned in each of the cells without the photon-map pass, and
  the cells' ``overrides`` mixed the study's own ``scene=``/``mode=`` with the user's ``--set``.
"""

from __future__ import annotations

import json
import os
import shutil

import numpy as np
import pytest
import yaml

from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.experiments import frames, run
from tlm.experiments.reference_cache import cache_dir as reference_dir
from tlm.experiments.reference_cache import save_reference
from tlm.experiments.sweep import run_sweep
from tlm.experiments.sweep_file import load_sweep

PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [12, 8], "photons": {"count": 3000},
        "render": {"light_samples": 1}, "estimate": {"final_gather": 0},
        "arch": {"frames": 1, "trace": False, "packet_size": 32}}
META = {"rounds": 12, "cycles": 3, "relative_standard_error": 0.01, "converged": True}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _store(key: str, pixels: int, seed: int = 1) -> np.ndarray:
    """A reference of ``key`` in the cache (made up: its numbers only have to be the ones read back)."""
    image = np.random.default_rng(seed).random((8, pixels // 8, 3)).astype(np.float32)
    save_reference(key, image, dict(META))
    return image


def _fresh_error(cfg) -> dict:
    """The error ``tlm run`` of ``cfg`` measures (the frame rendered now, the reference cached now)."""
    res = run.render(cfg)
    return run.photon_error(res.frame, res.radiance["pmap"].reshape(-1, 3))


def test_a_cached_frame_is_measured_against_a_reference_cached_after_it():
    cfg = config_from_dict(PMAP, "test")
    first = frames.cached_render(cfg)
    assert not first.cached and first.summary["error"]["available"] is False
    _store(first.summary["error"]["reference"], 12 * 8)
    again = frames.cached_render(cfg)
    assert again.cached  # (the cached frame stays valid: nothing rendered again)
    assert again.summary["error"]["available"] is True  # (was: False, frozen in the cached summary)
    assert again.summary["error"] == _fresh_error(cfg)


def test_a_config_of_other_reference_settings_sharing_the_frame_is_measured_against_its_own_reference():
    cfg = config_from_dict(PMAP, "test")
    first = frames.cached_render(cfg)
    other = config_from_dict({**PMAP, "reference": {"k_nearest": 40, "tolerance": 0.5}}, "test")
    fresh = _fresh_error(other)  # (its reference's key, not cached: unavailable)
    assert fresh["reference"] != first.summary["error"]["reference"]
    _store(fresh["reference"], 12 * 8, seed=2)
    got = frames.cached_render(other)
    assert got.cached and got.key == first.key  # (one frame: reference settings are not in its key)
    assert got.summary["error"] == _fresh_error(other)  # (was: the first config's reference key, unavailable)
    assert got.summary["error"]["reference_converged"] is True


def _sweep(tmp_path, base=None, grid=None) -> tuple:
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(base or PMAP))
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": "base.yaml", "set": {"seed": 0},
                                    "grid": grid or {"arch.pipelines": [1, 2]}}))
    return path, tmp_path / "o"


def test_a_sweep_says_its_points_without_error_and_a_rerun_measures_them(tmp_path, elsewhere):
    path, out = _sweep(tmp_path)
    first = run_sweep(path, out, jobs=1, overrides=["resolution=[12, 8]"])
    assert first.ok == 2 and all("error.rmse" not in r for r in first.rows)
    said = [w for w in first.warnings if "no photon-map error" in w]
    command = f"tlm reference {os.path.relpath(tmp_path / 'base.yaml')} --set 'resolution=[12, 8]'"
    assert said == [f"2 of 2 points have no photon-map error (error.rmse, error.rel_mse): no reference is cached for "
                    f"them, and a sweep computes none (reference.auto is 'tlm run''s); {command} computes this "
                    f"reference, and the sweep run again into {out} then measures them from their cached frames "
                    "('tlm sweep --reference' computes this reference before the points, and measures them)"]
    key = json.loads(next((out / "points").glob("*/results.json")).read_text())["error"]["reference"]
    _store(key, 12 * 8)
    again = run_sweep(path, out, jobs=1, overrides=["resolution=[12, 8]"])
    assert again.skipped == 0 and again.renders == 0  # (run again: their frames read from the cache)
    assert not [w for w in again.warnings if "no photon-map error" in w]
    cfg = config_from_dict({**PMAP, "seed": 0}, "test")
    assert all(r["error.rmse"] == _fresh_error(cfg)["rmse"] for r in again.rows)
    new = run_sweep(path, tmp_path / "new", jobs=1, overrides=["resolution=[12, 8]"])  # (a new folder: so too)
    assert new.renders == 0 and all(r["error.rmse"] == again.rows[0]["error.rmse"] for r in new.rows)


def test_a_point_s_bad_factor_value_is_named_by_the_sweep_file_not_the_set(tmp_path, elsewhere):
    path, _ = _sweep(tmp_path, grid={"cache.pairs": [1, 8]})
    with pytest.raises(InputError) as e:
        load_sweep(path, ["resolution=[12, 8]"])
    assert str(e.value).startswith(f"{path} (point 1: cache.pairs=8): cache.pairs: ")  # (was: "..., with --set")
    with pytest.raises(InputError) as e:
        load_sweep(path, ["cache.pairs=9"])  # (a --set of a factor's key: refused, as before)
    assert str(e.value).startswith(f"{path}: --set cache.pairs=9: cache.pairs is a factor of the sweep")


def test_a_set_scene_not_found_is_named_by_the_set(tmp_path, elsewhere):
    path, _ = _sweep(tmp_path)
    with pytest.raises(InputError) as e:
        load_sweep(path, ["scene=nonexist.yaml"])
    assert str(e.value).startswith(f"{path}, with --set: scene: scene file 'nonexist.yaml' not found")  # (was: point 0)


def test_sweep_csv_names_a_set_scene_as_given(tmp_path, elsewhere):
    sweep_dir = tmp_path / "sweeps"
    sweep_dir.mkdir()
    path, out = _sweep(sweep_dir, base={**PMAP, "mode": "rcast"})
    (elsewhere / "box.yaml").write_text("extends: cornell\nname: my box\n")
    done = run_sweep(path, out, jobs=1, overrides=["scene=box.yaml"])
    assert [r["scene"] for r in done.rows] == ["box.yaml", "box.yaml"]  # (was: ../work/box.yaml)
    assert "box.yaml,rcast" in (out / "sweep.csv").read_text()


def test_a_study_wide_set_that_some_cells_never_read_is_said_once(tmp_path, elsewhere, capsys):
    from tlm.experiments.thesis import run_thesis

    study = tmp_path / "th.yaml"
    study.write_text(yaml.safe_dump({"scenes": ["cornell"], "modes": ["rcast", "pmap"],
                                     "base": {k: v for k, v in PMAP.items() if k not in ("scene", "mode")}}))
    out = tmp_path / "th"
    done = run_thesis(study, out, overrides=("reference.auto=false",))
    line = ("--set reference.auto=false changes nothing in 1 of 2 cells (mode rcast of every scene): the photon-map "
            "pass is left out (its mode does not include the pmap (photon-map) pass)")
    assert capsys.readouterr().err.count("reference.auto=false") == 1
    assert done["summary"]["warnings"] == [line]
    for mode in ("rcast", "pmap"):
        results = json.loads((out / "cornell" / mode / "results.json").read_text())
        assert results["overrides"] == ["reference.auto=false"]  # (was: with scene=cornell, mode=...)
        assert not [w for w in results["warnings"] if "reference.auto" in w]  # (was: the rcast cell's line)
    assert json.loads((out / "thesis_summary.json").read_text())["warnings"] == [line]


def test_a_run_still_says_its_own_unread_set(tmp_path, elsewhere):
    cfg = config_from_dict({**PMAP, "mode": "rcast", "reference": {"auto": False}}, "test")
    res = run.render(cfg, overrides=("reference.auto=false",))
    said = run.results_dict(res, 1.0, "c.yaml")["warnings"]
    assert [w for w in said if w.startswith("--set reference.auto=false has no effect in this run")]
    assert not [w for w in run.results_dict(res, 1.0, "c.yaml", say_unread=False)["warnings"] if "reference.auto" in w]


# --- a review's findings (h145): a reference computed again under its key, a race on the frame's image, the
# line's grammar, and the command of a sweep whose base is a mapping


def test_a_rerun_measures_again_a_point_measured_against_a_reference_computed_again_since(tmp_path, elsewhere):
    path, out = _sweep(tmp_path)
    first = run_sweep(path, out, jobs=1)
    key = json.loads(next((out / "points").glob("*/results.json")).read_text())["error"]["reference"]
    _store(key, 12 * 8, seed=1)
    measured = run_sweep(path, out, jobs=1)
    assert first.renders == 1 and measured.renders == 0 and measured.skipped == 0
    was = measured.rows[0]["error.rmse"]
    assert was is not None and run_sweep(path, out, jobs=1).skipped == 2  # (the same reference: done)
    _store(key, 12 * 8, seed=2)  # (computed again under its key: tlm reference --set reference.max_rounds=16 --force)
    again = run_sweep(path, out, jobs=1)
    assert again.skipped == 0 and again.renders == 0  # (was: both skipped, the error of the reference replaced)
    cfg = config_from_dict({**PMAP, "seed": 0}, "test")
    now = _fresh_error(cfg)["rmse"]
    assert now != was and all(r["error.rmse"] == now for r in again.rows)
    assert run_sweep(path, tmp_path / "new", jobs=1).rows[0]["error.rmse"] == now  # (as a fresh folder gives)
    for results in (out / "points").glob("*/results.json"):  # (a point of an older tlm: no digest recorded)
        held = json.loads(results.read_text())
        del held["error"]["reference_sha256"]
        results.write_text(json.dumps(held))
    assert run_sweep(path, out, jobs=1).skipped == 0
    assert run_sweep(path, out, jobs=1).skipped == 2
    shutil.rmtree(reference_dir() / key)  # (the cache cleared: nothing measures it now)
    kept = run_sweep(path, out, jobs=1)
    assert kept.skipped == 2 and all(r["error.rmse"] == now for r in kept.rows)


def _entry_changed(monkeypatch, change) -> None:
    """``change(image file)`` called just after the functional cache entry was read and checked (another
    process at work on the entry between that check and the image's load)."""
    load = frames._load_entry

    def load_then_change(path, side, key):
        got = load(path, side, key)
        if got is not None:
            change(path.with_suffix(".pmap.npy"))
        return got

    monkeypatch.setattr(frames, "_load_entry", load_then_change)


def test_a_frame_s_image_removed_after_its_entry_was_read_renders_it_again(monkeypatch, capsys):
    cfg = config_from_dict(PMAP, "test")
    first = frames.cached_render(cfg)
    _store(first.summary["error"]["reference"], 12 * 8)
    _entry_changed(monkeypatch, lambda image: image.unlink())
    got = frames.cached_render(cfg)  # (was: FileNotFoundError from np.load)
    assert not got.cached and got.summary["error"] == _fresh_error(cfg)
    assert "damaged" not in capsys.readouterr().err  # (removed by another: not said here)


def test_a_frame_s_image_changed_after_its_entry_was_read_is_a_damaged_entry(monkeypatch, capsys):
    cfg = config_from_dict(PMAP, "test")
    first = frames.cached_render(cfg)
    _store(first.summary["error"]["reference"], 12 * 8)

    def overwrite(image):  # (the same size, other pixels)
        data = bytearray(image.read_bytes())
        data[-8:] = np.float64(7.0).tobytes()
        image.write_bytes(bytes(data))

    _entry_changed(monkeypatch, overwrite)
    got = frames.cached_render(cfg)
    assert not got.cached and got.summary["error"] == _fresh_error(cfg)  # (was: measured from the changed pixels)
    image = frames.cache_dir() / f"{first.key}.pmap.npy"
    assert (f"damaged functional cache entry {image} (its checksum differs from its sidecar's): removed, rendering it "
            "again") in " ".join(capsys.readouterr().err.split())


def test_the_line_on_one_point_without_error_says_it_in_the_singular(tmp_path, elsewhere):
    from tlm.experiments.sweep import unmeasured_line

    unmeasured = {"status": "ok", "results": {"error": {"reference": "r1", "available": False}}}
    measured = {"status": "ok", "results": {"error": {"reference": "r1", "available": True}}}
    path, out = _sweep(tmp_path, grid={"arch.pipelines": [1]})
    one = load_sweep(path)
    [line] = unmeasured_line(one, {one.points[0].hash: unmeasured}, out)
    assert line.startswith("the 1 point has no photon-map error (error.rmse, error.rel_mse): no reference is cached "
                           "for it, and")  # (was: 1 of 1 points have ... for them)
    assert line.endswith(f"the sweep run again into {out} then measures it from its cached frame ('tlm sweep "
                         "--reference' computes this reference before the points, and measures it)")
    path, out = _sweep(tmp_path, grid={"arch.pipelines": [1, 2, 4, 8]})
    four = load_sweep(path)
    records = {p.hash: unmeasured if p.index == 0 else measured for p in four.points}
    assert unmeasured_line(four, records, out)[0].startswith("1 of 4 points has no photon-map error")


def test_the_reference_command_of_a_sweep_with_an_inline_base_runs(tmp_path, elsewhere):
    from tlm.cli import main

    tiny = {**PMAP, "reference": {"photons": 1000, "min_rounds": 2, "max_rounds": 2}}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": tiny, "grid": {"arch.pipelines": [1, 2]}}))
    out = elsewhere / "o"
    first = run_sweep(path, out, jobs=1, overrides=["seed=3"])
    [line] = [w for w in first.warnings if "no photon-map error" in w]
    command = line.split("; ")[1].split(" computes this reference, ")[0]
    assert command.startswith("tlm reference o/points/") and command.endswith("/config.resolved.yaml")  # (was: CONFIG)
    assert main([*command.split()[1:], "--no-progress"]) == 1  # (computed and cached: not converged in 2 rounds)
    again = run_sweep(path, out, jobs=1, overrides=["seed=3"])
    assert again.skipped == 0 and again.renders == 0 and all(r["error.rmse"] is not None for r in again.rows)
    assert not [w for w in again.warnings if "no photon-map error" in w]
