"""Saved reference rounds (``references/<key>.partial.npz``): ``tlm cache`` says they are a partial and how many
rounds they hold, and a compute that cannot resume them never saves over more rounds than its own (h462).

The key does not hold ``reference.spp`` nor the stopping rule: a quick compute of another ``spp`` after a long one
interrupted is a compute of the same key, whose cycles (of another length) cannot resume the long one's rounds.
Its first save replaced them (8 rounds by 1): now they are kept, and said to be.
"""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

import tlm.experiments.reference as reference
from tlm import cache_admin
from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments import reference_resume
from tlm.experiments.loading import load_frame
from tlm.experiments.reference_cache import ReferenceSettings, partial_info, partial_path
from tlm.experiments.reference_resume import Partial, Rounds
from tlm.storage import process_tag

from .test_reference_resume_h454 import _rounds  # (one stand-in)

# cycles of 2 rounds, at most 6 of them; a tolerance no cycle meets: all 12 rounds
REF = {"photons": 500, "k_nearest": 8, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 12, "spp": 2}
CONFIG = {"scene": "cornell", "mode": "pmap", "resolution": [4, 4], "photons": {"count": 500}, "reference": REF}


def _frame(**ref):
    frame = load_frame(config_from_dict({**CONFIG, "reference": {**REF, **ref}}))
    settings = ReferenceSettings.from_config(frame.scene, frame.cfg)
    return frame, settings, reference.reference_key(frame.scene, frame.cfg, settings)


def _long_one_interrupted(monkeypatch) -> tuple:
    """The long compute (12 rounds in cycles of 2) interrupted at round 9: 4 cycles saved, 8 rounds."""
    frame, settings, key = _frame()
    _rounds(monkeypatch, stop_at=9)
    with pytest.raises(KeyboardInterrupt):
        reference.compute_reference(frame, None, settings, key=key)
    assert (partial_info(partial_path(key))["k"], partial_info(partial_path(key))["strata"]) == (4, 2)
    return frame, settings, key


def _resumes_to_the_same_bits(monkeypatch, frame, settings, key) -> None:
    """The long compute run again resumes from its round 8, to the bits of one never interrupted."""
    calls = _rounds(monkeypatch)
    said: list[str] = []
    image, meta = reference.compute_reference(frame, None, settings, key=key, say=said.append)
    assert meta["resumed_from_round"] == 8 and len(calls) == 4, said
    image2, meta2 = reference.compute_reference(frame, None, settings)  # (uninterrupted, nothing saved)
    assert image.tobytes() == image2.tobytes()
    varies = ("host_seconds", "resumed_from_round")
    assert {k: v for k, v in meta.items() if k not in varies} == {k: v for k, v in meta2.items() if k not in varies}


@pytest.mark.parametrize("interrupted", [False, True])
def test_a_quick_compute_of_another_spp_keeps_a_longer_ones_rounds(cache, monkeypatch, interrupted):
    frame, settings, key = _long_one_interrupted(monkeypatch)
    quick, quick_settings, quick_key = _frame(spp=1, max_rounds=4)  # (cycles of 1 round: its saves are small)
    assert quick_key == key  # (spp and the stopping rule are not keyed)
    calls = _rounds(monkeypatch, stop_at=4 if interrupted else None)
    said: list[str] = []
    if interrupted:  # (after its rounds 1-3, each a cycle it would have saved)
        with pytest.raises(KeyboardInterrupt):
            reference.compute_reference(quick, None, quick_settings, key=key, say=said.append)
    else:
        found = reference.ensure_reference(quick, compute=True, say=said.append)
        assert found.meta["rounds"] == 4 and (cache / "references" / key).is_dir()
    assert len(calls) == 4
    info = partial_info(partial_path(key))
    assert (info["k"], info["strata"]) == (4, 2)  # (not its own cycle 1, 2 or 3: 1 to 3 rounds over 8)
    (line,) = [x for x in said if "not resuming from round 8" in x]
    assert "they are kept, and this compute, of at most 4 rounds, saves none of its own over them" in line, said
    _resumes_to_the_same_bits(monkeypatch, frame, settings, key)


def test_a_longer_compute_of_another_spp_saves_in_their_place_once_it_has_as_many_rounds(cache, monkeypatch):
    _long_one_interrupted(monkeypatch)
    other, other_settings, _ = _frame(spp=1, max_rounds=12)  # (cycles of 1 round, 12 of them)
    key = _frame()[2]
    _rounds(monkeypatch, stop_at=6)  # (5 rounds done: fewer than the 8 saved)
    said: list[str] = []
    with pytest.raises(KeyboardInterrupt):
        reference.compute_reference(other, None, other_settings, key=key, say=said.append)
    assert (partial_info(partial_path(key))["k"], partial_info(partial_path(key))["strata"]) == (4, 2)
    assert any("they are kept until this compute has as many rounds (8)" in x for x in said), said

    _rounds(monkeypatch, stop_at=11)  # (10 rounds done: its cycles 8, 9 and 10 saved, in place of the 8 rounds)
    with pytest.raises(KeyboardInterrupt):
        reference.compute_reference(other, None, other_settings, key=key)
    assert (partial_info(partial_path(key))["k"], partial_info(partial_path(key))["strata"]) == (10, 1)
    calls = _rounds(monkeypatch)
    image, meta = reference.compute_reference(other, None, other_settings, key=key)
    assert meta["resumed_from_round"] == 10 and len(calls) == 2
    image2, _ = reference.compute_reference(other, None, other_settings)
    assert image.tobytes() == image2.tobytes()


