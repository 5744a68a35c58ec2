"""``tlm cache``: what tlm's caches hold (entries made by the real writers), and ``prune``/``clear``
removing whole entries, least recently used first, never a user's file nor a write in progress; a run
after a prune computes what it needs again."""

from __future__ import annotations

import json
import os
import re
import time
from pathlib import Path

import numpy as np
import pytest

from tlm import cache_admin
from tlm.cli import build_parser, main
from tlm.cli_cache import cache_command
from tlm.config import config_from_dict
from tlm.experiments.frames import cached_render
from tlm.experiments.reference_cache import load_reference, save_reference
from tlm.oracle.mitsuba import save_ground_truth
from tlm.scenes import cache as scene_cache
from tlm.storage import process_tag

SMALL = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"light_samples": 1, "spp": 1},
         "arch": {"frames": 1, "trace": False}}
DAY = 86400.0


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py) every test here has its own
    return cache


def aged(paths, days: float) -> None:
    """Every file of ``paths`` (folders: their files) last used ``days`` ago."""
    t = time.time() - days * DAY
    for p in paths:
        for f in ([p] if p.is_file() else [q for q in p.rglob("*") if q.is_file()] + [p]):
            os.utime(f, (t, t))


def a_reference(key: str, pixels: int = 16) -> Path:
    image = np.random.default_rng(0).random((pixels, pixels, 3)).astype(np.float32)
    return save_reference(key, image, {"rounds": 4, "converged": True, "relative_standard_error": 0.01})


def run_cli(capsys, *argv) -> tuple[int, str, str]:
    capsys.readouterr()
    status = main(["cache", *argv])
    out, err = capsys.readouterr()
    return status, out, err


def test_tlm_cache_lists_the_entries_the_real_writers_make(cache, capsys):
    frame = cached_render(config_from_dict(SMALL, "t"))  # functional/<key>.npz + <key>.json
    a_reference("a" * 20)
    save_ground_truth("b" * 20, np.zeros((4, 4, 3)), {"spp": 1})
    tri = np.random.default_rng(2).random((scene_cache.MIN_TRIANGLES, 3, 3))
    scene_cache.crease_normals(tri, np.zeros(len(tri), dtype=np.int64), 30.0, lambda t, p, a: np.ones_like(t))
    from tlm.cli_signals import save_traceback

    assert save_traceback(ValueError("x")).parent == cache / "tracebacks"
    kernels = cache / "numba" / "kernels_1234"
    kernels.mkdir(parents=True)
    for name in ("trace-10.py311.nbi", "trace-10.py311.1.nbc", "trace-10.py311.2.nbc"):
        (kernels / name).write_bytes(b"x" * 100)
    (cache / "functional" / "my notes.txt").write_text("mine")
    assert build_parser().parse_args(["cache"]).func is cache_command
    status, out, _ = run_cli(capsys, "--json")
    assert status == 0
    got = {c["cache"]: c for c in json.loads(out)["caches"]}
    assert {k: v["entries"] for k, v in got.items()} == {"functional": 1, "scenes": 1, "references": 1,
                                                         "oracle": 1, "tracebacks": 1, "numba": 1}
    npz, side = cache / "functional" / f"{frame.key}.npz", cache / "functional" / f"{frame.key}.json"
    assert got["functional"]["bytes"] == npz.stat().st_size + side.stat().st_size
    assert got["numba"]["bytes"] == 300
    assert got["functional"]["not_tlms"] == [str(cache / "functional" / "my notes.txt")]
    status, out, _ = run_cli(capsys)
    assert status == 0
    rows = {line.split()[0]: line.split() for line in out.splitlines()[2:9]}
    assert rows["functional"][1] == "1" and rows["all"][1] == "6" and rows["numba"][2] == "300B"
    assert "not tlm's entries, never removed: 1" in out


def test_a_missing_cache_folder_is_an_empty_cache(cache, capsys):
    status, out, err = run_cli(capsys)
    assert status == 0 and err == "" and ["all", "0", "0B"] in [line.split()[:3] for line in out.splitlines()]
    assert not cache.exists()  # (looking creates nothing)


