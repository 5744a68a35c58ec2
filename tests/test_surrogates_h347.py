"""Output folders, study files and error texts that hold bytes not UTF-8 (a surrogate, as Python reads them:
``os.fsdecode(b"dir_\\xff")`` is ``dir_\\udcff``), beyond ``tlm run``:

* a sweep's failed point whose error names such a path: ``sweep.csv`` is written, the byte escaped (``\\xff``), where
  UnicodeEncodeError left it unwritten (or the CSV of before beside the new ``sweep.jsonl``);
* a study's rows (``tlm extreme``: a bad-input case's error naming a scene file in such a folder): ``extreme.csv``
  with the byte escaped, where UnicodeEncodeError left no study folder at all;
* a report figure whose labels are laid out to place them (:func:`tlm.report.common.untangle`: error-vs-cost's) with
  such a folder's name drawn escaped, where matplotlib raised TypeError as it measured the title;
* a line printed to a stdout that refuses surrogates (a UTF-8 locale other than C.UTF-8, ``PYTHONIOENCODING=utf-8``)
  written with the byte escaped, where the command ended as an internal error (``tlm cache`` naming its folder).
"""

from __future__ import annotations

import csv
import io
import json
import os
import sys
from pathlib import Path

from matplotlib.figure import Figure as MplFigure

from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments import sweep_point
from tlm.experiments.sweep_rows import csv_cell, write_rows
from tlm.report.common import untangle
from tlm.storage_json import escaped

REPO = Path(__file__).resolve().parents[1]
DIR = os.fsdecode(b"dir_\xff")  # (dir_\udcff)
SWEEP = """description: two points, one failing
base: {scene: cornell, mode: rcast, seed: 0, resolution: [8, 8], render: {light_samples: 1, spp: 1},
       arch: {frames: 1, trace: false}}
grid:
  arch.packet_size: [16, 256]
"""


def test_escaped_writes_each_surrogate_as_its_byte():
    assert escaped(DIR) == "dir_\\xff" and escaped("a\ud800b") == "a\\ud800b" and escaped("8×8 é") == "8×8 é"
    assert csv_cell(f"InputError: /x/{DIR}/m.obj: not found") == "InputError: /x/dir_\\xff/m.obj: not found"


def test_sweep_csv_of_an_error_naming_a_path_not_utf8(tmp_path):
    (tmp_path / "sweep.csv").write_text("point\n0\n")  # (the CSV of before)
    rows = [{"point": 0, "hash": "a", "status": "failed", "error": f"InputError: /data/{DIR}/m.obj: not found"}]
    write_rows(tmp_path, rows)  # (was: UnicodeEncodeError, the CSV of before left beside the new JSONL)
    got = list(csv.DictReader(io.StringIO((tmp_path / "sweep.csv").read_text(encoding="utf-8"))))
    assert got[0]["error"] == "InputError: /data/dir_\\xff/m.obj: not found"
    assert json.loads((tmp_path / "sweep.jsonl").read_text())["error"] == rows[0]["error"]  # (JSON: the path itself)


def test_a_sweep_into_a_folder_not_utf8_whose_point_fails_naming_its_mesh(tmp_path, cache, monkeypatch, capsys):
    """End to end, the sweep file and its output in a folder of bytes not UTF-8, one point failing with an
    error naming a mesh file there: exit 1 (a point failed), ``sweep.csv`` written with the byte escaped."""
    folder = tmp_path / DIR
    folder.mkdir()
    (folder / "sw.yaml").write_text(SWEEP, encoding="utf-8")
    real = sweep_point.cached_render

    def render(cfg, *a, **k):
        if cfg.arch.packet_size == 256:
            raise InputError(f"mesh file '{folder / 'm.obj'}' not found", source=str(folder / "sw.yaml"))
        return real(cfg, *a, **k)

    monkeypatch.setattr(sweep_point, "cached_render", render)
    out = folder / "out"
    assert main(["sweep", str(folder / "sw.yaml"), "--out", str(out), "--jobs", "1", "--no-progress",
                 "--no-report"]) == 1  # (was: 1 as an internal error, UnicodeEncodeError, no sweep.csv)
    rows = list(csv.DictReader(io.StringIO((out / "sweep.csv").read_text(encoding="utf-8"))))
    assert [r["status"] for r in rows] == ["ok", "failed"]
    assert "dir_\\xff/sw.yaml: mesh file '" in rows[1]["error"] and "dir_\\xff/m.obj' not found" in rows[1]["error"]
    assert "internal error" not in capsys.readouterr().err


