"""A report leaves the objects the process held before it out of the garbage collector's passes.

The report of a small run cost about as much as the run. Part of it was the cyclic garbage
collector: a report makes and drops many objects (each figure's artists, ticks and texts), and
each full pass they set off scanned every object of the process again (after a run, about 180,000:
the kernels', the scene's, matplotlib's, the run's own), 0.11 - 0.19 s a pass of a report's 1.5 s.
Now :func:`tlm.report.build_report` freezes the objects it finds (:func:`gc.freeze`) while the
figures are made and gives them back at its end (:func:`gc.unfreeze`), also when it fails; a
caller's own freeze, or a collector turned off, it leaves as it is. The figures are not touched.

The inputs are a sweep folder of rows only (``sweep.yaml``, ``sweep.jsonl``): all its figures read.
"""

from __future__ import annotations

import gc
import json
from pathlib import Path

import pytest
import yaml

import tlm.report.sweeps
from tlm.report import build_report


def sweep_folder(folder: Path) -> Path:
    folder.mkdir(parents=True)
    (folder / "sweep.yaml").write_text(yaml.safe_dump({"sweep": "s.yaml", "description": "16x16 Cornell RCast",
                                                       "grid": {"arch.packet_size": [1, 16, 256]}}))
    rows = [{"point": i, "hash": f"h{i:02d}", "status": "ok", "arch.packet_size": p, "scene": "cornell",
             "mode": "rcast", "fps": 100.0 + p, "cycles.throughput": 6e8 / (100.0 + p)}
            for i, p in enumerate((1, 16, 256))]
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


@pytest.fixture
def seen(monkeypatch):
    """What the sweeps section sees of the collector as it is drawn: the objects frozen then, and
    whether an object made before the report is among them (``older``); ``fail``: it raises."""
    state: dict = {"older": object.__new__(type("Older", (), {})), "fail": False}  # (tracked by the collector)
    make = tlm.report.sweeps.sweeps_section

    def watched(inputs, out):
        state["frozen"] = gc.get_freeze_count()
        state["older_frozen"] = gc.is_tracked(state["older"]) and not any(
            o is state["older"] for o in gc.get_objects())  # (get_objects lists no frozen object)
        if state["fail"]:
            raise RuntimeError("a section failed")
        return make(inputs, out)

    monkeypatch.setattr(tlm.report.sweeps, "sweeps_section", watched)
    return state


@pytest.fixture(autouse=True)
def collector_as_found():
    """Each test leaves the collector as it found it (on, nothing frozen), whatever it asserted."""
    enabled = gc.isenabled()
    gc.unfreeze()
    yield
    gc.unfreeze()
    (gc.enable if enabled else gc.disable)()


def test_the_older_objects_are_frozen_while_the_figures_are_made_and_given_back(tmp_path, seen):
    page = build_report([sweep_folder(tmp_path / "sw")], tmp_path / "rep")
    assert page.is_file() and list((tmp_path / "rep").glob("*.png"))
    assert seen["frozen"] > 1000 and seen["older_frozen"]  # (a Python process holds tens of thousands)
    assert gc.get_freeze_count() == 0  # given back: collected as before
    assert any(o is seen["older"] for o in gc.get_objects())


def test_given_back_when_the_report_fails(tmp_path, seen):
    seen["fail"] = True
    with pytest.raises(RuntimeError, match="a section failed"):
        build_report([sweep_folder(tmp_path / "sw")], tmp_path / "rep")
    assert seen["frozen"] > 1000 and seen["older_frozen"]
    assert gc.get_freeze_count() == 0
    assert not (tmp_path / "rep").exists()  # (the folder is written whole or not at all, as before)


def test_a_callers_freeze_and_a_collector_turned_off_are_left_as_they_are(tmp_path, seen):
    sw = sweep_folder(tmp_path / "sw")
    build_report([sw], tmp_path / "plain")
    assert seen["frozen"] > 1000  # (frozen by the report itself)
    gc.freeze()  # the caller's own: the report neither freezes more nor undoes it at its end
    seen["older"] = object.__new__(type("Younger", (), {}))  # (made after the caller's freeze)
    build_report([sw], tmp_path / "frozen")
    assert not seen["older_frozen"] and gc.get_freeze_count() > 1000
    gc.unfreeze()
    gc.disable()  # the collector off: nothing is frozen, and it stays off
    build_report([sw], tmp_path / "off")
    assert seen["frozen"] == 0 and not gc.isenabled() and gc.get_freeze_count() == 0
    gc.enable()
    names = {p.name for p in (tmp_path / "plain").glob("*.png")}
    for other in ("frozen", "off"):  # the same figures, byte for byte
        assert {p.name for p in (tmp_path / other).glob("*.png")} == names
        for n in names:
            assert (tmp_path / other / n).read_bytes() == (tmp_path / "plain" / n).read_bytes()