def test_prune_removes_whole_entries_least_recently_used_first_and_dry_run_nothing(cache, capsys):
    folders = {k: a_reference(k * 20, 32) for k in "abcd"}  # a: used 40 days ago ... d: today
    for k, days in zip("abcd", (40, 20, 10, 0)):
        aged([folders[k]], days)
    entry = sum(f.stat().st_size for f in folders["a"].iterdir())
    status, out, _ = run_cli(capsys, "prune", "--older-than", "15d", "--dry-run")
    lines = out.splitlines()
    assert status == 0 and [line.split()[2] for line in lines[:-1]] == ["references/" + "a" * 20,
                                                                        "references/" + "b" * 20]
    assert lines[-1].startswith("would remove 2 entries") and lines[-1].endswith("nothing removed (--dry-run)")
    assert all(f.is_dir() for f in folders.values())
    status, out, _ = run_cli(capsys, "prune", "--older-than", "15d")
    assert status == 0 and out.startswith(f"removed 2 entries ({cache_admin.human(2 * entry)}) from references")
    assert sorted(p.name for p in (cache / "references").iterdir()) == ["c" * 20, "d" * 20]  # (no folder aside)
    # --max-size: the least recently used go until the rest fit (c before d)
    status, out, _ = run_cli(capsys, "prune", "--max-size", str(entry + 10))
    assert status == 0 and out.startswith("removed 1 entry") and [p.name for p in (cache / "references").iterdir()
                                                                  ] == ["d" * 20]
    status, out, _ = run_cli(capsys, "prune", "--max-size", "1G", "--older-than", "1d")
    assert out.startswith("removed 0 entries") and (cache / "references" / ("d" * 20) / "meta.json").is_file()


def test_a_functional_entry_goes_whole_and_a_run_after_a_prune_computes_it_again(cache, capsys):
    cfg = config_from_dict(SMALL, "t")
    first = cached_render(cfg)
    folder = cache / "functional"
    image = folder / f"{first.key}.pmap.npy"  # (a photon-map frame's third file: removed with its entry)
    np.save(image, np.zeros((64, 3)))
    aged(list(folder.iterdir()), 3)
    status, out, _ = run_cli(capsys, "prune", "--older-than", "2d", "--cache", "functional")
    assert status == 0 and out.startswith("removed 1 entry") and list(folder.iterdir()) == []
    again = cached_render(cfg)  # computed again, quietly, and cached again
    assert not again.cached and capsys.readouterr().err == ""
    assert again.summary["work"] == first.summary["work"] and cached_render(cfg).cached


def test_a_reference_removed_under_its_reader_is_computed_again_and_a_read_marks_it_used(cache, capsys):
    folder = a_reference("e" * 20)
    aged([folder], 30)
    assert load_reference("e" * 20) is not None
    assert time.time() - (folder / "meta.json").stat().st_mtime < 60  # (the read refreshed its last use)
    status, out, _ = run_cli(capsys, "prune", "--older-than", "1d")
    assert out.startswith("removed 0 entries")
    status, out, _ = run_cli(capsys, "clear", "--cache", "references")
    assert status == 0 and out.startswith("removed 1 entry") and not folder.exists()
    assert load_reference("e" * 20) is None and capsys.readouterr().err == ""  # (none: computed again, no warning)


def test_writes_in_progress_and_a_users_files_are_left_alone(cache, capsys):
    folder = cache / "functional"
    folder.mkdir(parents=True)
    key = "f" * 24
    young = folder / f".{key}.npz.tmph{'x' * 8}-{os.getpid()}"  # (write_atomic's temporary name)
    young.write_bytes(b"1" * 10)
    busy = folder / f"{key}.npz"  # (a writer's .npz, its sidecar not yet in place)
    busy.write_bytes(b"2" * 10)
    stale = folder / f".{'9' * 24}.npz.tmphgone-999999999"  # (a killed writer's, hours ago)
    stale.write_bytes(b"3" * 10)
    aged([stale], 0.5)
    mine = [folder / "notes.json", cache / "references" / "README", cache / "my-own-folder" / "x"]
    for p in mine:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text("the user's")
    aged(mine, 400)
    status, out, _ = run_cli(capsys, "clear")
    assert status == 0 and out.startswith("removed 1 entry") and "left alone: 2 being written, 2 not tlm's" in out
    assert young.exists() and busy.exists() and not stale.exists() and all(p.exists() for p in mine)
    aged([busy], 0.5)  # (an hour on, its writer long gone: an entry without its sidecar)
    status, out, _ = run_cli(capsys, "prune", "--older-than", "1h")
    assert out.startswith("removed 1 entry") and not busy.exists() and young.exists()


