"""A long-lived session (a notebook, a script of many runs) and its caches' lines (h319).

A cache found unwritable once stayed in every later result of the process after it was fixed
(:func:`tlm.caches.cache_warnings` returned each line ever noted); one that became unwritable after the
process first looked at it was never said (its folder's ``mkdir`` failed, quietly). Each line now says the
cache as it is for the call that records it, and the stderr line is said once a process per problem.
"""

from __future__ import annotations

import json
import shutil

import yaml

from tlm import api, caches
from tlm.config import config_from_dict
from tlm.experiments import frames

FRAME = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1}}


def _said(err: str, folder) -> list[str]:
    return [line for line in err.splitlines() if line.startswith(f"tlm: warning: cannot write tlm's functional "
                                                                 f"cache {folder} (")]


def test_a_fixed_cache_is_warned_of_no_more_and_a_changed_one_as_it_is(tmp_path, monkeypatch, capsys):
    cache = tmp_path / "c"
    cache.mkdir()
    monkeypatch.setenv("TLM_CACHE", str(cache))
    folder = cache / "functional"
    folder.write_text("in the way\n")
    caches.cache_root("functional")
    assert [w for w in caches.cache_warnings() if str(folder) in w] != []
    assert len(_said(capsys.readouterr().err, folder)) == 1

    folder.unlink()  # (fixed: the next record says nothing of it)
    assert [w for w in caches.cache_warnings() if str(folder) in w] == []

    shutil.rmtree(cache)
    cache.write_text("in the way\n")  # (broken again, another way: its line says this one)
    caches.cache_root("functional")
    lines = [w for w in caches.cache_warnings() if str(folder) in w]
    assert len(lines) == 1 and f"({cache} is a file, not a folder)" in lines[0], lines
    err = capsys.readouterr().err
    assert len(_said(err, folder)) == 1 and f"({cache} is a file" in err
    assert [w for w in caches.cache_warnings() if str(folder) in w] == lines
    assert _said(capsys.readouterr().err, folder) == []  # (said once a process per problem)


def test_a_line_a_failed_write_told_goes_once_a_write_succeeds(tmp_path, monkeypatch):
    """A full disk: looking at the folder cannot tell, the failed write did; a write that succeeds since clears it."""
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "c"))
    entry = caches.cache_root("functional") / "k.npz"
    caches._note_cache_write(entry, OSError(28, "No space left on device"))  # (storage's hearer)
    assert [w for w in caches.cache_warnings() if str(entry.parent) in w] != []
    assert [w for w in caches.cache_warnings() if str(entry.parent) in w] != []  # (looking cannot clear it)
    assert frames.cached_render(config_from_dict({**FRAME, "seed": 3}, "x.yaml")).cached is False  # (written)
    assert any(entry.parent.glob("*.npz"))
    assert [w for w in caches.cache_warnings() if str(entry.parent) in w] == []


def test_a_cache_that_became_unwritable_after_the_first_look_is_said_by_the_next_render(tmp_path, monkeypatch,
                                                                                          capsys):
    cache = tmp_path / "c"
    monkeypatch.setenv("TLM_CACHE", str(cache))
    cfg = config_from_dict(FRAME, "x.yaml")
    assert frames.cached_render(cfg).cached is False
    folder = cache / "functional"
    assert any(folder.glob("*.npz")) and caches.cache_warnings() == []
    capsys.readouterr()

    shutil.rmtree(folder)
    folder.write_text("in the way\n")  # (after this process looked at it: it is not looked at again)
    assert frames.cached_render(config_from_dict({**FRAME, "seed": 7}, "x.yaml")).cached is False
    said = _said(capsys.readouterr().err, folder)
    assert len(said) == 1 and f"({folder} is a file, not a folder)" in said[0], said  # (a fresh process's line)
    assert said[0].removeprefix("tlm: warning: ") in caches.cache_warnings()


def test_the_scene_key_cache_replaced_by_a_file_is_said(tmp_path, monkeypatch, capsys):
    cache = tmp_path / "c"
    monkeypatch.setenv("TLM_CACHE", str(cache))
    (cache / "scenes").mkdir(parents=True)
    caches.cache_root("scenes")  # (looked at: writable)
    shutil.rmtree(cache / "scenes")
    (cache / "scenes").write_text("in the way\n")
    frames._keep_key(("scene", "box.yaml"), "f" * 24, [])
    err = capsys.readouterr().err
    assert f"cannot write tlm's scene cache {cache / 'scenes'} ({cache / 'scenes'} is a file, not a folder)" in err


def test_a_run_and_a_sweep_after_the_cache_is_fixed_record_no_line_of_it(tmp_path, monkeypatch, capsys):
    cache = tmp_path / "c"
    cache.mkdir()
    monkeypatch.setenv("TLM_CACHE", str(cache))
    folder = cache / "functional"
    folder.write_text("in the way\n")
    sweep = tmp_path / "sw.yaml"
    sweep.write_text(yaml.safe_dump({"base": FRAME, "grid": {"arch.pipelines": [1, 2]}}))

    def step(tag: str) -> tuple[list[str], list[str], list[str]]:
        done = api.run_sweep(sweep, tmp_path / f"sw-{tag}", jobs=1)
        api.run(FRAME, tmp_path / f"run-{tag}", outputs=())
        run = json.loads((tmp_path / f"run-{tag}" / "results.json").read_text())["warnings"]
        points = [w for res in (tmp_path / f"sw-{tag}" / "points").glob("*/results.json")
                  for w in json.loads(res.read_text())["warnings"]]
        return ([w for w in done.warnings if str(folder) in w], [w for w in run if str(folder) in w],
                [w for w in points if str(folder) in w])

    assert all(step("broken"))
    assert len(_said(capsys.readouterr().err, folder)) == 1
    folder.unlink()
    assert step("fixed") == ([], [], [])
    assert any(folder.glob("*.npz"))


def test_a_sweep_after_the_cache_became_unwritable_gives_its_line_to_its_warn(tmp_path, monkeypatch, capsys):
    cache = tmp_path / "c"
    monkeypatch.setenv("TLM_CACHE", str(cache))
    folder = cache / "functional"
    for seed in (1, 2):
        (tmp_path / f"s{seed}.yaml").write_text(yaml.safe_dump({"base": {**FRAME, "seed": seed},
                                                                "grid": {"arch.pipelines": [1, 2]}}))
    assert api.run_sweep(tmp_path / "s1.yaml", tmp_path / "one", jobs=1).warnings == []
    shutil.rmtree(folder)
    folder.write_text("in the way\n")
    capsys.readouterr()
    got: list[str] = []
    done = api.run_sweep(tmp_path / "s2.yaml", tmp_path / "two", jobs=1, warn=got.append)
    lines = [w for w in got if w.startswith(f"cannot write tlm's functional cache {folder} ({folder} is a file")]
    assert len(lines) == 1 and lines[0] in done.warnings, got
    assert _said(capsys.readouterr().err, folder) == []  # (said through the sweep's warn, not past it)
