"""``tlm cache`` says what each entry is and which frames are stale (h515): a frame's sidecar records the code that
wrote it (``code_fingerprint``, written by :mod:`tlm.experiments.frames`; faked here as frames writes a sidecar, plus
the key), a frame of other code (or of a tlm before the field) is stale, ``tlm cache`` counts them, ``tlm cache list``
names every entry, ``tlm cache prune --stale`` removes the stale ones; a cache folder that is a link to a path that
does not exist is said."""

from __future__ import annotations

import json
import os
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

import tlm
from tests.test_cache_admin import DAY, SMALL  # (a tiny frame to cache; a day in seconds)
from tlm import cache_admin as ca
from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments.frames import cached_render
from tlm.experiments.reference_cache import save_reference
from tlm.fingerprint import code_fingerprint
from tlm.oracle.mitsuba import save_ground_truth


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py) every test here has its own
    return cache


def run_cli(capsys, *argv) -> tuple[int, str]:
    capsys.readouterr()
    status = main(["cache", *argv])
    return status, capsys.readouterr().out


def sidecar(side: Path, code: str | None, first: bool = False) -> None:
    """Write the frame's sidecar ``side`` again as frames writes it (``json.dumps(indent=1)``), its
    ``code_fingerprint`` ``code`` (first or last of its keys; None: without the field, a tlm before it)."""
    body = {k: v for k, v in json.loads(side.read_text()).items() if k != "code_fingerprint"}
    if code is not None:
        body = {"code_fingerprint": code, **body} if first else {**body, "code_fingerprint": code}
    side.write_text(json.dumps(body, indent=1) + "\n", encoding="utf-8")


def frames(cache: Path, codes: dict[str, tuple[str | None, bool]]) -> dict[str, Path]:
    """A frame rendered by the real writer, copied under other keys: ``{name: (code, first)}`` -> ``{name: the
    entry's sidecar}``, each written by :func:`sidecar`."""
    key = cached_render(config_from_dict(SMALL, "t")).key
    folder = cache / "functional"
    out = {}
    for i, (name, (code, first)) in enumerate(codes.items()):
        new = f"{i + 1:x}" * 24 if i else key
        if i:
            shutil.copyfile(folder / f"{key}.npz", folder / f"{new}.npz")
            shutil.copyfile(folder / f"{key}.json", folder / f"{new}.json")
        sidecar(folder / f"{new}.json", code, first)
        out[name] = folder / f"{new}.json"
    return out


def size(side: Path) -> int:
    return side.stat().st_size + side.with_suffix(".npz").stat().st_size


def test_stale_frames_are_counted_listed_and_pruned_on_request(cache, capsys):
    here = code_fingerprint()
    sides = frames(cache, {"live": (here, False), "live_first": (here, True), "other": ("0123456789abcdef", False),
                           "older": (None, False)})
    stale = {sides["other"], sides["older"]}
    status, out = run_cli(capsys)
    assert status == 0 and "functional: 2 of 4 entries stale" in out, out
    got = {c["cache"]: c for c in json.loads(run_cli(capsys, "--json")[1])["caches"]}
    assert (got["functional"]["stale"], got["functional"]["stale_bytes"]) == (2, sum(size(s) for s in stale))
    assert tlm.cache_info("functional")["caches"][0]["stale"] == 2  # (the API's, the same record)
    # list --stale: those two alone, named with what they are
    status, out = run_cli(capsys, "list", "--stale")
    rows = [line for line in out.splitlines() if line.startswith("functional/")]
    assert status == 0 and sorted(r.split()[0] for r in rows) == sorted(f"functional/{s.stem}" for s in stale)
    assert all("frame cornell 8x8 rcast" in r and r.endswith("stale") for r in rows), out
    # a dry run names what it would remove; nothing goes
    status, out = run_cli(capsys, "prune", "--stale", "--dry-run")
    lines = out.splitlines()
    assert status == 0 and len(lines) == 3 and all("(frame cornell 8x8 rcast, stale; " in x for x in lines[:2]), out
    assert all(s.is_file() for s in sides.values())
    status, out = run_cli(capsys, "prune", "--stale")
    assert status == 0 and out.startswith("removed 2 entries") and "kept 2" in out, out
    assert sorted(p.name for p in (cache / "functional").iterdir()) == sorted(
        n for s in (sides["live"], sides["live_first"]) for n in (s.name, s.with_suffix(".npz").name))
    assert cached_render(config_from_dict(SMALL, "t")).summary is not None  # (the live one still read, or rendered)


def test_stale_joins_the_other_prune_options(cache, capsys):
    sides = frames(cache, {"old_live": (code_fingerprint(), False), "new_stale": ("0123456789abcdef", False),
                           "new_live": (code_fingerprint(), True)})
    t = time.time() - 40 * DAY
    for f in (sides["old_live"], sides["old_live"].with_suffix(".npz")):
        os.utime(f, (t, t))
    got = json.loads(run_cli(capsys, "prune", "--stale", "--older-than", "30d", "--dry-run", "--json")[1])
    assert sorted(r["entry"] for r in got["removed"]) == sorted(
        f"functional/{sides[k].stem}" for k in ("old_live", "new_stale"))
    assert {r["entry"]: r["stale"] for r in got["removed"]} == {f"functional/{sides['old_live'].stem}": False,
                                                               f"functional/{sides['new_stale'].stem}": True}
    assert got["kept"] == 1