@pytest.mark.parametrize("argv, said", [
    (["prune", "--older-than", "3x"], "argument --older-than: '3x' is not a duration"),
    (["prune", "--max-size", "-1"], "argument --max-size: '-1' is not a size"),
    (["prune", "--cache", "nope", "--older-than", "1d"], "argument --cache: 'nope' is not one of tlm's caches"),
    (["clear", "--cache", "nope"], "argument --cache: 'nope' is not one of tlm's caches"),
    (["prune"], "give --older-than DURATION and/or --max-size SIZE"),
])
def test_bad_input_is_one_line_exit_2_and_nothing_removed(argv, said, cache, capsys):
    folder = a_reference("c" * 20)
    aged([folder], 100)
    status, out, err = run_cli(capsys, *argv)
    assert status == 2 and out == "" and len(err.splitlines()) == 1 and said in err, err
    assert (folder / "reference.npy").is_file() and (folder / "meta.json").is_file()


def test_the_flags_values():
    assert cache_admin.duration("30d") == 30 * DAY and cache_admin.duration("12h") == 12 * 3600
    assert cache_admin.size("2G") == 2 << 30 and cache_admin.size("500M") == 500 << 20 and cache_admin.size("7") == 7
    assert cache_admin.human(1536) == "1.5K" and cache_admin.human(12) == "12B"
    assert cache_admin.cache_names(["numba", "scenes", "numba"]) == ["scenes", "numba"]


# ---------------------------------------------------------------- a read is a use; a vanished entry a miss


def crease(compute=None) -> tuple[np.ndarray, np.ndarray]:
    """A scene cache entry (crease normals of ``MIN_TRIANGLES`` triangles), made or read: the normals."""
    tri = np.random.default_rng(2).random((scene_cache.MIN_TRIANGLES, 3, 3))
    part = np.zeros(len(tri), dtype=np.int64)
    return scene_cache.crease_normals(tri, part, 30.0, compute or (lambda t, p, a: np.ones_like(t)))


def test_a_frame_or_scene_read_marks_its_entry_used_by_a_time_no_digest_checks(cache, capsys):
    """On a ``noatime`` mount only a modification time tells a use: a read refreshes one file's, and
    the entry then reads back whole (the sidecar's digest is of the ``.npz``'s bytes, not its time)."""
    cfg = config_from_dict(SMALL, "t")
    cached_render(cfg)
    crease()
    entries = [f for name in ("functional", "scenes") for f in (cache / name).iterdir()]
    aged(entries, 30)
    assert cached_render(cfg).cached
    np.testing.assert_array_equal(crease(lambda t, p, a: pytest.fail("computed again")), 1.0)
    for name in ("functional", "scenes"):  # (was: every file's mtime 30 days old, pruned as unused)
        assert time.time() - max(f.stat().st_mtime for f in (cache / name).iterdir()) < 60, name
    status, out, _ = run_cli(capsys, "prune", "--older-than", "1d")
    assert status == 0 and out.startswith("removed 0 entries")
    assert cached_render(cfg).cached and capsys.readouterr().err == ""


