"""A failed point whose error.json a full disk refuses: its record is the full disk's, so the sweep stops there
(as at a point whose own results a full disk refused), not a failure with a note the sweep does not read as a
full disk (a probe's 12 KiB tmpfs: every point recorded failed, no stop line, nothing written)."""

from __future__ import annotations

from tlm.errors import EnvironmentFailure, InputError
from tlm.experiments import sweep_point
from tlm.storage_errors import says_disk_full


def _task(tmp_path):
    return sweep_point.Task("h", {"scene": "cornell", "nonsense_key": 1}, {}, str(tmp_path), "s.yaml",
                            str(tmp_path / "points" / "h"), {})


def test_a_full_disk_refusing_a_failed_points_error_json_is_its_record(tmp_path, monkeypatch):
    def full(task, error, *who):  # (who ran it, since 81ec1d4)
        raise EnvironmentFailure("cannot write: no space left on device", source=str(tmp_path / "points" / "h"))

    monkeypatch.setattr(sweep_point, "write_error", full)
    got = sweep_point.run_point(_task(tmp_path))
    assert got["status"] == "failed"
    assert says_disk_full(got["error"]["type"], got["error"]["message"]), got["error"]
    assert "nonsense_key" not in got["error"]["message"]


def test_another_refusal_of_its_error_json_keeps_the_points_own_error(tmp_path, monkeypatch):
    def refuse(task, error):
        raise InputError("is an older tlm's results.json", source=str(tmp_path / "points" / "h"))

    monkeypatch.setattr(sweep_point, "write_error", refuse)
    got = sweep_point.run_point(_task(tmp_path))
    assert not says_disk_full(got["error"]["type"], got["error"]["message"])
    assert "nonsense_key" in got["error"]["message"] and "could not be written" in got["error"]["message"]
