"""Findings of a probe of `tlm error-vs-cost` on a researcher's own scene file (h394): a scene whose
camera sees nothing lit gives Mitsuba a black ground truth, and flip_evaluator ended the whole process
on it (a C++ abort, "Start exposure must be smaller than stop exposure!", no output, no one-line
error); so did a faint one (luminance peaking below about 1e-7). The composite's truth_flip is now
empty where the truth is black, and a truth too faint for FLIP is scaled to 1, with the composite, before
FLIP (only such a one: HDR-FLIP changes with the scale where half the truth is dark, h397,
tests/test_review_h397.py). Each call runs in a child process, so that
the old abort fails the test rather than the test run."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

CHILD = """
import json, sys
import numpy as np
from tlm.experiments.error_cost_truth import truth_error
from tlm.oracle import mitsuba as oracle

rng = np.random.default_rng(0)
truth = rng.uniform(0.2, 1.0, (16, 16, 3))
truth[4:8, 4:8] = 3.0
img = truth * rng.uniform(0.8, 1.2, truth.shape)
keep = np.ones((16, 16), dtype=bool)
case = sys.argv[1]
if case == "black":
    row = truth_error(img.reshape(-1, 3), np.zeros_like(truth), keep)
    print(json.dumps(row))
else:
    scale = float(case)
    row = truth_error((img * scale).reshape(-1, 3), truth * scale, keep)
    print(json.dumps({**row, "unscaled": oracle.flip(img, truth)}))
"""


def _child(case: str) -> dict:
    pytest.importorskip("flip_evaluator")  # (these cases alone need it: the others run without it)
    done = subprocess.run([sys.executable, "-c", CHILD, case], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_black_truth_leaves_truth_flip_empty_and_the_process_alive():
    row = _child("black")
    assert row["truth_flip"] is None
    assert row["truth_rel_mse"] is None  # (no squared truth to divide by: as image_error says)
    assert row["truth_rmse"] > 0


@pytest.mark.parametrize("scale", ["1e-9", "1e-12"])
def test_faint_truth_gets_the_flip_of_the_same_images_at_full_scale(scale):
    row = _child(scale)
    assert row["truth_flip"] == pytest.approx(row["unscaled"], rel=1e-4, abs=1e-6)
    assert 0 < row["truth_flip"] < 1


def test_a_truth_of_ordinary_brightness_is_not_rescaled():
    row = _child("1.0")
    assert row["truth_flip"] == row["unscaled"]  # (bit for bit: the studies' numbers of before stand)


def test_black_lines_name_the_empty_columns():
    import numpy as np

    from tlm.experiments.error_cost_truth import black_lines

    lit = np.full((4, 3), 0.5)
    assert black_lines(lit, lit, "k") == []
    assert black_lines(lit, None, "k") == []
    (ref,) = black_lines(np.zeros((4, 3)), lit, "abc")
    assert ref.startswith("the photon-map reference abc is black (every pixel 0): every row's rel_mse is empty")
    (truth,) = black_lines(lit, np.zeros((4, 4, 3)), "abc")
    assert truth.startswith("the ground truth is black (every pixel 0): every row's truth_rel_mse and truth_flip")


def test_error_vs_cost_of_a_camera_that_sees_nothing_says_why_its_rel_mse_is_empty(tmp_path, monkeypatch, capsys):
    from tests.scenes import sphere_scene
    from tests.test_installed_copy_leftovers import REFERENCE, _run

    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    scene = tmp_path / "furnace.yaml"  # (the camera moved outside the closed sphere, looking away from it)
    scene.write_text(scene.read_text().replace("eye: [0.0, 0.0, 0.0], target: [0.0, 0.0, 1.0]",
                                               "eye: [0.0, 0.0, 5.0], target: [0.0, 0.0, 9.0]"))
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({
        "base": {"scene": "furnace.yaml", "resolution": [8, 8], "photons": {"count": 800},
                 "reference": REFERENCE, "estimate": {"final_gather": 0}},
        "points": [{"estimate.filter": ["disk"]}],
    }))
    assert _run(exp, tmp_path / "out") == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    lines = [line for line in err.splitlines() if "is black (every pixel 0)" in line]
    assert len(lines) == 1 and lines[0].startswith("tlm: warning: error-vs-cost: the photon-map reference "), err
    (row,) = [json.loads(line) for line in (tmp_path / "out" / "rows.jsonl").read_text().splitlines()]
    assert row["rel_mse"] is None


def _away(tmp_path):
    """tests/scenes.py's furnace with the camera outside the closed sphere, looking away from it."""
    from tests.scenes import sphere_scene

    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    scene = tmp_path / "furnace.yaml"
    scene.write_text(scene.read_text().replace("eye: [0.0, 0.0, 0.0], target: [0.0, 0.0, 1.0]",
                                               "eye: [0.0, 0.0, 5.0], target: [0.0, 0.0, 9.0]"))
    return scene


def test_granularity_says_the_frames_own_warnings(tmp_path, monkeypatch):
    from tlm.experiments.granularity import run_granularity

    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    _away(tmp_path)
    study = tmp_path / "gran.yaml"
    study.write_text(json.dumps({"base": {"scene": "furnace.yaml", "mode": "rcast", "resolution": [8, 8],
                                          "arch": {"frames": 2}}, "packet_sizes": [1, 16]}))
    said = []
    rows = run_granularity(study, tmp_path / "out", warned=said.append)
    assert [r["packet_size"] for r in rows] == [1, 16]
    # (8 x 8 pixels, 4 eye rays each)
    assert "granularity: the camera faces nothing: none of its 256 eye rays hits the scene" in said, said
    assert any(line.startswith("granularity: the image is black") for line in said), said
    # the furnace seen from inside, lit (its own lines, on its back faces, are said too)
    lit = tmp_path / "lit"
    lit.mkdir()
    from tests.scenes import sphere_scene

    sphere_scene(lit, n_seg=8, n_rings=4)
    (lit / "gran.yaml").write_text(study.read_text())
    said.clear()
    run_granularity(lit / "gran.yaml", lit / "out", warned=said.append)
    assert said and not [line for line in said if "faces nothing" in line or "is black" in line], said


@pytest.mark.parametrize(("given", "said"), [("[true, 4]", "[true, 4]"), ("null", "null"), ("[1, 1.5]", "[1, 1.5]")])
def test_a_bad_packet_sizes_is_quoted_as_the_yaml_wrote_it(tmp_path, given, said):
    from tlm.errors import InputError
    from tlm.experiments.granularity import load_granularity

    study = tmp_path / "g.yaml"
    study.write_text(f"base: {{scene: cornell, mode: rcast}}\npacket_sizes: {given}\n")
    with pytest.raises(InputError) as got:
        load_granularity(study)
    assert f"packet_sizes: {said} must be a non-empty list of whole numbers >= 1" in str(got.value), str(got.value)
