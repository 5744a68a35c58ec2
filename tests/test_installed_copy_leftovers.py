"""Leftovers of the installed-copy work: ``tlm error-vs-cost`` with a references cache it
cannot write keeps the reference as ``tlm reference`` does and goes on (it computed the
reference, then stopped with exit 1 before); its ground-truth line says when the truth is not
cached; the Python API's studies take a built-in experiment's name as their commands do (they
took a path only); ``tlm.scenes.loader.load_scene`` takes a :class:`~pathlib.Path` (an
``AttributeError`` before)."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import pytest

import tlm
from tlm import api
from tlm.cli import main
from tlm.errors import InputError
from tlm.scenes import loader

from .scenes import sphere_scene

# a reference of two rounds that meets its (loose) tolerance: the study's cheapest
REFERENCE = {"photons": 800, "k_nearest": 20, "tolerance": 0.9, "min_rounds": 2, "max_rounds": 2, "spp": 1}
KEPT = "not cached ("  # how the line on a reference the cache could not take starts, after its key


def _study(tmp_path: Path) -> Path:
    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({
        "base": {"scene": "furnace.yaml", "resolution": [8, 8], "photons": {"count": 800},
                 "reference": REFERENCE, "estimate": {"final_gather": 0}},
        "points": [{"estimate.filter": ["disk"]}],
    }))
    return exp


def _blocked_cache(tmp_path: Path, monkeypatch) -> Path:
    """``TLM_CACHE`` under a regular file (unwritable, even for root); the temporary folder
    (where a reference the cache cannot take is kept) the test's own."""
    afile = tmp_path / "afile"
    afile.write_text("")
    monkeypatch.setenv("TLM_CACHE", str(afile / "sub"))
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    return afile


def _kept_root(tmp_path: Path) -> Path:
    return tmp_path / "tmp" / f"tlm-cache-{os.getuid() if hasattr(os, 'getuid') else 'user'}"


def _run(exp: Path, out: Path, truth_spp: int = 0) -> int:
    return main(["error-vs-cost", str(exp), "--out", str(out), "--truth-spp", str(truth_spp), "--no-report"])


def test_error_vs_cost_keeps_a_reference_its_cache_cannot_take_and_goes_on(tmp_path, monkeypatch, capsys):
    afile = _blocked_cache(tmp_path, monkeypatch)
    exp, out = _study(tmp_path), tmp_path / "out"
    assert _run(exp, out) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and "error:" not in err, err
    kept = [line for line in err.splitlines() if KEPT in line]
    assert len(kept) == 1, err
    ref = json.loads((out / "reference.json").read_text())
    key = ref["key"]
    folder = _kept_root(tmp_path) / "references" / key
    assert kept[0].startswith(f"tlm: warning: reference {key}: not cached (")
    assert f"{afile} is a file, not a folder" in kept[0]
    assert f"kept in {folder} instead" in kept[0] and f"TLM_CACHE={_kept_root(tmp_path)}" in kept[0]
    assert (folder / "reference.npy").is_file() and (folder / "meta.json").is_file()
    assert ref["computed"] is True and ref["reference_converged"] is True
    assert ref["npy"] == json.loads((folder / "meta.json").read_text())["npy"]  # (as a cached one reads)
    (row,) = [json.loads(line) for line in (out / "rows.jsonl").read_text().splitlines()]
    assert row["rmse"] > 0.0 and row["reference_converged"] is True

    # the line's advice holds: a later study with TLM_CACHE there reads it, computes nothing
    import tlm.experiments.error_cost as ec

    monkeypatch.setenv("TLM_CACHE", str(_kept_root(tmp_path)))
    monkeypatch.setattr(ec, "compute_reference", lambda *a, **k: pytest.fail("computed the kept reference again"))
    again = tmp_path / "again"
    assert _run(exp, again) == 0
    assert KEPT not in capsys.readouterr().err
    second = json.loads((again / "reference.json").read_text())
    assert second["computed"] is False and second["key"] == key
    assert json.loads((again / "rows.jsonl").read_text())["rmse"] == row["rmse"]


def test_error_vs_cost_uses_a_reference_nowhere_to_keep_for_the_study_only(tmp_path, monkeypatch, capsys):
    afile = _blocked_cache(tmp_path, monkeypatch)
    monkeypatch.setattr(tempfile, "tempdir", str(afile / "tmp"))  # (the temporary folder unwritable too)
    out = tmp_path / "out"
    assert _run(_study(tmp_path), out) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and "error:" not in err, err
    (line,) = [line for line in err.splitlines() if KEPT in line]
    assert line.endswith("used by this study only"), line
    assert f"nor kept in {afile / 'tmp'}" in line
    ref = json.loads((out / "reference.json").read_text())
    assert ref["computed"] is True and ref["converged"] is True
    assert (out / "rows.csv").is_file()


