"""Review of an interrupted reference's resume (h458, of h454's commit 6eab8a3).

* A save is 48 bytes a pixel (100 MB at 1080p, about 0.5 s) and came after every cycle: 9% of a short
  1080p cycle (1000 photons, k 8, one round: 5.4 s). One larger than ``SMALL_SAVE`` now waits
  ``SAVE_SECONDS`` after the last save; what is saved is still a cycle's end, so the resume gives the
  same bits. (The clock is the module's ``_now``, stepped here: nothing is timed.)
* A cache folder too full for a save made the write fail and tlm say the reference cache cannot be
  written ("photon-map references are computed again by every run") although the reference itself, a
  quarter of the size, was stored: now one line of its own, once, and no save tried.
* Rounds saved by a tlm of another layout (a newer one's) were "damaged": a warning, and removed. Now
  one line, and left for that tlm.
"""

from __future__ import annotations

import itertools
import json
import shutil
from collections import namedtuple

import numpy as np
import pytest

import tlm.experiments.reference as reference
from tlm.config import config_from_dict
from tlm.experiments import reference_resume
from tlm.experiments.loading import load_frame
from tlm.experiments.reference_cache import ReferenceSettings, drop_partial, partial_info, partial_path
from tlm.experiments.reference_resume import Partial, Rounds

from .test_reference_resume_h454 import _rounds as _interrupt_at  # (reference_round counted, interrupted at a call)

# cycles of 2 rounds, at most 6 of them; a tolerance no cycle meets: all 12 rounds
REF = {"photons": 500, "k_nearest": 8, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 12, "spp": 2}
CONFIG = {"scene": "cornell", "mode": "pmap", "resolution": [4, 4], "reference": REF}


def _frame():
    frame = load_frame(config_from_dict(CONFIG))
    settings = ReferenceSettings.from_config(frame.scene, frame.cfg)
    return frame, settings, reference.reference_key(frame.scene, frame.cfg, settings)


def test_a_large_save_waits_save_seconds_and_the_resume_gives_the_same_bits(cache, tmp_path, monkeypatch):
    frame, settings, key = _frame()
    monkeypatch.setattr(reference_resume, "SMALL_SAVE", 0, raising=False)  # (every save "large")
    clock = itertools.count(0.0, 25.0)  # (25 s a call: the start 0, cycles' ends 25, 50, 75 saved, then 125...)
    monkeypatch.setattr(reference_resume, "_now", lambda: next(clock), raising=False)
    _interrupt_at(monkeypatch, 11)  # (cycles 1-5 finished, round 11 starts cycle 6)
    with pytest.raises(KeyboardInterrupt):
        reference.compute_reference(frame, None, settings, key=key)
    assert partial_info(partial_path(key))["k"] == 3  # (cycle 3 ended 75 s in; cycles 4 and 5 within 60 s of it)

    calls = _interrupt_at(monkeypatch, None)
    said: list[str] = []
    image, meta = reference.compute_reference(frame, None, settings, key=key, say=said.append)
    assert len(calls) == 6 and meta["resumed_from_round"] == 6
    assert [line for line in said if "resuming from round 6" in line], said
    image2, meta2 = reference.compute_reference(frame, None, settings)  # (uninterrupted, nothing saved)
    assert image.tobytes() == image2.tobytes()
    varies = ("host_seconds", "resumed_from_round")
    assert {k: v for k, v in meta.items() if k not in varies} == {k: v for k, v in meta2.items() if k not in varies}


def test_a_folder_too_full_for_a_save_is_said_once_and_the_reference_is_stored(cache, monkeypatch, capsys):
    frame, _, key = _frame()
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage(10**9, 10**9 - 1000, 1000))
    said: list[str] = []
    found = reference.ensure_reference(frame, compute=True, say=said.append)
    lines = [line for line in said if "not saved for a resume" in line]
    assert len(lines) == 1, said  # (5 cycles could have saved: said once)
    assert str(cache / "references") in lines[0] and "1000B free" in lines[0]  # (h516: sizes as tlm shows them)
    assert found.meta["rounds"] == 12 and (cache / "references" / key / "reference.npy").is_file()
    assert not partial_path(key).exists()
    assert "cannot write tlm's reference cache" not in capsys.readouterr().err  # (it could be written)


