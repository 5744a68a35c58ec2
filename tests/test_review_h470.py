"""Review of 0e37d3d (h470): the interrupted reference's line and the partials, in the cases it missed.

- ``tlm cache`` read each partial's header to name its rounds, and that read was a use of the file (its access
  time, under relatime): a partial listed (or shown by a dry run) was no longer stale, and a prune right after the
  listing kept it as "used meanwhile" (its scan's own read). The header is now read leaving its access time as it
  was, by the one reader of it (``tlm.cache_admin.partial_info``, which ``reference_cache`` re-exports).
- An interrupt after the compute's own saved rounds were replaced by another compute's (of another
  ``reference.spp``) said "before its first rounds were saved"; one whose saves were held off by another compute's
  rounds said nothing of them, nor how to save its own.
"""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import numpy as np

import tlm.experiments.reference as reference
import tlm.experiments.reference_cache as reference_cache
from tlm import cache_admin
from tlm.cli import main
from tlm.experiments.reference_cache import partial_info, partial_rounds
from tlm.experiments.reference_resume import Partial, Rounds

REF = {"photons": 500, "k_nearest": 8, "tolerance": 1e-9, "min_rounds": 2, "max_rounds": 40, "spp": 2}
BASE = {"scene": "cornell", "mode": "pmap", "resolution": [4, 4], "photons": {"count": 500}, "reference": REF}
PIXELS = 16


def _config(tmp_path: Path, **ref) -> Path:
    path = tmp_path / "ref.yaml"
    path.write_text(json.dumps({**BASE, "reference": {**REF, **ref}}))
    return path


def _rounds(k: int) -> Rounds:
    return Rounds(k, np.zeros((PIXELS, 3)), np.zeros((PIXELS, 3)), [0.5] * (k - 1), [0.5] * (k - 1), 1.0)


def _at(monkeypatch, at: int, then) -> None:
    """``reference_round`` counted, ``then()`` called and SIGINT sent at call ``at`` (the command's handler)."""
    real, calls = reference.reference_round, []

    def counted(*a, **k):
        calls.append(1)
        if len(calls) == at:
            then()
            os.kill(os.getpid(), signal.SIGINT)
        return real(*a, **k)

    monkeypatch.setattr(reference, "reference_round", counted)


def _partial(cache: Path) -> Path:
    (path,) = (cache / "references").glob("*.partial.npz")
    return path


def test_a_stale_partial_listed_is_still_stale_and_pruned(cache, tmp_path, monkeypatch, capsys):
    cfg = _config(tmp_path)
    _at(monkeypatch, 7, lambda: None)  # (cycles 1-3 saved: 6 rounds)
    assert main(["reference", str(cfg), "--no-progress"]) == 130
    path = _partial(cache)
    old = time.time() - 30 * 86400
    os.utime(path, (old, old))  # (a partial left a month ago, never read since its save)
    capsys.readouterr()
    assert main(["cache"]) == 0
    assert "6 rounds saved by an interrupted compute" in capsys.readouterr().out
    assert main(["cache", "prune", "--older-than", "7d", "--dry-run"]) == 0
    assert "would remove 1 entry" in capsys.readouterr().out  # (not refreshed by the listing)
    assert main(["cache", "prune", "--older-than", "7d"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("removed 1 entry") and "used meanwhile" not in out
    assert not path.exists()


def test_one_reader_of_a_partials_header(cache):
    assert reference_cache.partial_info is cache_admin.partial_info
    assert reference_cache.partial_rounds is cache_admin.partial_rounds
    fifo = cache / "references" / f"{'a' * 20}.partial.npz"
    fifo.parent.mkdir(parents=True)
    os.mkfifo(fifo)
    assert partial_info(fifo) is None  # (no regular file: not waited on)


def test_its_rounds_replaced_by_another_computes_are_said(cache, tmp_path, monkeypatch, capsys):
    cfg = _config(tmp_path)

    def replace():  # (another compute of the key, cycles of 4 rounds, 20 rounds: more than its 8, saved over them)
        path = _partial(cache)
        assert partial_rounds(partial_info(path)) == 8
        Partial(partial_info(path)["key"], 4, PIXELS).save(_rounds(5))

    _at(monkeypatch, 9, replace)  # (cycles 1-4 saved: 8 rounds)
    assert main(["reference", str(cfg), "--no-progress"]) == 130
    path = _partial(cache)
    assert partial_rounds(partial_info(path)) == 20
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        f"tlm: interrupted while computing the reference: its 8 rounds saved in {path} were replaced by another "
        "compute's 20 rounds, which the same command does not resume; the same command computes it from round 1")


def test_saves_held_off_by_another_computes_rounds_are_said_with_the_way_out(cache, tmp_path, monkeypatch, capsys):
    cfg = _config(tmp_path)
    _at(monkeypatch, 5, lambda: None)  # (its 4 rounds saved, to learn the key)
    assert main(["reference", str(cfg), "--no-progress"]) == 130
    path = _partial(cache)
    key = partial_info(path)["key"]
    path.unlink()
    Partial(key, 4, PIXELS).save(_rounds(6))  # (a long compute of cycles of 4 rounds, interrupted: 24 rounds)
    _at(monkeypatch, 11, lambda: None)  # (10 rounds of its own, fewer than 24: none saved)
    capsys.readouterr()
    assert main(["reference", str(cfg), "--no-progress"]) == 130
    assert partial_rounds(partial_info(path)) == 24
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "tlm: interrupted while computing the reference, before its first rounds were saved (the 24 rounds kept in "
        f"{path} are another compute's, which it does not resume nor save over with fewer: remove the file to save "
        "its own): the same command computes it from round 1")