def test_a_study_s_rows_of_an_error_naming_a_scene_in_a_folder_not_utf8(tmp_path, cache):
    """``tlm extreme`` of a bad-input case whose expected error names its scene file, in a folder of bytes not
    UTF-8: the study is written, ``extreme.csv`` with the byte escaped (was: UnicodeEncodeError, no folder)."""
    folder = tmp_path / DIR
    folder.mkdir()
    (folder / "bad.yaml").write_text("name: bad\ngeometry:\n  - mesh: missing.obj\n", encoding="utf-8")
    (folder / "cases.yaml").write_text(
        "description: one case\nbase: {seed: 0, resolution: [8, 8]}\ncases:\n"
        "  - {name: bad-mesh, category: bad input, expect: refused, config: {scene: bad.yaml, mode: rcast},\n"
        "     checks: [{error: not found}]}\n", encoding="utf-8")
    out = folder / "out"
    assert main(["extreme", str(folder / "cases.yaml"), "--out", str(out), "--no-report", "--no-progress"]) == 0
    row = next(csv.DictReader(io.StringIO((out / "extreme.csv").read_text(encoding="utf-8"))))
    assert row["passed"] == "True" and "dir_\\xff/bad.yaml" in row["measured"]


def test_labels_placed_by_untangle_are_drawn_escaped():
    fig = MplFigure(figsize=(4, 3), layout="constrained")
    ax = fig.subplots()
    ax.plot([0, 1], [0, 1], "o")
    ax.set_title(f"{DIR}: photon-map RMSE against simulated frame time")
    label = ax.annotate(f"{DIR} a", (0, 0), textcoords="offset points", xytext=(4, 4))
    untangle(fig, [label], [(4, 4), (4, -4)])  # (was: TypeError from matplotlib's font, measuring the title)
    assert ax.get_title().startswith("dir_\\xff: ") and label.get_text() == "dir_\\xff a"


def test_a_line_naming_a_folder_not_utf8_to_a_stdout_that_refuses_surrogates(tmp_path, monkeypatch):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / DIR))
    strict = io.TextIOWrapper(io.BytesIO(), encoding="utf-8", errors="strict", newline="")  # (a UTF-8 locale's)
    monkeypatch.setattr(sys, "stdout", strict)
    assert main(["cache"]) == 0  # (was: 1, an internal error: UnicodeEncodeError)
    strict.flush()
    assert f"tlm's caches in {tmp_path}/dir_\\xff\n".encode() in strict.buffer.getvalue()


def test_rows_whose_csv_fails_otherwise_than_a_full_disk_leave_no_csv_that_disagrees(tmp_path, monkeypatch):
    """(Only an OSError removed it: any other error left the CSV of before beside the new ``sweep.jsonl``.)"""
    (tmp_path / "sweep.csv").write_text("point\n0\n")
    from tlm.experiments import sweep_rows

    def refused(value, factor=False):
        raise ValueError("a cell the CSV cannot write")

    monkeypatch.setattr(sweep_rows, "csv_cell", refused)
    try:
        write_rows(tmp_path, [{"point": 0, "error": "x"}, {"point": 1}])
    except ValueError:
        pass
    else:
        raise AssertionError("the cell's error was lost")
    assert not (tmp_path / "sweep.csv").exists() and (tmp_path / "sweep.jsonl").read_text().count("\n") == 2


def test_a_built_in_experiment_exported_into_a_folder_not_utf8(tmp_path):
    """``tlm config export NAME dir_\\xff/x.yaml``: the copy's comments name it with the byte escaped (the encode of
    the comment lines raised UnicodeEncodeError: an internal error, nothing written)."""
    (tmp_path / DIR).mkdir()
    assert main(["config", "export", "sweep_fifo", str(tmp_path / DIR / "x.yaml")]) == 0
    text = (tmp_path / DIR / "x.yaml").read_text(encoding="utf-8")
    assert "dir_\\xff" in text


def test_storage_write_rows_escapes_a_cell_of_a_path_not_utf8(tmp_path):
    """tlm.storage.write_rows (every experiment's rows): a cell naming a path of bytes not UTF-8 is written with the
    byte escaped; the JSON keeps it as its own escape."""
    from tlm.storage import write_rows as storage_rows

    storage_rows(tmp_path, "rows", [{"error": f"{DIR}/m.obj: not found", "n": 1}])
    assert "dir_\\xff/m.obj" in (tmp_path / "rows.csv").read_text(encoding="utf-8")
    assert json.loads((tmp_path / "rows.jsonl").read_text(encoding="utf-8"))["error"] == f"{DIR}/m.obj: not found"
