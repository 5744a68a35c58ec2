"""The report's provenance section (:mod:`tlm.report.provenance`): per run its folder,
seed, revision, versions and host seconds, and its resolved config; per study folder its
``provenance.json``, or that it has none."""

from __future__ import annotations

from pathlib import Path

import yaml

from tlm.report.collect import Inputs, Run, Study
from tlm.report.provenance import MAX_CONFIGS, provenance_section


def _run(i: int, **results) -> Run:
    r = {"scene": {"name": "ring"}, "seed": 7 + i, "git_revision": "0123456789abcdef",
         "versions": {"numpy": "2.0", "tlm": "0.9", "other": "x"}, "host_seconds": {"sim": 1.5, "io": 0.25},
         **results}
    return Run(Path(f"runs/r{i}"), f"ring/rcast #{i}", "run", r, {"scene": "ring", "note": f"<{i}>"})


def _cells(html: str) -> list[list[str]]:
    return [[c.split("</td>")[0] for c in row.split('<td class="l">')[1:]]
            for row in html.split("<tr>") if row.startswith('<td class="l">')]


def test_a_row_and_a_config_per_run(tmp_path):
    runs = [_run(0), _run(1, functional={"render_host_seconds": {"a": 2.0}, "cached": True}),
            _run(2, git_revision=None, versions=None, host_seconds=None)]
    sec = provenance_section(Inputs([], runs=runs), tmp_path)
    assert sec.absent is None and sec.notes == []
    rows = _cells(sec.html)
    assert rows[0] == ["ring/rcast #0", "run", "runs/r0", "7", "0123456789ab", "tlm 0.9, numpy 2.0", "1.75"]
    assert rows[1][-1] == "1.75 (+ 2.0 render, cached)"
    assert rows[2][4:] == ["not recorded", "not recorded", "None"]
    config = sec.html.split("ring/rcast #1: resolved config</summary><pre>")[1].split("</pre>")[0]
    assert yaml.safe_load(config.replace("&lt;", "<").replace("&gt;", ">")) == {"scene": "ring", "note": "<1>"}


def test_a_modified_checkout_and_the_code_fingerprint_are_shown(tmp_path):
    runs = [_run(0, git_modified=True, code_fingerprint="93731cd52fc7e465"),
            _run(1, git_modified=False, code_fingerprint="93731cd52fc7e465"),
            _run(2, git_revision=None, git_modified=None, code_fingerprint="0a0b")]
    rows = _cells(provenance_section(Inputs([], runs=runs), tmp_path).html)
    assert [r[4] for r in rows] == ["0123456789ab (modified, code 93731cd52fc7e465)",
                                    "0123456789ab (code 93731cd52fc7e465)", "not recorded (code 0a0b)"]


def test_code_state_names_tlm_s_own_checkout_only(tmp_path, monkeypatch):
    """The revision is tlm's checkout's, "modified" when a tracked file differs from it, and
    nothing where tlm is not its checkout's ``tlm/`` (a copy in a site-packages inside some
    other git project must not record that project's commit)."""
    import subprocess

    from tlm.experiments import provenance as prov

    state = prov.code_state()
    assert set(state) == {"git_revision", "git_modified", "code_fingerprint"} and len(state["code_fingerprint"]) == 16
    if state["git_revision"] is not None:
        assert state["git_revision"] == prov.git_revision() and isinstance(state["git_modified"], bool)
    other = tmp_path / "project"
    (other / "tlm").mkdir(parents=True)
    subprocess.run(["git", "init", "-q", str(other)], check=True)
    subprocess.run(["git", "-C", str(other), "-c", "user.name=u", "-c", "user.email=u@x", "commit", "-q",
                    "--allow-empty", "-m", "the project's own commit"], check=True)
    monkeypatch.setattr(prov, "__file__", str(other / "venv" / "tlm" / "experiments" / "provenance.py"))
    (other / "venv" / "tlm" / "experiments").mkdir(parents=True)
    assert prov.git_revision() is None and prov.code_state()["git_modified"] is None


def test_configs_past_the_limit_are_left_to_their_folders(tmp_path):
    runs = [_run(i) for i in range(MAX_CONFIGS + 2)]
    sec = provenance_section(Inputs([], runs=runs), tmp_path)
    assert len(_cells(sec.html)) == MAX_CONFIGS + 2 and sec.html.count("resolved config</summary>") == MAX_CONFIGS
    assert sec.notes == [f"The resolved configs of the first {MAX_CONFIGS} of {MAX_CONFIGS + 2} runs are listed; "
                         "every run's is its folder's config.resolved.yaml."]


def test_a_study_folder_with_and_without_provenance(tmp_path):
    prov = {"study": "configs/thesis.yaml", "git_revision": "fedcba9876543210", "versions": {"python": "3.11"},
            "host_seconds": 12.5}
    studies = [Study("thesis", Path("th"), [], {"provenance": prov, "host_seconds": {"ring": 3.0},
                                                "config": {"scene": "ring"}}),
               Study("scaling", Path("old"), [])]
    sec = provenance_section(Inputs([], studies=studies), tmp_path)
    assert ("<p>thesis folder th: study configs/thesis.yaml, git fedcba987654, python 3.11, host 12.5 s; "
            "host seconds per scene: ring 3.00</p>") in sec.html
    assert "<p>scaling folder old: no provenance.json (written by an older tlm)" in sec.html
    assert "th: resolved config" in sec.html and "old: resolved config" not in sec.html
    assert provenance_section(Inputs([]), tmp_path).absent == "no inputs"
