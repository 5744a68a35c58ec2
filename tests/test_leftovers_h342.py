"""h342: what a run records, and a run folder's name of bytes not UTF-8 in the report's figures.

* ``tlm run``'s ``results.json`` records who ran it, ``ran`` (``worker`` None outside Dask, ``host``, ``pid``), as a
  sweep point's does; the report's Provenance table gives a ``ran on`` column where the runs shown ran on more
  than one host (a tlm run's too), none for one machine's runs;
* a figure's text holding a surrogate (``os.fsdecode(b"run_\\xff")``: a folder's name of bytes not UTF-8) is drawn
  with the byte escaped (``run_\\xff``), its title, labels, tick labels and legend, where matplotlib raised; a
  figure's file name made of such a name is made, where hashing it raised.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
from pathlib import Path

import pytest
from matplotlib.figure import Figure as MplFigure

from tlm.cli import main
from tlm.report.collect import read
from tlm.report.common import drawable, figure_name, write_png
from tlm.report.provenance import provenance_section

REPO = Path(__file__).resolve().parents[1]
BYTE = os.fsdecode(b"run_\xff")  # (a folder's name of bytes not UTF-8, as Python reads it: run_\udcff)


@pytest.fixture
def ran(tmp_path, cache) -> Path:
    """A tlm run folder, run in this process."""
    out = tmp_path / "a"
    assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--set", "resolution=[8,8]", "--set", "arch.frames=1",
                 "--mode", "rcast", "--out", str(out), "--no-reference", "--no-report", "--no-progress"]) == 0
    return out


def test_a_tlm_run_records_who_ran_it_as_a_sweep_point_does(ran):
    results = json.loads((ran / "results.json").read_text(encoding="utf-8"))
    # (was: no "ran")
    assert results["ran"] == {"worker": None, "host": socket.gethostname(), "pid": os.getpid()}


def _on(folder: Path, host: str) -> None:
    path = folder / "results.json"
    results = json.loads(path.read_text(encoding="utf-8"))
    path.write_text(json.dumps({**results, "ran": {"worker": None, "host": host, "pid": 7}}), encoding="utf-8")


def test_the_report_names_the_hosts_of_runs_only_where_more_than_one_ran_them(ran, tmp_path):
    other = tmp_path / "b"
    shutil.copytree(ran, other)
    _on(ran, "node1")
    _on(other, "node1")
    alike = provenance_section(read([ran, other]), tmp_path)
    assert "ran on</th>" not in alike.html  # (one machine's runs: no column)
    _on(other, "node7")
    prov = provenance_section(read([ran, other]), tmp_path)
    # (was: no column, a tlm run's host never read)
    assert '<th class="l">ran on</th>' in prov.html
    assert '<td class="l">node1</td>' in prov.html and '<td class="l">node7</td>' in prov.html


def test_drawable_escapes_each_surrogate():
    assert drawable(BYTE) == "run_\\xff"
    assert drawable("a\ud800b") == "a\\ud800b"  # (a lone surrogate not of a byte)
    assert drawable("Cornell é ×") == "Cornell é ×"


def test_a_figure_with_a_folder_name_of_bytes_not_utf8_is_drawn_with_the_byte_escaped(tmp_path):
    fig = MplFigure(figsize=(4, 3), layout="constrained")
    ax = fig.subplots()
    ax.plot([0, 1], [0, 1], label=f"{BYTE}: rcast")
    ax.set_yticks([0, 1], labels=[BYTE, "other"])
    ax.set_xticks([0, 1], [f"x {BYTE}", "y"])
    ax.set_title(f"ours: {BYTE}: cornell/rcast")
    ax.set_xlabel(BYTE)
    ax.legend()
    fig.suptitle(BYTE)
    # (was: TypeError from matplotlib's font, set_text() of a str with a surrogate)
    write_png(fig, tmp_path / "runs.png")
    assert (tmp_path / "runs.png").is_file()
    assert ax.get_title() == "ours: run_\\xff: cornell/rcast" and fig.get_suptitle() == "run_\\xff"
    assert ax.get_xlabel() == "run_\\xff"
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["run_\\xff: rcast"]
    assert [t.get_text() for t in ax.get_yticklabels()] == ["run_\\xff", "other"]  # (as drawn: the formatter's)
    assert [t.get_text() for t in ax.get_xticklabels()] == ["x run_\\xff", "y"]


def test_a_figure_name_of_a_folder_name_of_bytes_not_utf8(tmp_path):
    # (was: UnicodeEncodeError hashing the key)
    one = figure_name(tmp_path, "sweep", BYTE)
    assert one == "sweep_run.png"
    (tmp_path / one).write_bytes(b"")
    other = figure_name(tmp_path, "sweep", os.fsdecode(b"run_\xfe"))  # (the same stem: told apart by its key)
    assert other != one and other.startswith("sweep_run_") and other.isascii()


def test_a_run_and_its_report_in_a_folder_named_by_bytes_not_utf8(tmp_path, cache):
    """End to end: ``tlm run`` with its report into a folder whose name is bytes not UTF-8 ends 0 and its
    report.html names the folder with the byte escaped (the page's write raised UnicodeEncodeError)."""
    out = tmp_path / BYTE
    assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--set", "resolution=[8,8]", "--set", "arch.frames=1",
                 "--mode", "rcast", "--out", str(out), "--no-reference", "--no-progress"]) == 0
    page = (out / "report" / "report.html").read_text(encoding="utf-8")
    assert "run_\\xff" in page