def test_rounds_of_another_layout_are_left_for_the_tlm_that_saved_them(cache, capsys):
    key, pixels = "cd" * 10, 4
    Partial(key, 2, pixels).save(Rounds(2, np.ones((pixels, 3)), np.zeros((pixels, 3)), [0.5], [0.25], 3.0))
    path = partial_path(key)
    with open(path, "wb") as fh:  # (a newer tlm's layout: other arrays)
        np.savez(fh, info=np.array(json.dumps({"version": 2, "key": key, "k": 7})), state=np.zeros(3))
    before = path.read_bytes()
    said: list[str] = []
    assert Partial(key, 2, pixels, said.append).resume(2, 10, 1e-9) is None
    assert len(said) == 1 and "of layout 2" in said[0] and "removed" not in said[0], said
    assert path.read_bytes() == before
    drop_partial(key, {"rounds_per_cycle": 2, "cycles": 4})  # (a reference of this key stored: not its rounds)
    assert path.read_bytes() == before
    assert "warning" not in capsys.readouterr().err


def test_a_damaged_partial_that_cannot_be_removed_is_not_said_removed(cache, monkeypatch):
    """A read-only cache (which a root user's tests cannot make by chmod: the unlink refused here)."""
    key, pixels = "ef" * 10, 4
    path = partial_path(key)
    path.parent.mkdir(parents=True)
    path.write_bytes(b"not an npz\n")
    real = type(path).unlink

    def refused(self, *a, **k):
        if self == path:
            raise PermissionError(13, "Permission denied", str(self))
        return real(self, *a, **k)

    monkeypatch.setattr(type(path), "unlink", refused)
    said: list[str] = []
    assert Partial(key, 2, pixels, said.append).resume(2, 10, 1e-9) is None
    assert len(said) == 1 and "are ignored (and cannot be removed: permission denied)" in said[0], said
    assert "removed (" not in said[0] and path.exists()
    assert "(it is no .npz file)" in said[0] and "pickle" not in said[0]  # (not numpy's words on a pickle)


def test_a_quick_compute_of_another_spp_that_saved_nothing_leaves_a_longer_ones_rounds(cache, monkeypatch):
    """Rounds of cycles of another length (reference.spp), further than a compute that saved none (its saves
    large, and all within SAVE_SECONDS): they stay once its reference is stored, for the compute they are of."""
    frame, settings, key = _frame()
    _interrupt_at(monkeypatch, 9)
    with pytest.raises(KeyboardInterrupt):
        reference.compute_reference(frame, None, settings, key=key)
    assert partial_info(partial_path(key))["k"] == 4  # (8 rounds, cycles of 2)

    quick = load_frame(config_from_dict({**CONFIG, "reference": {**REF, "spp": 1, "max_rounds": 4}}))
    quick_settings = ReferenceSettings.from_config(quick.scene, quick.cfg)
    assert reference.reference_key(quick.scene, quick.cfg, quick_settings) == key
    monkeypatch.setattr(reference_resume, "SMALL_SAVE", 0, raising=False)  # (every save "large")
    monkeypatch.setattr(reference_resume, "_now", lambda: 0.0, raising=False)  # (none due)
    _interrupt_at(monkeypatch, None)
    found = reference.ensure_reference(quick, compute=True)
    assert found.meta["rounds"] == 4 and (cache / "references" / key).is_dir()
    assert partial_info(partial_path(key))["k"] == 4  # (left: 8 rounds, more than the 4 stored)

    calls = _interrupt_at(monkeypatch, None)
    image, meta = reference.compute_reference(frame, None, settings, key=key)
    assert meta["resumed_from_round"] == 8 and len(calls) == 4
    image2, _ = reference.compute_reference(frame, None, settings)
    assert image.tobytes() == image2.tobytes()