@pytest.mark.parametrize("gone", ["sidecar", "npz", "load"])
def test_a_frame_entry_removed_under_its_reader_is_a_quiet_miss_and_a_truncated_one_still_said(gone, cache, capsys,
                                                                                                 monkeypatch):
    from tlm.experiments import frames

    cfg = config_from_dict(SMALL, "t")
    first = cached_render(cfg)
    npz, side = cache / "functional" / f"{first.key}.npz", cache / "functional" / f"{first.key}.json"
    load, read = frames.Functional.__dict__["load"], frames._load_entry
    if gone == "load":  # (between the digest's check and the load: a prune removes the sidecar, then the npz)
        monkeypatch.setattr(frames.Functional, "load",
                            classmethod(lambda cls, path: (side.unlink(), npz.unlink(), load.__func__(cls, path))[-1]))
    else:
        monkeypatch.setattr(frames, "_load_entry",
                            lambda *a: ((side if gone == "sidecar" else npz).unlink(), read(*a))[-1])
    capsys.readouterr()
    again = cached_render(cfg)  # (was: "tlm: warning: damaged functional cache entry ...")
    assert not again.cached and again.summary["work"] == first.summary["work"]
    assert capsys.readouterr().err == ""
    monkeypatch.setattr(frames.Functional, "load", load)  # (not monkeypatch.undo(): the cache folder's too)
    monkeypatch.setattr(frames, "_load_entry", read)
    assert cached_render(cfg).cached  # (written again, whole)
    npz.write_bytes(npz.read_bytes()[:100])  # (cut short: damage, said and removed as before)
    assert not cached_render(cfg).cached and f"damaged functional cache entry {npz}" in capsys.readouterr().err


def test_a_scene_entry_removed_under_its_reader_is_a_quiet_miss_and_a_truncated_one_still_said(cache, capsys,
                                                                                                monkeypatch):
    calls = []

    def compute(t, p, a):
        calls.append(a)
        return np.ones_like(t)

    crease(compute)
    (entry,) = scene_cache.cache_dir().iterdir()
    read = scene_cache._read
    monkeypatch.setattr(scene_cache, "_read", lambda e: (e.unlink(), read(e))[-1])
    capsys.readouterr()
    np.testing.assert_array_equal(crease(compute), 1.0)
    assert len(calls) == 2 and capsys.readouterr().err == ""  # (was: "damaged scene cache entry ... No such file")
    monkeypatch.setattr(scene_cache, "_read", read)
    assert entry.is_file()  # (written again)
    entry.write_bytes(entry.read_bytes()[:200])  # (cut short: damage, said and removed as before)
    np.testing.assert_array_equal(crease(compute), 1.0)
    assert len(calls) == 3 and f"damaged scene cache entry {entry}" in capsys.readouterr().err


# ---------------------------------------------------------------- the Python API


def test_the_python_api_surveys_prunes_and_clears_as_tlm_cache_does(cache):
    import tlm

    folders = {k: a_reference(k * 20, 32) for k in "ab"}
    aged([folders["a"]], 40)
    crease()
    info = tlm.cache_info()
    assert info["folder"] == str(cache) and [c["cache"] for c in info["caches"]] == list(cache_admin.NAMES)
    assert {c["cache"]: c["entries"] for c in info["caches"] if c["entries"]} == {"references": 2, "scenes": 1}
    assert [c["cache"] for c in tlm.cache_info("scenes")["caches"]] == ["scenes"]
    would = tlm.prune_cache(older_than="30d", dry_run=True)
    assert [r["entry"] for r in would["removed"]] == ["references/" + "a" * 20] and would["not_removed"] == []
    assert folders["a"].is_dir() and would["kept"] == 2
    done = tlm.prune_cache(older_than=15 * DAY, caches=["references"])
    assert [r["entry"] for r in done["removed"]] == ["references/" + "a" * 20] and not folders["a"].exists()
    assert done["kept"] == 1 and done["kept_bytes"] == sum(f.stat().st_size for f in folders["b"].iterdir())
    assert tlm.prune_cache(max_size="1G")["removed"] == []
    assert tlm.prune_cache(max_size=0, caches="scenes")["kept"] == 0 and folders["b"].is_dir()
    assert len(tlm.clear_cache(dry_run=True)["removed"]) == 1 and folders["b"].is_dir()
    assert len(tlm.clear_cache()["removed"]) == 1 and not folders["b"].exists()