def test_the_ground_truth_line_says_when_the_truth_is_not_cached(tmp_path, monkeypatch, capsys):
    pytest.importorskip("mitsuba")
    exp = _study(tmp_path)
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "ok"))
    assert _run(exp, tmp_path / "first", truth_spp=1) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if "ground truth" in line]
    assert len(lines) == 1 and lines[0].startswith("error-vs-cost: computing the ground truth (not cached): ") \
        and lines[0].endswith("1 spp; this may take minutes; it is then cached for every later study of this scene "
                              "at this spp"), lines

    root = tmp_path / "blocked"  # (the references' cache writable, the ground truths' a regular file)
    root.mkdir()
    (root / "oracle").write_text("")
    monkeypatch.setenv("TLM_CACHE", str(root))
    assert _run(exp, tmp_path / "second", truth_spp=1) == 0
    captured = capsys.readouterr()
    lines = [line for line in captured.out.splitlines() if "ground truth" in line]
    assert len(lines) == 1 and lines[0].endswith("it is computed for this study only"), lines
    assert f"the cache cannot take it ({root / 'oracle'}" in lines[0], lines
    assert f"cannot write tlm's Mitsuba ground-truth cache {root / 'oracle'}" in captured.err
    assert json.loads((tmp_path / "second" / "truth.json").read_text())["available"] is True


# ------------------------------------------------------------------ the API's studies


STUDIES = [  # (the api function, its arguments after the experiment, the layer function it calls, the command)
    ("sweep", ("out",), "tlm.experiments.sweep", "run_sweep", "sweep", "sweep_fifo"),
    ("run_sweep", ("out",), "tlm.experiments.sweep", "run_sweep", "sweep", "sweep_fifo"),
    ("thesis", ("out",), "tlm.experiments.thesis", "run_thesis", "thesis", "thesis"),
    ("calibrate", (), "tlm.experiments.thesis", "calibrate", "calibrate", "thesis"),
    ("granularity", ("out",), "tlm.experiments.granularity", "run_granularity", "granularity", "tlm_granularity"),
    ("error_vs_cost", ("out",), "tlm.experiments.error_cost", "run_error_vs_cost", "error-vs-cost",
     "error_vs_cost"),
    ("extreme", ("out",), "tlm.experiments.extreme", "run_extreme", "extreme", "extreme"),
]


class _Called(Exception):
    """What the layer function was given (the test stops there: no study runs)."""


@pytest.mark.parametrize(("function", "args", "module", "name", "command", "experiment"), STUDIES,
                         ids=[s[0] for s in STUDIES])
def test_the_api_s_studies_take_a_built_in_experiment_s_name(tmp_path, monkeypatch, function, args, module, name,
                                                             command, experiment):
    import importlib

    def record(path, *a, **k):
        raise _Called(path)

    monkeypatch.setattr(importlib.import_module(module), name, record)
    monkeypatch.chdir(tmp_path)  # (a folder of no configs/: as an installed copy's user)
    study = getattr(tlm, function)
    with pytest.raises(_Called) as called:
        study(experiment, *(tmp_path / a for a in args))
    (given,) = called.value.args
    assert Path(given) == api.configs_dir() / f"{experiment}.yaml"
    assert Path(given).is_file()

    # the command line's errors: a path that is not there names the built-in experiment's command
    with pytest.raises(InputError, match=rf"^configs/{experiment}\.yaml: not found here; the built-in experiment "
                                         rf"of that name: tlm {command} {experiment} "):
        study(f"configs/{experiment}.yaml", *(tmp_path / a for a in args))
    with pytest.raises(InputError, match=r"neither a file nor a built-in experiment \(built-in: .*\bthesis\b"):
        study("no_such_experiment", *(tmp_path / a for a in args))
    with pytest.raises(InputError, match=r"^path: 42 is not an experiment: give an experiment file's path or a "
                                         r"built-in experiment's name"):
        study(42, *(tmp_path / a for a in args))

    # a file of that name in the working folder wins, as on the command line
    (tmp_path / experiment).write_text("")
    with pytest.raises(_Called) as called:
        study(experiment, *(tmp_path / a for a in args))
    assert Path(called.value.args[0]) == Path(experiment)


def test_calibration_table_takes_a_built_in_study_s_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    by_name = api.calibration_table("thesis")
    assert by_name == api.calibration_table(api.configs_dir() / "thesis.yaml")
    assert by_name.is_file()


def test_a_folder_named_as_a_built_in_experiment_does_not_hide_it_from_load_config(tmp_path, monkeypatch):
    (tmp_path / "cornell").mkdir()
    monkeypatch.chdir(tmp_path)
    cfg = tlm.load_config("cornell")
    assert Path(cfg.source) == api.configs_dir() / "cornell.yaml" and cfg.scene == "cornell"


# ------------------------------------------------------------------ the scene loader


def test_the_scene_loader_takes_a_path(tmp_path):
    builtin = loader.scenes_dir() / "cornell.yaml"
    scene = loader.load_scene(builtin, resolution=[8, 8])
    assert (scene.name, scene.camera.width, scene.camera.height) == ("cornell", 8, 8)
    assert scene.triangles.shape == loader.load_scene(str(builtin), resolution=[8, 8]).triangles.shape

    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    relative = loader.load_scene(Path("furnace.yaml"), tmp_path)  # (relative to base, as a str is)
    assert relative.name == "furnace" and relative.camera.width == 24
    assert loader.resolve_scene_path(Path("thesis/ring")) == loader.scenes_dir() / "thesis" / "ring.yaml"
    with pytest.raises(InputError, match=r"scene file 'nowhere\.yaml' not found"):
        loader.load_scene(Path("nowhere.yaml"), tmp_path)
