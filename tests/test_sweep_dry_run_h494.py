"""h494: a sweep's --dry-run and its report say what the sweep does with its folder.

1. h489 made a sweep remove its folder's earlier ``report/`` as it claims the folder (kept where it is of the very
   rows the sweep leaves), but ``tlm sweep --dry-run`` did not say so: it now has a line where the report would go
   (sweep_folder.report_goes, the rule drop_report follows), none where it would be kept or there is none.
2. The report's note on point folders not the sweep's still gave three possible causes ("of other tlm code, another
   config or a different --set"): it now says what their results.json's code_fingerprint tells (the folder's
   sweep.yaml is the latest sweep's, so the earlier sweep's settings cannot be compared at report time).
"""

from __future__ import annotations

import html
import json
import re
from pathlib import Path

import pytest

import tlm.fingerprint as fingerprint
from tests.test_sweep_folder_h489 import _run, _sweep
from tlm.cli import main

GONE = "the report of the folder's earlier sweep, removed as the sweep claims the folder"


def _dry(path: str, out: Path, capsys, *args: str) -> str:
    capsys.readouterr()
    assert main(["sweep", path, "--out", str(out), "--dry-run", *args]) == 0
    return capsys.readouterr().out


def _note(out: Path) -> str:
    """The report's words on the point folders not the sweep's."""
    text = " ".join(html.unescape(re.sub(r"<[^>]+>", " ", (out / "report" / "report.html").read_text())).split())
    return text[text.index("point folder"):]


@pytest.mark.slow
def test_the_dry_run_says_the_earlier_report_goes(tmp_path, cache, capsys):
    out = tmp_path / "X"
    r1 = _sweep(tmp_path, "r1.yaml", [16, 256])
    assert GONE not in _dry(r1, out, capsys)  # (no folder yet: no report)
    assert _run(r1, out) == 0
    assert GONE not in _dry(r1, out, capsys)  # (the same sweep, its points done: the report is of its rows, kept)
    r4 = _sweep(tmp_path, "r4.yaml", [16, 1024])
    said = _dry(r4, out, capsys)
    assert f"  {out / 'report'}: {GONE}" in said  # (the old code: nothing said)
    assert json.loads(_dry(r1, out, capsys, "--json"))["report_removed"] is False
    assert json.loads(_dry(r4, out, capsys, "--json"))["report_removed"] is True
    assert GONE in _dry(r1, out, capsys, "--set", "resolution=[6,6]")  # (another --set: other rows)
    assert (out / "report" / "report.html").is_file()  # (a dry run removes nothing)
    assert _run(r4, out, "--no-report") == 0  # (as it said)
    assert not (out / "report").exists()
    assert GONE not in _dry(r4, out, capsys)  # (none there)


@pytest.mark.slow
def test_the_reports_note_says_the_other_folders_code(tmp_path, cache, monkeypatch):
    out = tmp_path / "C"
    path = _sweep(tmp_path, "c.yaml", [16, 256])
    code = fingerprint.code_fingerprint()
    monkeypatch.setattr(fingerprint, "_CODE", "0123456789abcdef")  # (not the disk's: as before an edit)
    assert _run(path, out, "--no-report") == 0
    monkeypatch.setattr(fingerprint, "_CODE", code)
    assert _run(path, out) == 0  # (its report written after its points, by tlm report's code)
    note = _note(out)
    assert note.startswith(
        "point folders in C/points are not this sweep's: left by an earlier run into the folder of other tlm code "
        f"(code_fingerprint 0123456789abcdef in their results.json, this sweep's {code}); nothing reads them")
    assert "another config" not in note  # (the old code: three possible causes)
    assert _run(_sweep(tmp_path, "c.yaml", [16, 1024]), out) == 0  # (this code, other values: 1 folder more)
    note = _note(out)
    assert note.startswith(
        "point folders in C/points are not this sweep's: left by an earlier run into the folder of other tlm code "
        f"(code_fingerprint 0123456789abcdef in their results.json, this sweep's {code}): 2 of them; 1 more of "
        "this sweep's tlm code, so of another config, a different --set or an edited input file; nothing reads them")


def test_what_the_code_of_folders_tells(tmp_path):
    from tlm.experiments.sweep_folder import code_said

    def point(name: str, code: str | None) -> Path:
        folder = tmp_path / name
        folder.mkdir()
        if code is not None:
            (folder / "results.json").write_text(json.dumps({"code_fingerprint": code}))
        return folder

    a, b, c = point("a", "aaaa"), point("b", "bbbb"), point("c", None)
    assert code_said([a], "bbbb", "this sweep's") == (
        "other tlm code (code_fingerprint aaaa in its results.json, this sweep's bbbb)")
    assert code_said([b], "bbbb", "this sweep's") == (
        "this sweep's tlm code (code_fingerprint bbbb in its results.json), so of another config, a different --set "
        "or an edited input file")
    assert code_said([a, c], "bbbb", "this sweep's") is None  # (a point that failed: its code untold)
    assert code_said([], "bbbb", "this sweep's") is None
