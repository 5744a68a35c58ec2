"""Probe h204's findings on error-vs-cost and its report (task h211): a Ctrl-C that a C extension turned
into an error of its own, points that vary what changes nothing in the rows, a non-converged reference said
as converged, cut titles, series styles, the ground truth's samples, and the progress line."""

from __future__ import annotations

import os
import re
import signal
import traceback
from contextlib import suppress
from pathlib import Path

import numpy as np
import pytest
import yaml

import tlm.experiments.run as run_mod
from tlm.cli import main

from .test_faults import CORNELL, SMALL, leftovers


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _c_like(callback):
    """What nanobind does with an exception its call into Python raised (FLIP's ``evaluate`` importing a
    module as the signal comes): a TypeError of its own, the interrupt only in its text, not chained."""
    try:
        callback()
        return
    except KeyboardInterrupt as e:
        text = "".join(traceback.format_exception(e))
    raise TypeError(f"could not export nb::ndarray: {text}")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_an_interrupt_a_c_extension_made_its_own_error_is_still_an_interrupt(sig, tmp_path, monkeypatch, capsys):
    """Its one line and 128 + the signal, no traceback file; a bug raised before the signal came, whose handling
    the signal interrupted (the interrupt lost in such a call), is still the bug."""
    def render(*a, **k):
        _c_like(lambda: os.kill(os.getpid(), sig))

    monkeypatch.setattr(run_mod, "render", render)
    out = tmp_path / "runs" / "r"
    assert main(["run", CORNELL, "--out", str(out), *SMALL]) == 128 + sig
    assert capsys.readouterr().err.strip() == ("tlm: interrupted" if sig == signal.SIGINT
                                               else "tlm: terminated (SIGTERM)")
    assert not out.exists() and leftovers(tmp_path) == []
    assert not list(tmp_path.rglob("tlm-traceback-*"))

    def buggy():
        raise ValueError("a bug of its own")

    def render_bug(*a, **k):
        try:
            buggy()
        except ValueError:
            with suppress(TypeError):  # (lost)
                _c_like(lambda: os.kill(os.getpid(), sig))
            raise

    monkeypatch.setattr(run_mod, "render", render_bug)
    assert main(["run", CORNELL, "--out", str(tmp_path / "r"), *SMALL]) == 1
    assert "tlm: internal error: ValueError: a bug of its own" in capsys.readouterr().err



def test_a_bug_raised_after_a_library_swallowed_the_interrupt_is_the_bug_and_no_frame_outlives_the_command(
        tmp_path, monkeypatch, capsys):
    """(h219, 3) a bug raised in a caller of the frame a signal landed in, after a library swallowed the
    interrupt, was called "interrupted" (exit 130, no traceback kept); the frames the signal landed in, and
    every caller's locals, stayed alive after the command (errors._LANDED)."""
    import gc
    import weakref

    from tlm import errors

    held = []

    def swallowing_library():
        try:
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(10**6):
                pass
        except KeyboardInterrupt:
            pass

    def render(*a, **k):
        big = np.ones(1000)
        held.append(weakref.ref(big))
        swallowing_library()
        return {}["missing"]  # (a real bug, after the interrupt was handled)

    monkeypatch.setattr(run_mod, "render", render)
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    assert main(["run", CORNELL, "--out", str(tmp_path / "r"), *SMALL]) == 1
    assert "tlm: internal error: KeyError: 'missing'" in capsys.readouterr().err
    assert list((tmp_path / "cache").rglob("tlm-traceback-*"))
    assert errors._LANDED == []
    gc.collect()
    assert held and held[0]() is None  # (the command's locals let go)

# -- 2: a point that varies how the reference is found, or what changes nothing in the rows --------------------

@pytest.mark.parametrize(("points", "key"), [
    ({"photons.count": [2000], "reference.tolerance": [0.5, 0.01]}, "reference.tolerance"),
    ({"reference.max_rounds": [8, 16]}, "reference.max_rounds"),
    ({"reference.min_rounds": [4, 8]}, "reference.min_rounds"),
    ({"reference.spp": [1, 4]}, "reference.spp"),
    ({"reference": [{"auto": False}]}, "reference.auto"),
    ({"render.exposure": [1, 2]}, "render.exposure"),
    ({"render": [{"exposure": 2}]}, "render.exposure"),
])
def test_a_point_cannot_vary_the_references_stopping_rule_nor_the_exposure(points, key, tmp_path):
    from tlm.errors import InputError
    from tlm.experiments.error_cost import load_experiment

    path = tmp_path / "evp.yaml"
    path.write_text(yaml.safe_dump({"base": {"scene": "cornell", "resolution": [32, 32]}, "points": [points]}))
    with pytest.raises(InputError, match=rf"a point cannot vary {key}: "):
        load_experiment(path)