def test_a_kept_partial_is_a_warning_where_no_say_is_given(cache, monkeypatch, capsys):
    _long_one_interrupted(monkeypatch)
    quick, quick_settings, key = _frame(spp=1, max_rounds=4)
    _rounds(monkeypatch)
    capsys.readouterr()
    reference.compute_reference(quick, None, quick_settings, key=key)
    lines = [x for x in capsys.readouterr().err.splitlines() if "not resuming from round 8" in x]
    assert len(lines) == 1 and "warning" in lines[0] and "they are kept" in lines[0], lines
    assert partial_info(partial_path(key))["strata"] == 2


def test_rounds_of_the_other_engine_are_not_saved_over_by_fewer(cache, monkeypatch):
    key, pixels = "ab" * 10, 4

    def rounds(k):
        return Rounds(k, np.full((pixels, 3), float(k)), np.zeros((pixels, 3)), [0.5] * (k - 1), [0.25] * (k - 1),
                      1.0 * k)

    Partial(key, 2, pixels).save(rounds(4))  # (8 rounds)
    other = Partial(key, 2, pixels)
    other.kind["engine"] = "the other engine"
    other.save(rounds(3))  # (6 rounds: kept aside)
    assert partial_info(partial_path(key))["engine"] != "the other engine"
    other.save(rounds(4))  # (as many: saved in their place)
    assert partial_info(partial_path(key))["engine"] == "the other engine"


# ----------------------------------------------------------------------------------------- tlm cache


def _cli(capsys, *argv) -> tuple[int, str]:
    capsys.readouterr()
    status = main(["cache", *argv])
    return status, capsys.readouterr().out


def test_tlm_cache_says_a_partial_and_its_rounds(cache, monkeypatch, capsys):
    key = _long_one_interrupted(monkeypatch)[2]
    name = f"references/{key}.partial.npz"
    words = "8 rounds saved by an interrupted compute"
    status, out = _cli(capsys)
    assert status == 0 and f"{name}: partial: {words} (" in out, out
    status, out = _cli(capsys, "--json", "--cache", "references")
    (rec,) = json.loads(out)["caches"]
    assert rec["entries"] == 1 and [(p["entry"], p["partial_rounds"], p["partial"], p["being_written"])
                                    for p in rec["partials"]] == [(name, 8, words, False)]
    status, out = _cli(capsys, "clear", "--dry-run")
    assert status == 0 and f"would remove {name} (" in out and f"; partial: {words})" in out, out
    status, out = _cli(capsys, "clear", "--dry-run", "--json")
    assert [(r["entry"], r["partial_rounds"]) for r in json.loads(out)["removed"]] == [(name, 8)]
    status, out = _cli(capsys, "clear")
    assert status == 0 and "removed 1 entry" in out and f"(1 partial: {words})" in out, out
    assert not partial_path(key).exists()


def test_a_partial_a_live_compute_is_saving_is_being_written_and_left_alone(cache, monkeypatch, capsys):
    key, pixels = "cd" * 10, 4
    live = f"{process_tag().rpartition('-')[0]}-{os.getppid()}"  # (this machine's, alive: pytest's parent)
    monkeypatch.setattr(reference_resume, "process_tag", lambda: live)
    Partial(key, 3, pixels).save(Rounds(2, np.ones((pixels, 3)), np.zeros((pixels, 3)), [0.5], [0.25], 2.0))
    (scanned,) = cache_admin.survey(["references"], cache)
    assert not scanned.entries and scanned.busy == [partial_path(key)]
    assert scanned.partials[0].partial == f"6 rounds saved so far by process {os.getppid()}, computing it now"
    status, out = _cli(capsys)
    assert f"partial: 6 rounds saved so far by process {os.getppid()}, computing it now" in out, out
    status, out = _cli(capsys, "clear")
    assert status == 0 and "removed 0 entries" in out and "left alone: 1 being written" in out, out
    assert partial_path(key).exists()


def test_a_damaged_partial_is_listed_as_one_whose_rounds_cannot_be_read(cache, capsys):
    path = partial_path("ef" * 10)
    path.parent.mkdir(parents=True)
    path.write_bytes(b"not an npz\n")
    status, out = _cli(capsys)
    assert status == 0 and f"references/{path.name}: partial: its rounds cannot be read" in out, out
    status, out = _cli(capsys, "clear")
    assert "(1 partial: 1 unreadable)" in out and not path.exists(), out