def test_list_says_what_each_entry_is_and_looking_is_no_use(cache, capsys):
    sides = frames(cache, {"live": (code_fingerprint(), False)})
    image = np.random.default_rng(0).random((16, 24, 3)).astype(np.float32)
    ref = save_reference("a" * 20, image, {"photons": 2000, "rounds": 4, "converged": True,
                                           "relative_standard_error": 0.01})
    truth = save_ground_truth("b" * 20, np.zeros((6, 10, 3)), {"scene": "cornell", "spp": 16})
    files = [sides["live"], sides["live"].with_suffix(".npz"), *ref.iterdir(), *truth.iterdir()]
    t = time.time() - 40 * DAY
    for f in [*files, ref, truth]:  # (a folder's own time counts as its last use too)
        os.utime(f, (t, t))
    before = {f: (f.stat().st_atime_ns, f.stat().st_mtime_ns) for f in files}
    status, out = run_cli(capsys, "list")
    assert status == 0
    rows = {line.split()[0]: line for line in out.splitlines()[2:] if "/" in line.split()[0]}
    assert "frame cornell 8x8 rcast" in rows[f"functional/{sides['live'].stem}"]
    assert not rows[f"functional/{sides['live'].stem}"].endswith("stale")
    assert "reference 24x16 2000 photons 4 rounds" in rows["references/" + "a" * 20], out
    assert "ground truth cornell 10x6 16 spp" in rows["oracle/" + "b" * 20], out
    entries = json.loads(run_cli(capsys, "list", "--json", "--sort", "size")[1])["entries"]
    frame = entries[0]  # (largest first)
    assert frame["entry"] == f"functional/{sides['live'].stem}"
    assert (frame["kind"], frame["scene"], frame["resolution"], frame["mode"], frame["stale"]) == (
        "frame", "cornell", [8, 8], "rcast", False)
    assert {f: (f.stat().st_atime_ns, f.stat().st_mtime_ns) for f in files} == before  # (listing: no use)
    status, out = run_cli(capsys, "prune", "--older-than", "30d", "--dry-run")
    assert out.splitlines()[-1].startswith("would remove 3 entries"), out  # (still unused for 40 days)


def test_a_frames_mode_and_what_a_damaged_sidecar_says(cache):
    folder = cache / "functional"
    folder.mkdir(parents=True)

    def described(body) -> ca.Entry:
        side = folder / ("c" * 24 + ".json")
        side.write_text(body if isinstance(body, str) else json.dumps(body, indent=1) + "\n")
        e = ca.Entry("functional", "c" * 24, [side])
        ca.describe(e, whole=True)
        return e

    fgather = {"reasons": {"rcast": "every mode casts primary rays", "fgather": "estimate.final_gather is 16"}}
    e = described({"scene": {"name": "room", "resolution": [320, 240]}, "plan": fgather})
    assert (e.what(), e.stale) == ("frame room 320x240 pmap", True)
    e = described({"scene": {"name": "room", "resolution": [32, 24]}, "code_fingerprint": code_fingerprint(),
                   "plan": {"reasons": {"reflect": "the scene has no mirror material",
                                        "refract": "mode 'refract' asks for it and the scene has what it needs"}}})
    assert (e.what(), e.stale) == ("frame room 32x24 refract", False)
    e = described({"scene": {"name": ["x"], "resolution": "big"}, "plan": 3})
    assert (e.what(), e.about, e.stale) == ("frame", {}, True)
    e = described("{not json")
    assert (e.what(), e.stale) == ("frame", True)


def test_a_cache_folder_that_is_a_link_to_nothing_is_said(cache, capsys, tmp_path):
    cache.mkdir()
    (cache / "functional").symlink_to(tmp_path / "gone")
    status, out = run_cli(capsys)
    said = f"{cache / 'functional'} is a link to {tmp_path / 'gone'}, which does not exist"
    assert status == 0 and said in out, out
    got = {c["cache"]: c for c in json.loads(run_cli(capsys, "--json")[1])["caches"]}
    assert got["functional"]["problem"] == said and got["functional"]["not_tlms"] == []


def test_the_api_prunes_the_stale_frames_as_the_command_does(cache):
    """tlm.prune_cache(stale=True) is ``tlm cache prune --stale`` (it took older_than= or max_size= only)."""
    from tlm.errors import InputError

    sides = frames(cache, {"live": (code_fingerprint(), False), "other": ("0123456789abcdef", False)})
    with pytest.raises(InputError, match="stale: 'yes'"):
        tlm.prune_cache(stale="yes")
    out = tlm.prune_cache(stale=True, dry_run=True)
    assert out["dry_run"] is True and [r["entry"] for r in out["removed"]] == [f"functional/{sides['other'].stem}"]
    assert sides["other"].exists()
    out = tlm.prune_cache(stale=True)
    assert not sides["other"].exists() and sides["live"].exists()
