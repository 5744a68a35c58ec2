"""h477: the report reads a run's files only where the run's ``.tlm-written`` lists them.

A rerun into a run folder keeps what the new run does not write of the earlier one's (the user's files, a file the
user edited since, and, where the folder had no listing, whole folders such as ``radiance/``: tlm.storage_carry).
The report took them for the new run's: h468 reran ``tlm run`` at 24x24 with ``--outputs images`` into the folder of
a 16x16 run whose listing it had deleted, and the report rebuilt its image panels from the 16x16 ``radiance/``, with
no sign of it. A file present but not listed is now read as absent (and said so where the report says a file is
absent); a thesis study's cell that its listing does not name is left out, with a note. A folder with no listing
at all is read as it is.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from tlm.cli import main
from tlm.report import build_report
from tlm.report.collect import read
from tlm.report.images import error_figure, run_panels
from tlm.report.written import kept
from tlm.storage_carry import LISTING

CORNELL = str(Path(__file__).resolve().parents[1] / "configs" / "cornell.yaml")
RUN = ["run", CORNELL, "--no-report", "--no-progress"]


def _run(out: Path, *args: str) -> None:
    assert main([*RUN, "--out", str(out), *args]) == 0


def test_the_h468_rerun_does_not_rebuild_its_images_from_the_earlier_run_s_radiance(tmp_path, cache):
    out = tmp_path / "R"
    _run(out, "--set", "resolution=[8,8]")
    (out / LISTING).unlink()
    run = read([out]).runs[0]  # (a folder with no listing, as a tlm older than listings wrote it: read as it is)
    assert run.radiance == out / "radiance" and run.trace == out / "trace.json"
    assert all(p.image is not None for p in run_panels(run)[:3])
    _run(out, "--set", "resolution=[12,12]", "--set", "mode=rcast", "--outputs", "images")
    assert (out / "radiance" / "rcast.npy").is_file()  # (kept: the folder had no listing)
    run = read([out]).runs[0]
    assert run.radiance is None and run.images == out / "images"
    panels = run_panels(run)
    assert panels[0].image.shape == (12, 12, 3)  # (its own composite: not the 8x8 run's radiance)
    assert [p.image for p in panels[1:]] == [None] * 3


def test_a_kept_radiance_folder_is_said_to_be_not_the_run_s(tmp_path, cache):
    out = tmp_path / "R"
    _run(out, "--set", "resolution=[8,8]")
    (out / LISTING).unlink()
    _run(out, "--set", "resolution=[12,12]", "--outputs", "images")  # (refract: three panels)
    panels = run_panels(read([out]).runs[0])
    assert [p.image is None for p in panels] == [True, True, False, True]
    assert panels[2].image.shape == (12, 12, 3)
    assert panels[0].remark.startswith("cannot rebuild: the run wrote no radiance/ (radiance/ is there, but not in "
                                       "the run's .tlm-written")  # (h486: not "the run folder has no radiance/")
    page = build_report([out]).read_text(encoding="utf-8")
    assert "radiance/ is there, but not in the run&#x27;s .tlm-written" in page


def test_a_kept_trace_is_not_drawn(tmp_path, cache):
    out = tmp_path / "R"
    _run(out, "--set", "resolution=[8,8]")
    with open(out / "trace.json", "a") as f:  # (the user's edit: kept by a rerun that writes no trace)
        f.write("\n")
    _run(out, "--set", "resolution=[8,8]", "--outputs", "images")
    assert (out / "trace.json").is_file()
    run = read([out]).runs[0]
    assert run.trace is None and kept(run, "trace.json").startswith(" (trace.json is there, but not in the run's")
    page = build_report([out]).read_text(encoding="utf-8")
    assert "no trace.json of its own (trace.json is there, but not in the run" in page


@pytest.fixture
def reference(monkeypatch):
    """Every photon-map run finds its reference at once (a grey image, converged), and its difference image is
    written while ``reference["there"]``, else not (the reference removed between the render and the write:
    tlm.experiments.run._write_difference writes none, the error stays measured)."""
    import tlm.experiments.run as run_module
    from tlm.experiments.reference import Found
    from tlm.experiments.reference_cache import ReferenceSettings

    state = {"there": True}
    meta = {"rounds": 8, "relative_standard_error": 0.001, "cycles": 2}

    def grey(frame):
        cam = frame.scene.camera
        return np.full((cam.width * cam.height, 3), 0.2, dtype=np.float32)

    monkeypatch.setattr(run_module, "ensure_reference", lambda frame, *a, **k: Found(
        "grey", ReferenceSettings.from_config(frame.scene, frame.cfg), grey(frame), meta))
    monkeypatch.setattr(run_module, "load_reference", lambda key: (
        np.full((8 * 8, 3), 0.2, dtype=np.float32), meta) if state["there"] else None)
    return state


def test_an_edited_difference_image_kept_by_a_rerun_is_not_drawn_as_the_run_s(tmp_path, cache, reference):
    out = tmp_path / "R"
    pmap = ["--set", "resolution=[8,8]", "--set", "mode=pmap", "--outputs", "images"]
    _run(out, *pmap)
    assert json.loads((out / "results.json").read_text())["error"]["difference_image"] == "images/pmap_error.png"
    Image.new("RGB", (8, 8), (255, 0, 255)).save(out / "images" / "pmap_error.png")  # (the user's annotation)
    reference["there"] = False
    _run(out, *pmap)
    error = json.loads((out / "results.json").read_text())["error"]
    assert error["available"] and "difference_image" not in error
    assert (out / "images" / "pmap_error.png").is_file()  # (edited since: kept as the user's)
    run = read([out]).runs[0]
    assert error_figure(run, tmp_path) is None
    assert run.wrote("images/pmap.png") == out / "images" / "pmap.png" and run.wrote("images/pmap_error.png") is None
    page = build_report([out]).read_text(encoding="utf-8")
    assert "images/pmap_error.png is there, but not in the run&#x27;s .tlm-written" in page


def test_an_edited_image_kept_by_a_rerun_is_not_read_as_the_run_s(tmp_path, cache):
    out = tmp_path / "R"
    _run(out, "--set", "resolution=[8,8]", "--set", "mode=pmap", "--no-reference", "--outputs", "images")
    Image.new("RGB", (8, 8), (255, 0, 255)).save(out / "images" / "pmap.png")  # (the user's annotation)
    _run(out, "--set", "resolution=[8,8]", "--set", "mode=rcast", "--outputs", "images")
    assert (out / "images" / "pmap.png").is_file()  # (edited since: kept as the user's)
    run = read([out]).runs[0]
    run.results["error"] = {"available": True, "rmse": 0.1, "rel_mse": 0.01}  # (as though it measured one)
    (out / "images" / "pmap_error.png").write_bytes((out / "images" / "pmap.png").read_bytes())  # (the user's)
    assert error_figure(run, tmp_path) is None
    assert run.wrote("images/pmap.png") is None and run.wrote("images/composite.png") is not None


@pytest.mark.slow
def test_a_thesis_cell_kept_by_a_rerun_is_left_out(tmp_path, cache):
    study = tmp_path / "thesis.yaml"
    out = tmp_path / "T"
    base = {"seed": 0, "resolution": [8, 8], "arch": {"frames": 2, "trace": False}}
    for modes in (["rcast", "reflect"], ["rcast"]):
        study.write_text(yaml.safe_dump({"base": base, "scenes": ["cornell"], "modes": modes}))
        assert main(["thesis", str(study), "--out", str(out), "--no-report", "--no-progress"]) == 0
        if len(modes) == 2:
            (out / LISTING).unlink()  # (then the rerun keeps the cell it does not write: cornell/reflect)
    assert (out / "cornell" / "reflect" / "results.json").is_file()
    inputs = read([out])
    assert [r.label for r in inputs.runs] == ["cornell/rcast"]
    assert any(n.startswith(f"{out / 'cornell' / 'reflect'}: a thesis cell that the study") for n in inputs.notes)