def test_the_command_refuses_it_before_any_work(tmp_path, capsys):
    path = tmp_path / "evp.yaml"
    path.write_text(yaml.safe_dump({"base": {"scene": "cornell", "resolution": [32, 32]},
                                    "points": [{"reference.tolerance": [0.5, 0.01]}]}))
    out = tmp_path / "ev"
    assert main(["error-vs-cost", str(path), "--out", str(out), "--truth-spp", "0", "--no-report"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("tlm: error: ") and "a point cannot vary reference.tolerance" in err
    assert len(err.splitlines()) == 1 and not out.exists()


# -- 3, 4, 5, 6: the report's words and styles -----------------------------------------------------------------

def _rows(fg=(0, 4, 16), converged=False, truth_spp=16):
    rows = []
    for i, (filt, g) in enumerate([("knn", 0), *[("mvoxel", g) for g in fg]]):
        for j, n in enumerate((1000, 4000)):
            rows.append({"point": 2 * i + j, "filter": filt, "final_gather": g, "photons": n, "rmse": 0.1 / (j + 1 + i),
                         "rel_mse": 0.01, "frame_seconds": 1e-3 * (i + j + 1), "trace_seconds": 0.1 * (j + 1),
                         "gather_seconds": 0.05 * (i + 1), "one_off_seconds": 0.0, "truth_rmse": 0.2,
                         "truth_rel_mse": 0.3, "truth_flip": 0.2, "truth_spp": truth_spp,
                         "reference_converged": converged, "factors": f"photons.count={n}"})
    return rows


def _study(tmp_path, converged=False, overrides=(), truth_spp=16):
    from tlm.report.collect import Study

    ref = {"key": "cace69a31d6a419bba0c", "rounds": 32, "relative_standard_error": 0.0547, "tolerance": 0.02,
           "converged": converged, "reference_converged": converged}
    meta = {"reference": ref, "provenance": {"overrides": list(overrides)}}
    return Study("error-vs-cost", tmp_path / "evc", _rows(converged=converged, truth_spp=truth_spp), meta)


def test_a_non_converged_reference_is_said_so_in_the_figures(tmp_path, monkeypatch):
    import tlm.report.tradeoff as tradeoff
    from tests.helpers_figures import capture

    figs = capture(monkeypatch, tradeoff)
    study = _study(tmp_path)
    frame = tradeoff.evc_figure(study, tmp_path, "f.png", "frame", [], "evc")
    truth = tradeoff.evc_truth_figure(study, tmp_path, "t.png", [], "evc")
    assert "NOT converged" in figs[0].axes[0].get_ylabel() and "did NOT converge" in frame.caption
    assert "converged k-NN" not in truth.caption and "NOT converged" in truth.caption
    converged = _study(tmp_path / "c", converged=True)
    tradeoff.evc_figure(converged, tmp_path, "c.png", "frame", [], "evc")
    assert figs[-1].axes[0].get_ylabel() == "image RMSE against the converged reference (linear radiance)"


def test_the_warnings_box_lists_a_non_converged_reference(tmp_path):
    from tlm.report.warnings import study_recorded

    inputs = type("Inputs", (), {"studies": [_study(tmp_path)], "runs": [], "damaged": []})()
    (line, _, files), = study_recorded(inputs)
    assert "NOT converged" in line and "0.0547" in line and files == ["reference.json:reference_converged"]
    from tlm.report.warnings import warnings_html

    assert "(reference.json <code>reference_converged</code>)" in warnings_html(inputs)


def test_a_runs_error_figure_says_its_reference_not_converged(tmp_path):
    import tlm.report.images as images
    from tests.test_report_diff_grey import error_run
    from tlm.report.common import Section

    run = error_run(tmp_path / "run1", np.full((4, 9, 3), 128, np.uint8))
    run.results["error"]["reference_converged"] = False
    (tmp_path / "rep").mkdir()
    fig = images.error_figure(run, tmp_path / "rep")
    assert "converged reference" not in fig.title and "NOT converged" in fig.title
    section = Section("images", "x")
    images._error_figures(section, [run], tmp_path / "rep")
    assert "converged reference" not in section.lead and "NOT converged" in section.lead


def test_long_titles_are_wrapped(tmp_path, monkeypatch):
    import tlm.report.tradeoff as tradeoff
    from tests.helpers_figures import capture

    figs = capture(monkeypatch, tradeoff)
    label = "evfull2 (with --set resolution=[32,32], reference.photons=2000, reference.max_rounds=16)"
    tradeoff.evc_figure(_study(tmp_path), tmp_path, "w.png", "wall", [], label)
    tradeoff.evc_truth_figure(_study(tmp_path), tmp_path, "t.png", [], label)
    for fig in figs:
        assert "\n" in fig.axes[0].get_title()


def test_one_style_per_series_in_numeric_order(tmp_path, monkeypatch):
    """The final-gather series: 4 rays before 16, and the same marker and colour in each figure, drawn or not."""
    import tlm.report.tradeoff as tradeoff
    from tests.helpers_figures import capture

    rows = _rows()
    assert tradeoff.series_order(rows) == ["knn", "mvoxel", "mvoxel + final gather (4 rays)",
                                           "mvoxel + final gather (16 rays)"]
    figs = capture(monkeypatch, tradeoff)
    study = _study(tmp_path)
    for r in study.rows:  # (the truth figure draws no knn row: the others keep their styles)
        if r["filter"] == "knn":
            r["truth_rmse"] = None
    tradeoff.evc_figure(study, tmp_path, "w.png", "wall", [], "evc")
    tradeoff.evc_truth_figure(study, tmp_path, "t.png", [], "evc")

    def styles(fig):
        out = {}
        for c in fig.axes[0].collections:
            name = str(c.get_label()).removeprefix("filter ").split(":")[0]
            if c.get_offsets().size and name in tradeoff.series_order(rows):
                filled = c.get_facecolor().size and c.get_facecolor()[0][3]  # (hollow: its edge's colour)
                out.setdefault(name, tuple(np.round((c.get_facecolor() if filled else c.get_edgecolor())[0][:3], 3)))
        return out

    wall, truth = styles(figs[0]), styles(figs[1])
    assert set(truth) == set(wall) - {"knn"}
    assert all(truth[k] == wall[k] for k in truth)


def test_a_few_truth_samples_are_said(tmp_path):
    import tlm.report.tradeoff as tradeoff
    from tlm.experiments.error_cost_truth import TRUTH_SPP_LOW, truth_noise_words

    assert truth_noise_words(16).startswith("The ground truth has only 16 samples per pixel")
    assert truth_noise_words(TRUTH_SPP_LOW) == truth_noise_words(4096) == truth_noise_words(None) == ""
    fig = tradeoff.evc_truth_figure(_study(tmp_path), tmp_path, "t.png", [], "evc")
    assert "(16 spp)" in fig.caption and "only 16 samples per pixel" in fig.caption


# -- 7: the progress line, and tlm reference's line for a cached reference -------------------------------------

def test_the_progress_line_gives_no_radius_for_knn_and_names_its_seconds(monkeypatch, tmp_path, capsys):
    import tlm.cli as cli

    row = {"rel_mse": 0.1, "truth_rel_mse": None, "fps": 10.0, "factors": "estimate.filter=knn", "filter": "knn",
           "photons": 1000, "radius": None, "k": None, "k_nearest": 50, "photons_tested": 5, "gather_seconds": 0.5}

    def fake(config, out, progress=None, **k):
        progress(0, 1, row)
        return [row]

    monkeypatch.setattr(cli.api, "error_vs_cost", fake)
    (tmp_path / "x.yaml").write_text("base: {scene: cornell}\npoints: [{photons.count: [1000]}]\n")
    assert main(["error-vs-cost", str(tmp_path / "x.yaml"), "--out", str(tmp_path / "o"), "--no-report"]) == 0
    line = capsys.readouterr().out.splitlines()[0]
    assert "radius        -" in line and "radius        0" not in line and "gather 0.50 s" in line


def test_tlm_reference_says_a_kept_reference_was_found_cached_not_computed(capsys):
    args = ["reference", str(Path(CORNELL).with_name("cornell_pmap.yaml")), "--set", "resolution=[16,16]",
            "--set", "reference.photons=500",
            "--set", "reference.max_rounds=4", "--set", "reference.spp=2", "--set", "reference.tolerance=0.0001",
            "--no-progress"]
    assert main(args) == 1
    first = capsys.readouterr().out.strip().splitlines()[-1]
    assert re.search(r"after 4 rounds \(.*\) in [0-9.]+ s; wrote ", first), first
    assert main(args) == 1  # (kept: computing it again would repeat the same rounds)
    second = capsys.readouterr().out.strip().splitlines()[-1]
    assert "after 4 rounds" in second and ", found cached (nothing computed); the cache keeps " in second
    assert not re.search(r"\) in [0-9.]+ s", second), second


@pytest.mark.parametrize(("truth", "converged"), [(True, True), (False, False)])
def test_the_summary_s_quality_line_says_the_truth_s_samples_and_an_unconverged_reference(tmp_path, truth,
                                                                                          converged):
    """"What quality costs" quoted truth_rel_mse with no word of the truth's 16 samples a pixel, and rel_mse
    "against our reference" where that reference had not converged."""
    from tlm.report.collect import Inputs
    from tlm.report.summary import _tradeoff

    st = _study(tmp_path, converged=converged)
    if not truth:
        st.rows[:] = [{**r, "truth_rel_mse": None} for r in st.rows]
    text, _ = _tradeoff(Inputs([tmp_path], studies=[st]), tmp_path)
    if truth:
        assert "against Mitsuba's path tracer (16 spp)" in text and "only 16 samples per pixel" in text
    else:
        assert "against our reference (NOT converged)" in text


def test_the_summary_s_figure_styles_a_series_as_the_study_s_figures_do(tmp_path, monkeypatch):
    """(h219, 8) the summary numbered its series from the rows it draws (knn without a frame time left out:
    mvoxel took knn's colour), where the study's figures style them by all its rows (tradeoff.series_styles)."""
    import matplotlib.colors as mcolors

    import tlm.report.summary as summary
    from tests.helpers_figures import capture
    from tlm.report.collect import Inputs
    from tlm.report.common import line_style
    from tlm.report.tradeoff import series_styles

    figs = capture(monkeypatch, summary)
    st = _study(tmp_path, converged=True)
    for r in st.rows:
        if r["filter"] == "knn":
            r["frame_seconds"] = None
    summary._tradeoff(Inputs([tmp_path], studies=[st]), tmp_path)
    styles = series_styles(st.rows)
    drawn = {ln.get_label(): (mcolors.to_hex(ln.get_color()), ln.get_marker()) for ln in figs[0].axes[0].get_lines()}
    assert "knn" not in drawn and set(drawn) == set(styles) - {"knn"}
    for name, (color, mark) in drawn.items():
        want = line_style(styles[name])
        assert (color, mark) == (mcolors.to_hex(want["color"]), want["marker"]), name


def test_the_summary_marks_a_value_against_a_non_converged_reference_among_several_studies(tmp_path):
    """(h219, 8) with two studies, a series' best value from the study whose reference did not converge was quoted
    beside the others' with no word of it."""
    from tlm.report.collect import Inputs
    from tlm.report.summary import _tradeoff

    good = _study(tmp_path / "a", converged=True, overrides=["photons.count=1"])
    bad = _study(tmp_path / "b", converged=False, overrides=["photons.count=2"])
    for st in (good, bad):
        st.rows[:] = [{**r, "truth_rel_mse": None} for r in st.rows]
    for r in bad.rows:
        r["rel_mse"] = 0.02  # (the good study holds the lowest: the bad one's values are in the rest)
    text, _ = _tradeoff(Inputs([tmp_path], studies=[good, bad]), tmp_path)
    assert text.split("; ", 1)[0].endswith("a frame against our reference"), text  # (the lowest: converged)
    assert text.count("(against a reference NOT converged)") == 4, text  # (the bad study's 4 series)