@pytest.mark.parametrize("call, said", [
    (lambda tlm: tlm.prune_cache(max_size=-1), "max_size: -1 is not a size"),
    (lambda tlm: tlm.prune_cache(max_size="-1"), "max_size: '-1' is not a size"),
    (lambda tlm: tlm.prune_cache(older_than="3x"), "older_than: '3x' is not a duration"),
    (lambda tlm: tlm.prune_cache(older_than=float("nan")), "older_than: nan is not a duration"),
    (lambda tlm: tlm.prune_cache(older_than=True), "older_than: True is not a duration"),
    (lambda tlm: tlm.prune_cache(older_than=1, caches="nope"), "caches: 'nope' is not one of tlm's caches"),
    (lambda tlm: tlm.clear_cache(caches=5), "caches: 5 is not one of tlm's caches"),
    (lambda tlm: tlm.clear_cache(dry_run="yes"), "dry_run: 'yes' is not True or False"),
    (lambda tlm: tlm.prune_cache(), "prune_cache: give older_than=, max_size= and/or stale=True"),
])
def test_the_python_api_s_bad_arguments_are_input_errors_in_python_words(call, said, cache):
    import tlm

    folder = a_reference("c" * 20)
    aged([folder], 100)
    with pytest.raises(tlm.InputError) as got:
        call(tlm)
    assert str(got.value).startswith(said), str(got.value)
    assert (folder / "reference.npy").is_file() and (folder / "meta.json").is_file()


# ---------------------------------------------------------------- flags before and after the command; odd folders


def test_json_before_or_after_prune_and_clear_prints_what_the_api_returns(cache, capsys):
    import tlm

    folders = [a_reference(k * 20) for k in "ab"]
    aged(folders[:1], 10)
    status, out, _ = run_cli(capsys, "--json", "prune", "--max-size", "0", "--dry-run")  # (was: the text lines)
    assert status == 0 and json.loads(out) == tlm.prune_cache(max_size=0, dry_run=True)
    assert [r["entry"] for r in json.loads(out)["removed"]] == ["references/" + "a" * 20, "references/" + "b" * 20]
    status, out, _ = run_cli(capsys, "prune", "--json", "--older-than", "5d")  # (was: refused, exit 2)
    got = json.loads(out)
    assert status == 0 and [r["entry"] for r in got["removed"]] == ["references/" + "a" * 20] and got["kept"] == 1
    assert not folders[0].exists() and folders[1].is_dir()
    status, out, _ = run_cli(capsys, "clear", "--json", "--dry-run")
    assert status == 0 and json.loads(out)["kept"] == 0 and folders[1].is_dir()
    status, out, _ = run_cli(capsys, "--json", "clear")
    assert status == 0 and json.loads(out) == {"dry_run": False, "removed": [json.loads(out)["removed"][0]],
                                               "not_removed": [], "kept": 0, "kept_bytes": 0}
    assert not folders[1].exists()


@pytest.mark.parametrize("argv", [["--cache", "tracebacks", "prune", "--cache", "references", "--max-size", "0"],
                                  ["--cache", "tracebacks", "clear", "--cache", "references"],
                                  ["--cache", "references", "--cache", "tracebacks", "clear"],
                                  ["clear", "--cache", "tracebacks", "--cache", "references"]])
def test_cache_given_before_and_after_the_command_are_both_taken(argv, cache, capsys):
    a_reference("a" * 20)
    from tlm.cli_signals import save_traceback

    save_traceback(ValueError("x"))
    crease()  # (a scenes entry: not chosen, kept)
    status, out, _ = run_cli(capsys, *argv, "--dry-run")
    listed = [line.split()[2].split("/")[0] for line in out.splitlines()[:-1]]
    assert status == 0 and listed == ["references", "tracebacks"], out  # (was: the command's --cache alone)
    assert out.splitlines()[-1].startswith("would remove 2 entries (")  # (the scenes entry: not of these caches)
    status, out, _ = run_cli(capsys, "--cache", "scenes", "info", "--cache", "tracebacks")
    assert status == 0 and [line.split()[0] for line in out.splitlines()[2:5]] == ["scenes", "tracebacks", "all"]


