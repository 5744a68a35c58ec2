"""``tlm cache list`` tells frames of one scene, resolution and mode apart (h527): each such frame's row says the
settings its sidecar records where they differ (``[spp=2]``, ``[photons=2000 filter=knn]``), and where two still read
the same (a seed: no sidecar records it) the start of each's key (``other=1a2b3c4d``); a frame alone of its kind says
nothing more. Before, every such row read ``frame cornell 8x8 rcast``."""

from __future__ import annotations

import json
import shutil

from tests.test_cache_entries_h515 import frames, run_cli  # (a real frame, copied under other keys)
from tlm import cache_admin as ca
from tlm.fingerprint import code_fingerprint


def _set(side, **changes) -> None:
    """The sidecar ``side`` with ``changes`` (``section={key: value}``) made, written as frames writes it."""
    body = json.loads(side.read_text())
    for section, values in changes.items():
        body[section] = {**(body.get(section) or {}), **values}
    side.write_text(json.dumps(body, indent=1) + "\n", encoding="utf-8")


def _rows(out: str) -> dict[str, str]:
    return {line.split()[0]: line for line in out.splitlines() if line.startswith("functional/")}


def test_list_tells_frames_of_one_scene_resolution_and_mode_apart(cache, capsys):
    here = code_fingerprint()
    sides = frames(cache, {"a": (here, False), "b": (here, False), "spp": (here, False), "old": ("0123456789abcdef",
                                                                                                 False)})
    _set(sides["spp"], primary={"spp": 2})
    _set(sides["old"], primary={"spp": 2})
    lone = cache / "functional" / ("e" * 24 + ".json")  # (a frame alone of its resolution: nothing more said)
    shutil.copyfile(sides["a"], lone)
    shutil.copyfile(sides["a"].with_suffix(".npz"), lone.with_suffix(".npz"))
    _set(lone, scene={"resolution": [16, 8]})
    status, out = run_cli(capsys, "list")
    rows = _rows(out)
    assert status == 0 and len(rows) == 5, out
    whats = {name: rows[f"functional/{side.stem}"].split("  ")[1].strip() for name, side in
             {**sides, "lone": lone}.items()}
    assert len(set(whats.values())) == 5, whats  # (before: four read "frame cornell 8x8 rcast")
    assert whats["spp"] == f"frame cornell 8x8 rcast [spp=2 code={here}]", whats
    assert whats["old"] == "frame cornell 8x8 rcast [spp=2 code=0123456789abcdef]", whats
    for k in ("a", "b"):  # (the same recorded settings: told apart by their keys' start)
        assert whats[k] == f"frame cornell 8x8 rcast [spp=1 code={here} other={sides[k].stem[:8]}]", whats
    assert whats["lone"] == "frame cornell 16x8 rcast", whats
    assert out.splitlines()[1].split() == ["entry", "what", "size", "last", "use", "stale"]  # (the columns kept)
    assert rows[f"functional/{sides['old'].stem}"].endswith("stale")
    entries = {e["entry"]: e for e in json.loads(run_cli(capsys, "list", "--json")[1])["entries"]}
    got = entries[f"functional/{sides['spp'].stem}"]
    assert (got["differs"], got["what"], got["mode"]) == ({"spp": 2, "code": here}, whats["spp"], "rcast")
    assert "differs" not in entries[f"functional/{lone.stem}"]
    status, out = run_cli(capsys, "list", "--stale")  # (the same words: told apart among every frame)
    assert [r.split("  ")[1].strip() for r in _rows(out).values()] == [whats["old"]], out


def test_photon_map_frames_say_their_photons_and_filter(cache):
    folder = cache / "functional"
    folder.mkdir(parents=True)
    common = {"scene": {"name": "room", "resolution": [32, 24], "source": "/s/room.yaml", "triangles": 10},
              "plan": {"reasons": {"fgather": "estimate.final_gather is 16"}}, "code_fingerprint": code_fingerprint(),
              "primary": {"spp": 1}, "pmap": {"reference": "r", "photons": 100000, "k_nearest": 100}}
    density = {"radius_rule": "density", "radius_photons": 100, "radius": 1.5}
    photons = {"disk": {"emitted": 2000, "filter": "disk", **density},
               "knn": {"emitted": 2000, "filter": "knn", "radius_rule": None},
               "more": {"emitted": 3000, "filter": "disk", **density},
               "given": {"emitted": 3000, "filter": "disk", "radius_rule": "radius", "radius": 2.0}}
    entries = []
    for i, p in enumerate(photons.values()):
        side = folder / (f"{i + 1:x}" * 24 + ".json")
        side.write_text(json.dumps({**common, "photons": p}, indent=1) + "\n")
        e = ca.Entry("functional", side.stem, [side])
        ca.describe(e, whole=True)
        entries.append(e)
    ca.tell_apart(entries)
    assert [e.what() for e in entries] == [
        "frame room 32x24 pmap [photons=2000 filter=disk]", "frame room 32x24 pmap [photons=2000 filter=knn]",
        "frame room 32x24 pmap [photons=3000 filter=disk radius_photons=100]",
        "frame room 32x24 pmap [photons=3000 filter=disk radius=2]"]
    e = ca.Entry("functional", "f" * 24, entries[0].files)  # (described but not told apart: prune's words, as before)
    ca.describe(e, whole=True)
    assert e.what() == "frame room 32x24 pmap" and "differs" not in e.row()
