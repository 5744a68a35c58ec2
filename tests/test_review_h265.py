"""Review of fb823e9 (h265): a failed point's error folder and a concurrent sweep's good folder of the same point.
write_error asked (under the lock) whether the folder held finished results, and where not wrote an error folder
with atomic_folder: a good folder another sweep swapped in after the question (before atomic_folder began, or
while it wrote) was refused, with a refusal in place of the point's own error and the error folder left beside
the points as ``<hash>.unsaved-<pid>``. Now atomic_folder's ``into`` asks again under the lock at the swap: the
error.json goes beside the good results, as where they were there at the question."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from tlm import storage
from tlm.experiments import sweep_point
from tlm.experiments.sweep_point import Task, run_point
from tlm.storage import atomic_folder

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False, "packet_size": 16}}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def results(out: Path) -> str:
    return storage.json_text({"tlm": sweep_point.POINT_FORMAT, "hash": out.name, "tag": "good",
                              **{k: {} for k in ("cycles", "timing", "functional", "host_seconds")}})


def other_sweep_swaps_in(out: Path) -> None:
    """Another sweep of the same point puts its good folder in place (run_point's write, over an error folder)."""
    with atomic_folder(out, "results.json", sweep_point.POINT_FILES, clean_once=True, replaces=("error.json",)) as tmp:
        (tmp / "results.json").write_text(results(out))


@pytest.mark.parametrize("before", ["nothing", "an earlier error"])
@pytest.mark.parametrize("when", ["before the folder's write began", "while it was written"])
def test_a_good_folder_swapped_in_after_the_question_keeps_its_results(tmp_path, monkeypatch, when, before):
    out = tmp_path / "points" / "abc123"
    if before == "an earlier error":
        with atomic_folder(out, "error.json", sweep_point.POINT_FILES) as tmp:
            (tmp / "error.json").write_text("{}\n")
    if when == "before the folder's write began":  # (between write_into's question and atomic_folder's start)
        real = storage.write_into

        def write_into(*a, **kw):
            got = real(*a, **kw)
            other_sweep_swaps_in(out)
            return got

        monkeypatch.setattr(storage, "write_into", write_into)
    else:  # (while write_error writes its folder: before the swap)
        monkeypatch.setattr(sweep_point, "config_text", lambda config: other_sweep_swaps_in(out) or "x: 1\n")
    sweep_point.write_error(SimpleNamespace(hash=out.name, factors={"f": 1}, out=str(out), config={}),
                            {"type": "Boom", "message": "boom"})
    assert json.loads((out / "results.json").read_text())["tag"] == "good"
    assert json.loads((out / "error.json").read_text()) == {"hash": out.name, "factors": {"f": 1}, "type": "Boom",
                                                            "message": "boom"}
    assert sorted(p.name for p in out.parent.iterdir()) == [out.name]  # (no .unsaved, no temporary folder)
    assert sorted(p.name for p in out.iterdir()) == ["error.json", "results.json"]  # (the good folder's config)


def test_into_at_the_swap_puts_the_marker_only_and_leaves_nothing(tmp_path):
    """The folder ``into`` keeps gets the block's marker, not its other files; a folder it does not keep is
    replaced as ever; no folder: the new one."""
    out = tmp_path / "o"
    with atomic_folder(out, "m", {"m", "a"}, into=lambda folder: (folder / "keep").exists()) as tmp:
        (tmp / "m").write_text("1")
    assert sorted(p.name for p in out.iterdir()) == ["m"]
    with atomic_folder(out, "m", {"m", "a"}, into=lambda folder: (folder / "keep").exists()) as tmp:
        (tmp / "m").write_text("2")
        (tmp / "a").write_text("a")
        (out / "keep").write_text("k")  # (a user's file, the folder now one to keep)
    assert sorted(p.name for p in out.iterdir()) == ["keep", "m"] and (out / "m").read_text() == "2"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]
    (out / "keep").unlink()
    with atomic_folder(out, "m", {"m", "a"}, into=lambda folder: (folder / "keep").exists()) as tmp:
        (tmp / "m").write_text("3")
        (tmp / "a").write_text("a")
    assert sorted(p.name for p in out.iterdir()) == ["a", "m"] and (out / "m").read_text() == "3"


def test_a_good_point_replaces_an_error_folder_a_concurrent_sweep_put_there_meanwhile(tmp_path, monkeypatch):
    """The mirror case: a sweep removes a failed point's folder before it runs the point again, and a concurrent
    sweep's failed try of the same point puts its error folder there while this one runs: the good folder was
    refused at its swap (no results.json there), the point failed with that refusal and its results were left in
    ``points/<hash>.unsaved-<pid>``. Now an error folder is one a point's results replace."""
    (tmp_path / "sweep.yaml").write_text("{}\n")
    out = tmp_path / "points" / "p"
    real = sweep_point.config_text

    def config_text(config):  # (while this point's folder is written: the other sweep's error folder arrives)
        if not out.exists():
            with atomic_folder(out, "error.json", sweep_point.POINT_FILES) as tmp:
                (tmp / "error.json").write_text("{}\n")
        return real(config)

    monkeypatch.setattr(sweep_point, "config_text", config_text)
    got = run_point(Task("h", BASE, {}, str(tmp_path), "sweep.yaml", str(out), {}))
    assert got["status"] == "ok", got.get("error")
    assert sorted(p.name for p in out.iterdir()) == ["config.resolved.yaml", "results.json"]
    assert sorted(p.name for p in out.parent.iterdir()) == ["p"]