@pytest.mark.parametrize("argv", [[], ["info"], ["--json"], ["clear"], ["prune", "--older-than", "0s"]])
def test_tlm_cache_set_to_a_file_is_one_line_exit_2_naming_it(argv, tmp_path, monkeypatch, capsys):
    import tlm

    afile = tmp_path / "afile"
    afile.write_text("hi\n")
    monkeypatch.setenv("TLM_CACHE", str(afile))
    status, out, err = run_cli(capsys, *argv)  # (was: six empty caches, "the folder in all: 3B"; exit 0)
    assert status == 2 and out == "" and err.splitlines() == [f"tlm: error: TLM_CACHE: {afile} is a file, not "
                                                              "a folder"], err
    assert afile.read_text() == "hi\n"
    for call in (tlm.cache_info, tlm.clear_cache, lambda: tlm.prune_cache(older_than=0)):
        with pytest.raises(tlm.InputError, match=f"^TLM_CACHE: {afile} is a file, not a folder$"):
            call()


def test_a_file_for_a_cache_s_folder_is_not_tlm_s_and_an_unreadable_folder_is_said(cache, capsys, monkeypatch):
    a_reference("a" * 20)
    (cache / "functional").write_text("mine")
    status, out, err = run_cli(capsys)
    assert status == 0 and err == "" and f"not tlm's entries, never removed: 1 (4B), e.g. {cache / 'functional'}" in out
    status, out, _ = run_cli(capsys, "clear")
    assert status == 0 and out.startswith("removed 1 entry") and (cache / "functional").read_text() == "mine"
    a_reference("b" * 20)
    listing = Path.iterdir

    def iterdir(self):
        if self == cache / "references":
            raise PermissionError(13, "Permission denied", str(self))
        return listing(self)

    monkeypatch.setattr(Path, "iterdir", iterdir)  # (as root, chmod 000 does not stop a read)
    for argv in ([], ["clear"]):  # (was: an empty cache, and the clear removed nothing and said so, exit 0)
        status, out, err = run_cli(capsys, *argv)
        assert status == 1 and out == "" and err.splitlines() == [
            f"tlm: error: cannot read the cache folder {cache / 'references'}: permission denied"], err
    monkeypatch.setattr(Path, "iterdir", listing)
    assert (cache / "references" / ("b" * 20)).is_dir()


def test_entries_that_could_not_be_removed_are_counted_kept_as_the_api_counts_them(cache, capsys, monkeypatch):
    import tlm

    folders = [a_reference(k * 20) for k in "abcd"]
    monkeypatch.setattr(cache_admin, "_remove_one", lambda path, root, leftover, *_: "operation not permitted")
    status, out, _ = run_cli(capsys, "prune", "--max-size", "0")
    first, second = out.splitlines()
    assert status == 1 and ", kept 4 (" in first and first.startswith("removed 0 entries"), out  # (was: kept 0)
    assert second.startswith("could not remove 4 entries") and "operation not permitted" in second
    status, out, _ = run_cli(capsys, "--json", "clear")
    assert status == 1 and json.loads(out) == tlm.clear_cache() and json.loads(out)["kept"] == 4
    assert len(json.loads(out)["not_removed"]) == 4 and all(f.is_dir() for f in folders)


def test_units_in_any_case_and_too_large_values_alike_for_both_flags(cache, capsys):
    import tlm

    assert cache_admin.duration("12H") == 12 * 3600 and cache_admin.duration("2W") == 14 * DAY  # (was: refused)
    assert cache_admin.duration("90M") == 90 * 60 and cache_admin.size("2gb") == cache_admin.size("2GiB") == 2 << 30
    folder = a_reference("a" * 20)
    aged([folder], 20)
    status, out, _ = run_cli(capsys, "prune", "--older-than", "2W", "--dry-run")
    assert status == 0 and out.startswith("would remove references/" + "a" * 20)
    huge = "9" * 400
    for flag, value, said in (("--older-than", huge + "d", "too large for a duration: at most 1000 years"),
                              ("--max-size", huge, "too large for a size: at most 1 EiB"),
                              ("--older-than", "60000w", "'60000w' is too large for a duration")):
        status, out, err = run_cli(capsys, "prune", flag, value)  # (was: --older-than infinite, --max-size "not a
        assert status == 2 and out == "" and len(err.splitlines()) == 1 and said in err, err  # size" without why)
        assert len(err) < 200 and f"argument {flag}: " in err
    for kw in ({"max_size": 10 ** 400}, {"older_than": 1e300}, {"max_size": huge}):  # (was: an OverflowError; ok)
        with pytest.raises(tlm.InputError, match="is too large for a"):
            tlm.prune_cache(**kw)
    assert folder.is_dir()


