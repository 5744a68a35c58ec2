"""h286: report_claimed refuses a report's folder with tlm.report.check_out, the check the report's
write makes (it had a copy of it: check_destination, and '; give --out' for the default DIR/report)."""

from __future__ import annotations

import tlm.report as report
from tlm.cli_report import report_claimed


def test_report_claimed_refuses_a_folder_as_check_out_does(tmp_path, monkeypatch):
    seen = []
    real = report.check_out
    monkeypatch.setattr(report, "check_out", lambda *a, **k: seen.append(a) or real(*a, **k))
    with report_claimed(tmp_path / "out"):
        pass
    with report_claimed(tmp_path / "d" / "report", of=str(tmp_path / "d")):
        pass
    with report_claimed(tmp_path / "e" / "report", wait=lambda holder: None):
        pass
    assert seen == [(tmp_path / "out", []), (None, [tmp_path / "d"]), (tmp_path / "e" / "report", [])]
