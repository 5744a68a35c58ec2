"""An interrupted reference resumes from its last finished cycle, to the same bits (h454).

A reference takes minutes (hours on a large scene), and a Ctrl-C, SIGTERM or crash part-way lost every
round: the next run started from round 1. Now its rounds are saved after each cycle
(``references/<key>.partial.npz``) and the next compute of the key resumes from them, giving what an
uninterrupted compute gives under the settings asked for then (or starting over where it cannot).
An interrupt is simulated by making ``reference_round`` raise KeyboardInterrupt at a given round.
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
from tlm.experiments.reference_cache import ReferenceSettings, partial_info, partial_path, store_reference
from tlm.experiments.reference_resume import Partial, Rounds
from tlm.storage import process_tag

# cycles of 2 rounds, at most 6 of them; a tolerance no cycle meets: all 12 rounds
REF = {"photons": 500, "k_nearest": 8, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 12, "spp": 2}
CONFIG = {"scene": "cornell", "mode": "pmap", "resolution": [4, 4], "photons": {"count": 500}, "reference": REF}
VARIES = ("host_seconds", "resumed_from_round", "meta_sha256")  # (all else the same as an uninterrupted compute's;
# the seal is a digest of the rest, host_seconds among it)


def _frame(**ref):
    return load_frame(config_from_dict({**CONFIG, "reference": {**REF, **ref}}))


def _settings(frame):
    return ReferenceSettings.from_config(frame.scene, frame.cfg)


def _rounds(monkeypatch, stop_at: int | None = None) -> list[int]:
    """``reference_round`` counted (the calls list), raising KeyboardInterrupt at call ``stop_at``."""
    real, calls = reference.reference_round, []

    def counted(*a, **k):
        calls.append(1)
        if len(calls) == stop_at:
            raise KeyboardInterrupt
        return real(*a, **k)

    monkeypatch.setattr(reference, "reference_round", counted)
    return calls


def _same(a: dict, b: dict) -> None:
    assert {k: v for k, v in a.items() if k not in VARIES} == {k: v for k, v in b.items() if k not in VARIES}


def _stored(cache, key):
    folder = cache / "references" / key
    return (folder / "reference.npy").read_bytes(), json.loads((folder / "meta.json").read_text())


def test_an_interrupted_reference_resumes_from_its_last_finished_cycle_to_the_same_bits(
        cache, tmp_path, monkeypatch):
    frame = _frame()
    key = reference.reference_key(frame.scene, frame.cfg, _settings(frame))
    _rounds(monkeypatch, stop_at=7)  # (rounds 1-6: cycles 1-3 finished; round 7 starts cycle 4)
    said: list[str] = []
    with pytest.raises(KeyboardInterrupt):
        reference.ensure_reference(frame, compute=True, say=said.append)
    assert not (cache / "references" / key).exists()
    info = partial_info(partial_path(key))
    assert info is not None and info["k"] == 3 and info["strata"] == 2 and info["key"] == key

    calls = _rounds(monkeypatch)
    said.clear()
    found = reference.ensure_reference(frame, compute=True, say=said.append)
    assert len(calls) == 6  # (rounds 7-12 only)
    assert [line for line in said if "resuming from round 6 of a reference interrupted earlier" in line]
    assert found.meta["resumed_from_round"] == 6 and found.meta["rounds"] == 12
    assert found.meta["host_seconds"] >= round(info["seconds"], 3)
    assert not partial_path(key).exists()  # (removed once the reference is stored)
    image, meta = _stored(cache, key)

    other = tmp_path / "other-cache"
    monkeypatch.setenv("TLM_CACHE", str(other))
    calls.clear()
    fresh = reference.ensure_reference(frame, compute=True)
    assert len(calls) == 12 and "resumed_from_round" not in fresh.meta
    image2, meta2 = _stored(other, key)
    assert image == image2  # (the same reference.npy, byte for byte)
    _same(meta, meta2)
    np.testing.assert_array_equal(found.image, fresh.image)


def test_tlm_reference_says_it_resumes(cache, tmp_path, monkeypatch, capsys):
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps(CONFIG))
    _rounds(monkeypatch, stop_at=5)
    assert main(["reference", str(cfg), "--no-progress"]) == 130
    capsys.readouterr()
    calls = _rounds(monkeypatch)
    assert main(["reference", str(cfg), "--no-progress"]) == 1  # (not converged: tolerance 1e-6)
    out = capsys.readouterr().out
    assert "resuming from round 4 of a reference interrupted earlier" in out and len(calls) == 8
    assert not list((cache / "references").glob("*.partial.npz"))


def _interrupted(monkeypatch, frame, key, at: int) -> None:
    _rounds(monkeypatch, stop_at=at)
    with pytest.raises(KeyboardInterrupt):
        reference.compute_reference(frame, None, _settings(frame), key=key)


# the settings asked for when the rounds saved are 4 cycles of 2 (REF, interrupted at round 9); ``errors``: the
# relative standard error of cycles 2-6. Then: whether they are resumed, the rounds computed now, and whether
# they stay once the reference is stored (rounds further than it: for a later compute to a stricter rule)
CASES = {
    "more-rounds": (lambda errors: {"max_rounds": 16}, True, 8, False),
    "fewer-rounds": (lambda errors: {"max_rounds": 6}, False, 6, True),
    "stops-at-the-saved-cycle": (lambda errors: {"max_rounds": 8}, True, 0, False),
    # cycle 3 meets the tolerance (min_rounds keeps cycle 2 from stopping it): it stops before the saved cycle 4
    "tolerance-met-before": (lambda errors: {"min_rounds": 6, "tolerance": errors[1] * (1 + 1e-9)}, False, 6, True),
    "tolerance-met-at-the-saved-cycle": (lambda errors: {"min_rounds": 8, "tolerance": errors[2] * (1 + 1e-9)},
                                         True, 0, False),
    "another-spp": (lambda errors: {"spp": 3}, False, 12, False),
}


@pytest.mark.parametrize("case", list(CASES))
def test_the_rounds_saved_give_what_the_settings_asked_for_now_give(cache, monkeypatch, case):
    asked, resumed, computed, kept = CASES[case]
    first = _frame()
    key = reference.reference_key(first.scene, first.cfg, _settings(first))
    _, whole = reference.compute_reference(first, None, _settings(first))  # (nothing saved: no key)
    assert not partial_path(key).exists()
    _interrupted(monkeypatch, first, key, at=9)
    assert partial_info(partial_path(key))["k"] == 4

    frame = _frame(**asked(whole["standard_error_per_cycle"]))
    settings = _settings(frame)
    assert reference.reference_key(frame.scene, frame.cfg, settings) == key  # (the stopping rule is not keyed)
    calls = _rounds(monkeypatch)
    said: list[str] = []
    image, meta = reference.compute_reference(frame, None, settings, key=key, say=said.append)
    assert len(calls) == computed
    assert len(said) == 1
    assert ("resuming from round 8" if resumed else "not resuming from round 8") in said[0], said
    assert meta.get("resumed_from_round") == (8 if resumed else None)
    if case == "tolerance-met-at-the-saved-cycle":
        assert meta["converged"] and meta["rounds"] == 8
    calls.clear()
    image2, meta2 = reference.compute_reference(frame, None, settings)  # (uninterrupted)
    np.testing.assert_array_equal(image, image2)
    assert image.tobytes() == image2.tobytes()
    _same(meta, meta2)
    store_reference(key, image.reshape(4, 4, 3), meta, settings)
    assert partial_path(key).exists() == kept


@pytest.mark.parametrize("how", ["garbage", "cut-short", "another-key"])
def test_a_damaged_or_foreign_partial_is_said_in_one_line_and_computed_again(cache, monkeypatch, capsys, how):
    frame = _frame(max_rounds=8)
    key = reference.reference_key(frame.scene, frame.cfg, _settings(frame))
    path = partial_path(key)
    if how == "garbage":
        path.parent.mkdir(parents=True)
        path.write_bytes(b"not an npz\n")
    else:
        other = "0" * 20
        _interrupted(monkeypatch, frame, other if how == "another-key" else key, at=5)
        if how == "another-key":
            partial_path(other).rename(path)
        else:
            data = path.read_bytes()
            path.write_bytes(data[: len(data) // 2])
    calls = _rounds(monkeypatch)
    said: list[str] = []
    found = reference.ensure_reference(frame, compute=True, say=said.append)
    lines = [line for line in said if "interrupted earlier" in line]
    assert len(lines) == 1 and "are ignored and removed" in lines[0] and str(path) in lines[0], said
    assert "\n" not in lines[0] and "Traceback" not in capsys.readouterr().err
    if how == "another-key":
        assert "holds the rounds of reference '00000000000000000000'" in lines[0]
    assert len(calls) == 8 and "resumed_from_round" not in found.meta
    assert not path.exists()


def test_a_damaged_partial_is_a_warning_where_no_say_is_given(cache, capsys):
    frame = _frame(max_rounds=4)
    key = reference.reference_key(frame.scene, frame.cfg, _settings(frame))
    partial_path(key).parent.mkdir(parents=True)
    partial_path(key).write_bytes(b"\x00" * 10)
    reference.compute_reference(frame, None, _settings(frame), key=key)
    err = capsys.readouterr().err.splitlines()
    assert len([line for line in err if "are ignored and removed" in line]) == 1


def test_a_process_behind_does_not_replace_the_rounds_of_one_ahead(cache, monkeypatch):
    """Two processes computing one key save the same rounds (the same seeds) into one file, each through
    a temporary file of its own: the one behind leaves the one ahead's rounds."""
    key, pixels = "ab" * 10, 4
    ahead, behind = Partial(key, 2, pixels), Partial(key, 2, pixels)

    def rounds(k):
        return Rounds(k, np.full((pixels, 3), float(k)), np.zeros((pixels, 3)), [0.5] * (k - 1), [0.25] * (k - 1),
                      1.0 * k)

    ahead.save(rounds(3))
    behind.save(rounds(2))
    assert partial_info(partial_path(key))["k"] == 3
    behind.save(rounds(4))
    assert partial_info(partial_path(key))["k"] == 4
    Partial(key, 3, pixels).save(rounds(3))  # (cycles of another length, 9 rounds over 8: replaced)
    assert partial_info(partial_path(key))["strata"] == 3
    assert sorted(p.name for p in (cache / "references").iterdir()) == [f"{key}.partial.npz"]  # (no temporaries)

    # one that starts while another computes the key resumes from its rounds, and says whose they are
    live = f"{process_tag().rpartition('-')[0]}-{os.getppid()}"  # (this machine's, alive: pytest's parent)
    with monkeypatch.context() as m:
        m.setattr(reference_resume, "process_tag", lambda: live)
        ahead.save(rounds(5))
    said: list[str] = []
    got = Partial(key, 2, pixels, said.append).resume(2, 10, 1e-9)
    assert got is not None and got.k == 5 and np.array_equal(got.mean, np.full((pixels, 3), 5.0))
    assert len(said) == 1 and f"resuming from round 10 of a reference that process {os.getppid()} is computing now" \
        in said[0], said


def test_tlm_cache_lists_and_prunes_a_partial_as_an_entry(cache, monkeypatch):
    frame = _frame()
    key = reference.reference_key(frame.scene, frame.cfg, _settings(frame))
    _interrupted(monkeypatch, frame, key, at=5)
    (scanned,) = cache_admin.survey(["references"], cache)
    assert [e.name for e in scanned.entries] == [f"{key}.partial.npz"] and not scanned.other and not scanned.busy
    assert scanned.entries[0].size == partial_path(key).stat().st_size and not scanned.entries[0].leftover
    outcome = cache_admin.prune(["references"], clear=True, home=cache)
    assert [e.name for e in outcome.removed] == [f"{key}.partial.npz"] and not partial_path(key).exists()