def test_an_empty_list_of_caches_is_none_in_the_api(cache):
    import tlm

    folder = a_reference("a" * 20)
    assert tlm.cache_info(caches=[])["caches"] == []  # (was: every cache)
    assert tlm.clear_cache(caches=[]) == {"dry_run": False, "removed": [], "not_removed": [], "kept": 0,
                                          "kept_bytes": 0}
    assert tlm.prune_cache(max_size=0, caches=())["removed"] == [] and folder.is_dir()  # (was: all removed)
    assert [c["cache"] for c in tlm.cache_info()["caches"]] == list(cache_admin.NAMES)


# ---------------------------------------------------------------- an entry used or replaced while a prune runs (h171)


@pytest.mark.parametrize("command", ["prune", "clear"])
def test_a_reference_swapped_in_while_the_prune_waits_for_its_lock_is_kept(command, cache, monkeypatch):
    """A ``tlm reference`` swaps its new folder in just as the prune reaches the old one's lock: the lock
    then holds the new folder, which is not what was surveyed (was: renamed aside and removed, the new
    reference lost)."""
    import contextlib

    key = "e" * 20
    aged([a_reference(key)], 40)
    real = cache_admin.folder_lock

    @contextlib.contextmanager
    def writer_swaps_first(path, *a, **k):
        save_reference(key, np.ones((4, 4, 3), np.float32),
                       {"rounds": 64, "converged": True, "relative_standard_error": 0.001})
        with real(path, *a, **k):
            yield

    monkeypatch.setattr(cache_admin, "folder_lock", writer_swaps_first)
    out = cache_admin.prune(["references"], DAY if command == "prune" else None, clear=command == "clear")
    assert out.removed == [] and [(e.shown(), why) for e, why in out.failed] == [("references/" + key,
                                                                                   "used meanwhile")]
    got = load_reference(key)
    assert got is not None and got[1]["rounds"] == 64
    assert [p.name for p in (cache / "references").iterdir()] == [key]  # (nothing left aside)


def test_a_frame_rewritten_after_its_sidecar_went_keeps_its_new_file(cache, monkeypatch):
    """Each file is looked at again just before it goes: a writer that replaced the ``.npz`` after the
    prune removed the sidecar keeps its new one (was: removed with the old entry's)."""
    first = cached_render(config_from_dict(SMALL, "t"))
    folder = cache / "functional"
    aged(list(folder.iterdir()), 3)
    npz = folder / f"{first.key}.npz"
    removing = cache_admin.remove_entry

    def a_writer_replaces_the_npz(path, root):
        if path.name.endswith(".json"):  # (the sidecar goes first; a writer then puts a new .npz in place)
            new = folder / f".{npz.name}.tmp{process_tag()}"
            new.write_bytes(b"the new frame")
            os.replace(new, npz)
        return removing(path, root)

    monkeypatch.setattr(cache_admin, "remove_entry", a_writer_replaces_the_npz)
    out = cache_admin.prune(["functional"], 2 * DAY)
    assert out.removed == [] and [why for _, why in out.failed] == ["used meanwhile"]
    assert npz.read_bytes() == b"the new frame" and not (folder / f"{first.key}.json").exists()


