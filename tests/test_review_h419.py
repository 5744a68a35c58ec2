"""h419, review of h416 (67fe109) and h417 (e48f84f).

The summary's "What quality costs", for an error-vs-cost study whose reference is black (a camera that faces
nothing: no ``rel_mse`` in any row), said the study was "written before 'tlm error-vs-cost' simulated the
frame: run it again", which running it again does not change. It now says the reference (and the ground truth,
where that is black too) is black, so that no relative error can be measured (found by h417); a study written
before ``reference_black`` was kept is told by its rows, as the section's own figures tell it. And the section's
lead, HTML inside one ``<p class="lead">``, held a ``<p>`` per black image (no ``<p>`` can sit in a ``<p>``: a
browser closes the lead's first, leaving its words out of the lead)."""

from __future__ import annotations

import html
import json
import shutil

import tlm.report.tradeoff as tradeoff
from tests.test_error_cost_warnings_h417 import BlackTruth, _experiment
from tlm.experiments import error_cost as ec
from tlm.report.collect import read
from tlm.report.summary import _tradeoff

OLD = "written before 'tlm error-vs-cost' simulated the frame"


def _quality(folders, out) -> str:
    text, _ = _tradeoff(read(folders), out)
    return html.unescape(text)


def test_a_black_reference_is_said_as_black_not_as_an_old_study(tmp_path, cache):
    out = tmp_path / "evc"
    ec.run_error_vs_cost(_experiment(tmp_path), out, truth=ec.Truth(spp=0), warned=lambda line: None)
    text = _quality([out], tmp_path)
    assert OLD not in text and "run it again" not in text, text
    assert text.startswith("<b>What quality costs:</b> The photon-map reference is black (every pixel 0")
    assert "no relative error can be measured" in text and "ground truth" not in text.split(".")[0]

    # a study written before reference.json kept reference_black (and its warnings): told by its rows
    old = tmp_path / "old"
    shutil.copytree(out, old)
    ref = json.loads((old / "reference.json").read_text())
    for key in ("reference_black", "truth_black", "warnings"):
        del ref[key]
    (old / "reference.json").write_text(json.dumps(ref))
    assert _quality([old], tmp_path) == text

    # a lit study written before 'tlm error-vs-cost' simulated the frame (no frame_seconds) is still said so
    rows = [{"point": 0, "filter": "disk", "final_gather": 0, "photons": 800, "rmse": 0.2, "rel_mse": 0.1,
             "trace_seconds": 0.01, "gather_seconds": 0.0, "truth_rmse": None, "truth_rel_mse": None}]
    folder = tmp_path / "before"
    folder.mkdir()
    (folder / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    (folder / "reference.json").write_text(json.dumps({"reference_converged": True}))
    (folder / "provenance.json").write_text(json.dumps({"command": "error-vs-cost"}))
    inputs = read([folder])
    assert inputs.of_kind("error-vs-cost")
    text = html.unescape(_tradeoff(inputs, tmp_path)[0])
    assert OLD in text and "is black" not in text
    # both: each said so, the black one first
    text = _quality([out, folder], tmp_path)
    assert text.startswith("<b>What quality costs:</b> The photon-map reference of evc is black"), text
    assert "No row of the other error-against-cost study among the inputs has both a relative MSE and a " in text
    assert OLD in text


def test_a_black_reference_and_truth_and_a_lit_study_beside_them(tmp_path, cache):
    dark, lit = tmp_path / "dark", tmp_path / "lit"
    ec.run_error_vs_cost(_experiment(tmp_path), dark, truth=BlackTruth(spp=4096), warned=lambda line: None)
    text = _quality([dark], tmp_path)
    assert text.startswith("<b>What quality costs:</b> The photon-map reference (and its ground truth) is black")
    assert OLD not in text

    # beside a lit study: its lowest error quoted, and the dark one named as black (not left out unsaid)
    ec.run_error_vs_cost(_experiment(tmp_path, away=False), lit, truth=ec.Truth(spp=0), warned=lambda line: None)
    text = _quality([dark, lit], tmp_path)
    assert "the lowest error" in text, text
    assert "The photon-map reference of dark (and its ground truth) is black" in text, text
    assert OLD not in text


def test_the_sections_lead_holds_no_paragraph_of_its_own(tmp_path, cache):
    out = tmp_path / "evc"
    ec.run_error_vs_cost(_experiment(tmp_path), out, truth=BlackTruth(spp=4096), warned=lambda line: None)
    report = tmp_path / "report"
    report.mkdir()
    sec = tradeoff.tradeoff_section(read([out]), report)
    assert "<p" not in sec.lead and sec.lead.count("<br>") == 1, sec.lead
    assert "The photon-map reference is black" in html.unescape(sec.lead)
