"""The Python API checks its arguments and names them as a notebook gave them.

A bool argument given something else (``reference="yes"``, ``progress=1``) is an InputError naming it,
before any work, not taken as true; ``tlm.write_report`` takes one folder's path as that folder; an error
names the argument (``out``, ``jobs``, ``dpi``), not the command line's flag (``--out``), which the
command line keeps; a render in a message is named by its type, not its repr of many lines;
``tlm.simulate``'s ``programs=`` is named as the absolute path it tried and as ``programs``; a key of
another section than arch in ``tlm.simulate``'s mapping says that simulate does not render again; and
``progress=True`` shows a reference computed now (its lines on stderr where no ``say`` is given).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import tlm
import tlm.experiments.reference as reference_mod
import tlm.experiments.run as run_mod
import tlm.experiments.sweep as sweep_mod
import tlm.experiments.thesis as thesis_mod
import tlm.report as report_mod
from tlm.cli import main

TINY = {"mode": "rcast", "resolution": [8, 8], "render.spp": 1, "render.light_samples": 1}


@pytest.fixture
def no_work(monkeypatch):
    """Every layer an API call hands its work to, made to fail: a call that got there did not check first."""

    def worked(*args, **kwargs):
        raise AssertionError("the work began: the argument was not checked first")

    for module, name in ((run_mod, "run"), (run_mod, "render"), (run_mod, "simulate_run"),
                         (reference_mod, "make_reference"), (sweep_mod, "run_sweep"), (thesis_mod, "run_thesis"),
                         (report_mod, "build_report")):
        monkeypatch.setattr(module, name, worked)


@pytest.fixture(scope="module")
def res(tmp_path_factory):
    import os

    old = os.environ.get("TLM_CACHE")
    os.environ["TLM_CACHE"] = str(tmp_path_factory.mktemp("cache"))
    try:
        return tlm.render_image(tlm.load_config("cornell", TINY))
    finally:
        if old is None:
            del os.environ["TLM_CACHE"]
        else:
            os.environ["TLM_CACHE"] = old


CALLS = {
    "run reference": (lambda cfg, res, out: tlm.run(cfg, out, reference="yes"), "reference", "'yes'"),
    "run reference no": (lambda cfg, res, out: tlm.run(cfg, out, reference="no"), "reference", "'no'"),
    "run progress": (lambda cfg, res, out: tlm.run(cfg, out, progress="no"), "progress", "'no'"),
    "render progress": (lambda cfg, res, out: tlm.render_image(cfg, progress=1), "progress", "1"),
    "simulate progress": (lambda cfg, res, out: tlm.simulate(res, progress="yes"), "progress", "'yes'"),
    "reference force": (lambda cfg, res, out: tlm.reference(cfg, force="no"), "force", "'no'"),
    "reference bar": (lambda cfg, res, out: tlm.reference(cfg, bar=2), "bar", "2"),
    "reference progress": (lambda cfg, res, out: tlm.reference(cfg, progress="on"), "progress", "'on'"),
    "sweep progress": (lambda cfg, res, out: tlm.sweep("sweep_fifo", out, progress="no"), "progress", "'no'"),
    "run_sweep jobs": (lambda cfg, res, out: tlm.run_sweep("sweep_fifo", out, jobs="2"), "jobs", "'2'"),
    "thesis bar": (lambda cfg, res, out: tlm.thesis("thesis", out, bar="no"), "bar", "'no'"),
    "write_report lock": (lambda cfg, res, out: tlm.write_report([out], lock="no"), "lock", "'no'"),
}


@pytest.mark.parametrize("name", list(CALLS))
def test_a_bool_or_int_argument_of_another_kind_is_refused_naming_it(name, res, tmp_path, cache, no_work):
    call, key, shown = CALLS[name]
    with pytest.raises(tlm.InputError) as e:
        call(tlm.load_config("cornell", TINY), res, tmp_path / "out")
    assert str(e.value).startswith(f"{key}: {shown} is not ")
    assert not (tmp_path / "out").exists()


def test_numpy_bools_and_ints_are_taken(res, monkeypatch):
    seen = {}
    timing = tlm.simulate(res)  # (a real one, which simulate gives the stream's warnings, h542)
    monkeypatch.setattr(run_mod, "simulate_run", lambda result, table, progress: seen.setdefault("p", progress)
                        and timing)
    tlm.simulate(res, progress=np.bool_(True))
    assert seen["p"] is True


@pytest.mark.parametrize("given", [str, Path])
def test_write_report_takes_one_folder_as_that_folder(given, tmp_path, monkeypatch):
    seen = []
    monkeypatch.setattr(report_mod, "build_report", lambda dirs, out, title, **kw: seen.append(dirs) or "page")
    tlm.write_report(given(tmp_path / "run"))
    assert seen == [[tmp_path / "run"]]  # (was: one folder per character, or a TypeError for a Path)


def test_write_report_refuses_what_is_no_folder(tmp_path, no_work):
    for dirs, said in ((5, "dirs: 5 is not a folder or a list of folders"), ([5], "dirs: 5 is not a folder's path"),
                       ([], "dirs: no folder given")):
        with pytest.raises(tlm.InputError, match=f"^{said}"):
            tlm.write_report(dirs)


def test_errors_name_the_argument_not_the_flag(tmp_path, cache, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg = tlm.load_config("cornell", TINY)
    cases = [
        (lambda: tlm.run(cfg, ""), "out: '' is the current folder"),
        (lambda: tlm.run(cfg, tmp_path / "r", outputs="imagez"), "outputs: 'imagez': expected"),
        (lambda: tlm.sweep("sweep_fifo", tmp_path / "s", jobs=0), "jobs: 0 must be >= 1"),
        (lambda: tlm.write_report([tmp_path], dpi=20), "dpi: 20 dots per inch is out of range"),
        (lambda: tlm.write_report([tmp_path, tmp_path]), "out: several folders: name the report folder"),
        (lambda: tlm.run_sweep("sweep_fifo", tmp_path / "s", dask_wait=5), "dask_wait: 5: a wait for Dask"),
        (lambda: tlm.write_calibration(None, {}, " "), "target: an empty path names no table"),
    ]
    for call, said in cases:
        with pytest.raises(tlm.InputError) as e:
            call()
        assert str(e.value).startswith(said), str(e.value)
        assert "--" not in str(e.value), str(e.value)  # (nor a flag in the text: 'leave dask_wait out')
        assert e.value.key == said.split(":")[0]


def test_the_command_line_keeps_its_flags(tmp_path, cache, capsys):
    assert main(["sweep", "sweep_fifo", "--out", str(tmp_path / "s"), "--jobs", "0", "--no-progress"]) == 2
    assert "tlm: error: --jobs: 0 must be >= 1" in capsys.readouterr().err
    assert main(["report", str(tmp_path), str(tmp_path)]) == 2
    assert "tlm: error: --out: several folders: name the report folder" in capsys.readouterr().err
    assert main(["sweep", "sweep_fifo", "--out", str(tmp_path / "s"), "--dask-wait", "5", "--no-progress"]) == 2
    assert "leave --dask-wait out" in capsys.readouterr().err


def test_a_render_given_as_a_config_is_named_by_its_type(res, tmp_path):
    with pytest.raises(tlm.InputError) as e:
        tlm.run(res, tmp_path / "x")
    assert str(e.value).startswith("config: a RenderResult is not a config: give")
    assert "\n" not in str(e.value)


def test_simulate_names_its_programs_argument_as_the_path_it_tried(res, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(tlm.InputError) as e:
        tlm.simulate(res, programs="my.yaml")
    assert str(e.value) == f"{tmp_path / 'my.yaml'}: programs: file not found"


def test_simulate_says_it_takes_arch_keys_only(res, no_work):
    with pytest.raises(tlm.InputError) as e:
        tlm.simulate(res, {"render.spp": 2})
    assert str(e.value).startswith("arch: 'render.spp' is not a key of arch: simulate takes arch keys only")
    assert "without rendering it again" in str(e.value)
    with pytest.raises(tlm.InputError, match=r"^arch: 'pipelinez' is not a key of arch \(did you mean 'pipelines'"):
        tlm.simulate(res, {"pipelinez": 2})


def test_progress_shows_a_reference_computed_now(tmp_path, cache, monkeypatch, capsys):
    seen = {}

    def run(*args, say=None, progress=False, **kwargs):
        seen["run"] = progress
        say("computing the photon-map reference")
        return {}

    def make(*args, say=None, progress=None, bar=False, **kwargs):
        seen["reference"] = (bar, progress)
        say("reference computed")

    monkeypatch.setattr(run_mod, "run", run)
    monkeypatch.setattr(reference_mod, "make_reference", make)
    tlm.run(tlm.load_config("cornell", TINY), tmp_path / "r", progress=True)
    tlm.reference(tlm.load_config("cornell", TINY), progress=True)
    assert seen == {"run": True, "reference": (True, None)}
    assert capsys.readouterr().err == "computing the photon-map reference\nreference computed\n"


def test_outputs_and_overrides_of_another_kind_are_input_errors(tmp_path, no_work):
    for outputs in (0, [1], ["aov", None]):
        with pytest.raises(tlm.InputError, match=r"^outputs: .* is not an output's name"):  # (was a TypeError)
            tlm.run("cornell", tmp_path / "r", outputs=outputs)
    with pytest.raises(tlm.InputError, match=r"^overrides: 5 is not overrides: give a mapping"):
        tlm.load_config("cornell", 5)
    assert not (tmp_path / "r").exists()
