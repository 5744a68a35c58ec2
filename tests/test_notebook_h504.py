"""What a notebook probe found (h499):

* A report drew under the caller's matplotlib settings: after ``plt.style.use("dark_background")`` every PNG of
  ``tlm.write_report`` came out black, ``font.size = 20`` clipped its labels, ``axes.grid`` and
  ``savefig.transparent`` changed them too (a user's matplotlibrc, the CLI's report alike). Now a report draws in
  matplotlib's defaults and tlm's own settings (:func:`tlm.report.common.report_style`), the same files whoever
  writes it, and the caller's settings are as they were after it.
* ``tlm.reference()`` returned a ``Made`` whose repr printed the whole image (16 KB at 16x16), and a ``Scene``'s
  repr was 4 KB over 49 lines: now one short line each, every field still there.
* ``dir(tlm)`` listed ``Any``, ``TYPE_CHECKING`` and ``annotations``: now the API's names only.
"""

from __future__ import annotations

import copy
import hashlib
import threading
from pathlib import Path

import matplotlib
import matplotlib.style
import numpy as np
import pytest

import tlm
import tlm.report.common as common
from tests.test_report_speed_h128 import sweep_folder  # (a 3-point sweep's rows: the figures' input)
from tlm.experiments.reference import Made
from tlm.experiments.reference_cache import ReferenceSettings
from tlm.report import build_report


def figures(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha1(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())
            if p.suffix in (".png", ".svg")}


def test_a_report_draws_the_same_files_whatever_the_callers_matplotlib_settings(tmp_path):
    sw = sweep_folder(tmp_path / "sw")
    with matplotlib.rc_context():  # (this test's settings go with it)
        build_report([sw], tmp_path / "plain", formats="svg")
        plain = figures(tmp_path / "plain")
        assert any(name.endswith(".png") for name in plain)
        matplotlib.style.use("dark_background")
        matplotlib.rcParams.update({"font.size": 20, "axes.grid": True, "savefig.transparent": True,
                                    "lines.linewidth": 5, "figure.dpi": 200, "svg.fonttype": "path"})
        theirs = copy.deepcopy(dict(matplotlib.rcParams))
        build_report([sw], tmp_path / "styled", formats="svg")
        assert figures(tmp_path / "styled") == plain  # (was: every figure other: black, larger text, a grid)
        assert dict(matplotlib.rcParams) == theirs  # the caller's settings as they were


def test_the_callers_settings_are_back_at_the_last_end_of_reports_in_two_threads():
    with matplotlib.rc_context({"font.size": 20, "axes.facecolor": "black"}):
        first, second = common.report_style(), common.report_style()
        first.__enter__()
        assert matplotlib.rcParams["font.size"] == 10 and matplotlib.rcParams["pdf.fonttype"] == 42
        entered = threading.Thread(target=second.__enter__)
        entered.start()
        entered.join()
        first.__exit__(None, None, None)  # (the first report done: the second still draws in the defaults)
        assert matplotlib.rcParams["font.size"] == 10 and matplotlib.rcParams["axes.facecolor"] == "white"
        second.__exit__(None, None, None)
        assert matplotlib.rcParams["font.size"] == 20 and matplotlib.rcParams["axes.facecolor"] == "black"


def test_a_reference_shows_in_one_short_line_its_image_kept():
    image = np.linspace(0, 1, 16 * 16 * 3, dtype=np.float32).reshape(16, 16, 3)
    meta = {"rounds": 6, "cycles": 3, "relative_standard_error": 0.0123, "converged": True}
    made = Made("9b6bee9395849f54b2b7", ReferenceSettings(photons=5000, min_rounds=2), meta, True,
                Path("/cache/references/9b6bee9395849f54b2b7"), image=image, warnings=("a warning",))
    shown = repr(made)
    assert "\n" not in shown and len(shown) < 300  # (was: 16 KB, the image's every value)
    for part in ("9b6bee9395849f54b2b7", "image 16x16", "6 rounds", "0.0123", "tolerance 0.02: met", "computed now",
                 "/cache/references/9b6bee9395849f54b2b7", "1 warning"):
        assert part in shown
    assert made.image is image and made.meta is meta and made.meets


def test_a_scene_shows_in_one_short_line_its_arrays_kept():
    scene = tlm.load_scene("cornell")
    shown = repr(scene)
    assert "\n" not in shown and len(shown) < 300  # (was: 4 KB over 49 lines, the triangles' coordinates)
    cam = scene.camera
    for part in ("'cornell'", f"{scene.n_triangles:,} triangles", f"{len(scene.materials)} materials",
                 f"camera {cam.width}x{cam.height}", f"{scene.photons:,} photons", scene.source):
        assert part in shown
    assert scene.triangles.shape == (scene.n_triangles, 3, 3)


def test_dir_lists_the_api_alone():
    assert dir(tlm) == sorted(tlm.__all__)  # (was: Any, TYPE_CHECKING, annotations and the submodules too)


@pytest.mark.parametrize("name", ["Any", "TYPE_CHECKING", "annotations"])
def test_dir_lists_no_name_of_the_module_itself(name):
    assert name not in dir(tlm)
