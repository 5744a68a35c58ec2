"""Small leftovers of the API and the studies (h142).

``tlm.run``'s line on a reference it computes named the command line's ``--no-reference`` in a
Python call; ``tlm.error_vs_cost`` with no ``note`` lost its notes (that no ground truth was used:
only empty ``truth_*`` columns told it); its ``rows.csv`` wrote a setting's null as an empty cell,
where ``sweep.csv`` writes a null factor ``null``; ``tlm config export`` wrote a sweep's file in
place before its base was written; the stale-points warning did not name a different ``--set``;
``tlm.StepsFailed`` was not exported; docs/api.md did not name the studies' ``overrides=``.
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import pytest

import tlm
import tlm.builtin
import tlm.storage
from tlm import api
from tlm.api_common import arguments_text, flags_kept
from tlm.cli import main

from .scenes import sphere_scene

ROOT = Path(__file__).resolve().parents[1]
# two rounds over a few photons, far short of the tolerance: quick, and not converged
SHORT = {"photons": 500, "k_nearest": 20, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 2, "spp": 1}
PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "render": {"spp": 1}, "photons": {"count": 500},
        "reference": SHORT, "arch": {"frames": 1}}


# ---------------------------------------------------------------- 1. tlm.run's lines name its arguments


def test_flags_that_turn_an_argument_off_or_take_a_number_read_as_python_arguments():
    names = {"reference", "truth_spp", "force", "jobs"}
    assert arguments_text("('--no-reference' or reference.auto: false skips it)", names) == \
        "('reference=False' or reference.auto: false skips it)"
    assert arguments_text("not asked for (--truth-spp 0); the truth_* columns", names) == \
        "not asked for (truth_spp=0); the truth_* columns"
    assert arguments_text("give --jobs 2.", names) == "give jobs=2."
    assert arguments_text("use --force", names, {"force"}) == "use force=True"  # (as before)
    assert arguments_text("--no-report and --no-reference", {"force"}) == "--no-report and --no-reference"
    assert arguments_text("run tlm run x --no-reference ", names) == "run tlm run x --no-reference "  # (a command)


def test_run_s_line_on_the_reference_it_computes_names_reference_false(tmp_path, cache):
    said: list[str] = []
    tlm.run(PMAP, tmp_path / "a", outputs="images", reference=True, say=said.append)
    assert said and said[0].startswith("computing the photon-map reference")
    assert "('reference=False' or reference.auto: false skips it)" in said[0]
    assert not [line for line in said if "--no-reference" in line]
    import shutil

    shutil.rmtree(cache)
    with flags_kept():  # (tlm run: its flags, as the user typed them)
        kept: list[str] = []
        tlm.run(PMAP, tmp_path / "b", outputs="images", reference=True, say=kept.append)
    assert "('--no-reference' or reference.auto: false skips it)" in kept[0]


# ---------------------------------------------------------------- 2. and 3. error-vs-cost


def _study(tmp_path: Path, points: list) -> Path:
    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({
        "base": {"scene": "furnace.yaml", "resolution": [8, 8], "reference": SHORT, "photons": {"count": 800},
                 "estimate": {"final_gather": 0}},
        "points": points,
    }))
    return exp


def test_error_vs_cost_s_notes_and_warnings_are_its_rows_attrs(tmp_path, cache, capsys):
    exp = _study(tmp_path, [{"estimate.filter": ["disk"]}])
    rows = tlm.error_vs_cost(exp, tmp_path / "out", truth_spp=0)  # (note=None: the old code lost its notes)
    assert isinstance(rows, list) and len(rows) == 1 and rows[0]["truth_rmse"] is None
    notes, warnings = rows.attrs["notes"], rows.attrs["warnings"]
    assert "no ground truth: not asked for (truth_spp=0); the truth_* columns are empty" in notes
    assert notes[0].startswith("computing the photon-map reference")
    assert capsys.readouterr().out == ""  # (nothing printed: returned)
    assert len(warnings) == 1 and "is NOT converged" in warnings[0]  # (printed on stderr too, as before)
    heard: list[str] = []
    again = tlm.error_vs_cost(exp, tmp_path / "out", truth_spp=0, note=heard.append)
    assert heard == again.attrs["notes"] == ["no ground truth: not asked for (truth_spp=0); the truth_* columns "
                                             "are empty"]  # (the reference cached now: not computed)
    # the command line's note names its flag, as typed
    assert main(["error-vs-cost", str(exp), "--out", str(tmp_path / "cli"), "--truth-spp", "0", "--no-report"]) == 0
    assert "error-vs-cost: no ground truth: not asked for (--truth-spp 0)" in capsys.readouterr().out


def test_error_vs_cost_s_csv_writes_a_setting_s_null_as_null_and_a_missing_measure_empty(tmp_path, cache):
    exp = _study(tmp_path, [{"estimate.filter": ["disk"], "estimate.radius_fraction": [None, 0.02]}])
    out = tmp_path / "out"
    rows = tlm.error_vs_cost(exp, out, truth_spp=0)
    assert [r["radius_fraction"] for r in rows] == [None, 0.02]  # (null: the density rule)
    with open(out / "rows.csv", newline="") as fh:
        cells = list(csv.DictReader(fh))
    assert [c["radius_fraction"] for c in cells] == ["null", "0.02"]  # (the old code: an empty cell)
    assert [c["k"] for c in cells] == ["", ""] and [c["truth_rmse"] for c in cells] == ["", ""]  # (no meaning, none)
    assert all(float(c["radius"]) > 0 for c in cells) and cells[0]["filter"] == "disk"
    header = (out / "rows.csv").read_bytes().split(b"\r\n")[0].decode()
    from tlm.experiments.error_cost import COLUMNS

    assert header.split(",") == list(COLUMNS)  # (the columns as before, in their order)
    lines = (out / "rows.jsonl").read_text().splitlines()
    assert [json.loads(line)["radius_fraction"] for line in lines] == [None, 0.02]
    pd = pytest.importorskip("pandas")
    assert pd.read_csv(out / "rows.csv")["radius_fraction"].isna().tolist() == [True, False]


# ---------------------------------------------------------------- 4. config export


def test_config_export_puts_no_file_in_place_before_both_are_written(tmp_path, monkeypatch):
    """The old loop wrote the sweep's file in place, then its base: a reader in between found a sweep
    whose ``base: cornell.yaml`` was not there. Both are written beside (hidden) first."""
    real, seen = tlm.storage.write_file, []

    def write_file(path, data):
        seen.append(sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")))
        return real(path, data)

    monkeypatch.setattr(tlm.storage, "write_file", write_file)
    written = tlm.builtin.export_experiment("sweep_fifo", tmp_path / "fifo.yaml")
    assert written == [tmp_path / "fifo.yaml", tmp_path / "cornell.yaml"]
    assert seen == [[], []]  # (the old code: [[], ["fifo.yaml"]])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cornell.yaml", "fifo.yaml"]  # (nothing hidden left)


# ---------------------------------------------------------------- 5. the stale-points warning


def test_the_stale_points_line_names_a_different_set(tmp_path):
    from tlm.experiments.sweep import other_folders_line

    line = other_folders_line(2, tmp_path)
    assert "of other tlm code, another config or a different --set (" in line


# ---------------------------------------------------------------- 6. and 7. exports and docs


def test_steps_failed_is_exported():
    from tlm.errors import StepsFailed

    assert "StepsFailed" in api.__all__ and "StepsFailed" in tlm.__all__
    assert tlm.StepsFailed is api.StepsFailed is StepsFailed
    text = (ROOT / "docs" / "api.md").read_text()
    assert "tlm.StepsFailed" in text


def test_the_api_page_names_the_studies_overrides():
    text = " ".join((ROOT / "docs" / "api.md").read_text().split())
    said = re.search(r"The studies take `overrides=` as their commands take `--set`: (.*?)\. A mapping", text)
    assert said is not None
    for name in ("tlm.sweep", "tlm.thesis", "tlm.granularity", "tlm.error_vs_cost", "tlm.extreme"):
        assert f"`{name}`" in said[1], name
    for name in ("sweep", "thesis", "granularity", "error_vs_cost", "extreme"):
        assert "overrides" in __import__("inspect").signature(getattr(tlm, name)).parameters