def test_a_use_between_the_survey_and_the_removal_keeps_the_entry(cache, capsys, monkeypatch):
    """An entry read (its time refreshed) after the survey is kept as used meanwhile: before the removal
    starts, and while the removal waits for its folder's lock (was: only the first)."""
    import contextlib

    folders = {k: a_reference(k * 20) for k in "ab"}
    aged(folders.values(), 40)
    survey = cache_admin.survey

    def survey_then_a_read(*a, **k):
        caches = survey(*a, **k)
        os.utime(folders["a"] / "meta.json")  # (what load_reference does to it)
        return caches

    monkeypatch.setattr(cache_admin, "survey", survey_then_a_read)
    real = cache_admin.folder_lock

    @contextlib.contextmanager
    def read_under_the_lock(path, *a, **k):
        with real(path, *a, **k):
            if path.name == "b" * 20:
                os.utime(path / "meta.json")
            yield

    monkeypatch.setattr(cache_admin, "folder_lock", read_under_the_lock)
    status, out, _ = run_cli(capsys, "prune", "--older-than", "1d")
    assert status == 0 and out.startswith("removed 0 entries") and out.rstrip().endswith("; 2 used meanwhile kept")
    assert all((f / "meta.json").is_file() for f in folders.values())


def test_an_hour_old_temporary_named_by_a_live_process_is_kept(cache, capsys):
    """A temporary over :data:`~tlm.cache_admin.BUSY_SECONDS` old is a killed writer's leftover, removed,
    unless its name carries a live process of this machine (a long write): that one is kept."""
    folder = cache / "functional"
    folder.mkdir(parents=True)
    live = folder / f".{'a' * 24}.npz.tmp{process_tag()}"  # (this process: alive)
    dead = folder / f".{'b' * 24}.npz.tmp{process_tag().rsplit('-', 1)[0]}-999999999"
    for p in (live, dead):
        p.write_bytes(b"x" * 10)
    aged([live, dead], 2 / 24)
    status, out, _ = run_cli(capsys, "prune", "--older-than", "1h")
    assert status == 0 and out.startswith("removed 1 entry") and "left alone: 1 being written" in out, out
    assert live.exists() and not dead.exists()


def test_choose_never_compares_entries_field_by_field(monkeypatch):
    """``choose`` keeps the chosen by identity (was: ``e not in gone``, a list, each entry compared with
    every chosen one: 20,000 entries took 97 s)."""
    now = time.time()
    entries = [cache_admin.Entry("scenes", f"mesh-{k:016x}", [], 10, now - k * DAY) for k in range(40)]
    monkeypatch.setattr(cache_admin.Entry, "__eq__", lambda a, b: pytest.fail("entries compared"))
    gone = cache_admin.choose([cache_admin.Cache("scenes", Path("."), entries)], 30.5 * DAY, 150, now)
    assert [e.name for e in gone] == [f"mesh-{k:016x}" for k in range(39, 14, -1)]


def test_a_dry_run_s_record_says_so(cache, capsys):
    import tlm

    aged([a_reference("a" * 20)], 10)
    status, out, _ = run_cli(capsys, "prune", "--json", "--older-than", "5d", "--dry-run")
    assert status == 0 and json.loads(out)["dry_run"] is True and len(json.loads(out)["removed"]) == 1
    assert tlm.clear_cache(dry_run=True)["dry_run"] is True and tlm.prune_cache(older_than="1d")["dry_run"] is False
    assert tlm.cache_info()["caches"][2]["entries"] == 0


@pytest.mark.parametrize("variable, value", [("XDG_CACHE_HOME", "{file}"), ("TLM_CACHE", "{file}/sub")])
def test_a_file_above_the_cache_folder_is_one_line_exit_2_naming_the_variable(variable, value, tmp_path,
                                                                              monkeypatch, capsys):
    import tlm

    afile = tmp_path / "afile"
    afile.write_text("hi\n")
    monkeypatch.delenv("TLM_CACHE", raising=False)
    monkeypatch.setenv(variable, value.format(file=afile))
    home = cache_admin.cache_home()
    said = f"{variable}: {home}: {afile} is a file, not a folder"
    for argv in ([], ["clear"]):  # (was: "cannot read the cache folder .../afile/tlm: not a directory", exit 1)
        status, out, err = run_cli(capsys, *argv)
        assert status == 2 and out == "" and err.splitlines() == [f"tlm: error: {said}"], err
    with pytest.raises(tlm.InputError, match=f"^{re.escape(said)}$"):
        tlm.cache_info()
    assert afile.read_text() == "hi\n"
