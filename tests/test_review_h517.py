"""Review of fb96772 (h517): ``tlm cache`` reads every frame's sidecar to judge it stale; a look by a user who does not
own the file (a shared cache) marked it used.

fb96772 made ``tlm cache``, ``tlm cache list`` and every ``tlm cache prune`` read each frame's ``<key>.json`` (its
``code_fingerprint``), a look meant to be no use: opened ``O_NOATIME``, else its access time set back. Both are the
owner's alone: another user's read set the file's access time, which ``tlm cache prune`` takes for a use. So a prune
of another user's frames last used 40 days ago (``--older-than 30d``) removed none ("4 used meanwhile kept": its own
survey's read), and every ``tlm cache`` made them used now. Another user's frame is now not read (nor judged stale).
"""

from __future__ import annotations

import json
import os
import time

import pytest

from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments.frames import cache_dir, cached_render

CFG = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1},
       "arch": {"frames": 2, "trace": False}}
DAY = 86400


def _not_the_owner(monkeypatch) -> list[str]:
    """From now on, as a user who does not own the cache's files: ``O_NOATIME`` and setting a file's times are
    refused (EPERM, as Linux refuses them to all but the owner); the files opened without ``O_NOATIME`` are listed
    (a read that marks the file used where its access time is kept)."""
    real_open, real_utime = os.open, os.utime
    noatime = getattr(os, "O_NOATIME", 0)
    if not noatime:
        pytest.skip("no O_NOATIME here")
    read: list[str] = []

    def opened(path, flags, *args, **kwargs):
        if flags & noatime:
            raise PermissionError(1, "Operation not permitted", str(path))
        read.append(str(path))
        return real_open(path, flags, *args, **kwargs)

    def utime(path, *args, **kwargs):
        if isinstance(path, int) or kwargs.get("ns") or (args and args[0] is not None):
            raise PermissionError(1, "Operation not permitted")
        return real_utime(path, *args, **kwargs)

    monkeypatch.setattr(os, "open", opened)
    monkeypatch.setattr(os, "utime", utime)
    return read


def _frames(n: int = 2) -> list:
    files = []
    for levels in (5, 7)[:n]:
        got = cached_render(config_from_dict({**CFG, "bsp": {"levels": levels}}, "test"))
        files += [cache_dir() / f"{got.key}.npz", cache_dir() / f"{got.key}.json"]
    old = time.time() - 40 * DAY
    for f in files:
        os.utime(f, (old, old))
    return files


def test_another_users_frames_are_not_read_by_tlm_cache_and_prune_by_age_takes_them(cache, monkeypatch, capsys):
    files = _frames()
    not_the_owner = _not_the_owner(monkeypatch)
    before = {f: (f.stat().st_atime_ns, f.stat().st_mtime_ns) for f in files}
    for args in (["cache"], ["cache", "list"], ["cache", "--json"], ["cache", "prune", "--stale", "--dry-run"]):
        assert main(args) == 0
    out = capsys.readouterr().out
    assert not [p for p in not_the_owner if p.endswith(".json")], not_the_owner  # (was: each sidecar read)
    assert {f: (f.stat().st_atime_ns, f.stat().st_mtime_ns) for f in files} == before
    assert ("functional: 0 of 2 entries stale (0B of " in out and "; 2 not judged: frames of another user's, not read "
            "(a read would mark them used now, which only the owner may set back)" in out), out
    assert "not judged" in out.split("tlm's cache entries")[1].splitlines()[2]  # (the list's row)
    assert "would remove 0 entries" in out  # (--stale: none judged, none taken)
    record = json.loads(out[out.index("{"):out.index("\n}\n") + 2])
    functional = next(c for c in record["caches"] if c["cache"] == "functional")
    assert (functional["stale"], functional["not_judged"]) == (0, 2)
    assert main(["cache", "prune", "--older-than", "30d"]) == 0  # (was: "2 used meanwhile kept", none removed)
    assert "removed 2 entries" in capsys.readouterr().out and not any(cache_dir().iterdir())

