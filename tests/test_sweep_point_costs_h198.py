"""A sweep point's costs (h198): ``cache.pairs`` 2, 3 and 4 give one frame, so they share its functional key
(:func:`tlm.render.planner.same_frame_settings`: a sweep of them rendered a frame each); a point's
``host_seconds`` and row hold the writing of its folder (``write``, ``seconds.write``: it was in neither);
``config.resolved.yaml`` is written by libyaml's emitter where its text is PyYAML's own
(:func:`tlm.experiments.sweep_point.config_text`); and a process keeps the last frame it read while its
cache entry is that file (:func:`tlm.experiments.frames._read_frame`), so the points of a frame group do
not each decompress it."""

from __future__ import annotations

import dataclasses
import json
import math
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

import tlm.arch.units as units
import tlm.experiments.frames as frames
from tlm.arch.functional import Functional
from tlm.caches import file_digest
from tlm.config import config_from_dict, load_config, to_dict
from tlm.config_words import dump_yaml, parse_yaml
from tlm.errors import InputError
from tlm.experiments import run
from tlm.experiments.frames import cache_dir, cached_render, functional_key
from tlm.experiments.sweep import run_sweep
from tlm.experiments.sweep_file import load_sweep
from tlm.experiments.sweep_point import config_text
from tlm.experiments.sweep_rows import result_columns, result_fields
from tlm.render.planner import same_frame_settings

REPO = Path(__file__).resolve().parents[1]
SMALL = {"scene": "cornell", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
         "photons": {"count": 2000}, "arch": {"frames": 2, "trace": False}}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def cfg_of(**raw):
    return config_from_dict({**SMALL, **raw})


# ------------------------------------------------------------------ cache.pairs: one frame, one key


@pytest.mark.parametrize("mode", ["rcast", "reflect", "pmap"])
def test_cache_pairs_2_to_4_give_one_frame_and_share_its_key(mode):
    """The frames of pairs 2, 3 and 4 are the same (every array and every work total; 1's is not), and so are
    their keys; 1 keeps a key of its own, as does another block size."""
    got = {}
    for pairs in (1, 2, 3, 4):
        res = run.render(cfg_of(mode=mode, cache={"pairs": pairs}))
        got[pairs] = (res.functional(), run.results_dict(res, exposure=0.0, config_path=None)["work"])
    assert all(got[p] == got[4] for p in (2, 3))  # (Functional's == compares every array of the frame)
    assert got[1][0] != got[4][0] and got[1][1] != got[4][1]  # (the node heap and the indices share one pair)
    key = {p: functional_key(cfg_of(mode=mode, cache={"pairs": p}), "scene", "code") for p in (1, 2, 3, 4)}
    assert key[2] == key[3] == key[4] != key[1]  # (2 and 3 had keys of their own)
    other = functional_key(cfg_of(mode=mode, cache={"pairs": 2, "block_words": 256}), "scene", "code")
    assert other not in key.values()
    # only the keys of 2 and 3 change: the default's (4) and 1's keep the values they hold
    assert same_frame_settings(cfg_of(mode=mode)) == {"cache.pairs": 4}
    assert same_frame_settings(cfg_of(mode=mode, cache={"pairs": 1})) == {}


def test_a_sweep_of_cache_pairs_renders_two_frames_for_four_values(tmp_path):
    path = tmp_path / "pairs.yaml"
    path.write_text(yaml.safe_dump({"base": {**SMALL, "mode": "rcast"}, "grid": {"cache.pairs": [1, 2, 3, 4]}}))
    done = run_sweep(path, tmp_path / "out", jobs=1)
    assert (done.ok, done.failed, done.renders) == (4, 0, 2)  # (was 4: one frame per value)
    rows = sorted(done.rows, key=lambda r: r["cache.pairs"])
    assert rows[1]["cycles.throughput"] == rows[2]["cycles.throughput"] == rows[3]["cycles.throughput"]
    keys = [json.loads((tmp_path / "out" / "points" / r["hash"] / "results.json").read_text())["functional"]["key"]
            for r in rows]
    assert keys[1] == keys[2] == keys[3] != keys[0]
    # the frame a pairs-2 point read is the frame pairs 2 renders
    two = cfg_of(mode="rcast", cache={"pairs": 2})
    assert cached_render(two).cached
    assert cached_render(two).functional == run.render(two).functional()


# ------------------------------------------------------------------ the write of a point's folder


def test_a_point_records_the_seconds_of_writing_its_folder(tmp_path, monkeypatch):
    """``host_seconds.write`` (and the row's ``seconds.write``, the CSV's last column) holds the writing of the
    point's folder: a trace.json that takes 0.2 s to write is in it, not in functional or simulate."""
    real = units.Trace.write

    def slow(self, *args, **kwargs):
        time.sleep(0.2)
        return real(self, *args, **kwargs)

    monkeypatch.setattr(units.Trace, "write", slow)
    path = tmp_path / "one.yaml"
    path.write_text(yaml.safe_dump({"base": {**SMALL, "mode": "rcast", "arch": {"frames": 2, "trace": True}},
                                    "grid": {"arch.fifo_depth": [16]}}))
    out = tmp_path / "out"
    done = run_sweep(path, out, jobs=1)
    (row,) = done.rows
    res = json.loads((out / "points" / row["hash"] / "results.json").read_text())
    host = res["host_seconds"]
    assert set(host) == {"functional", "simulate", "write", "one_off"}
    assert 0.2 <= host["write"] < 5 and host["functional"] + host["simulate"] < 5
    assert row["seconds.write"] == host["write"]
    assert json.loads((out / "sweep.jsonl").read_text().splitlines()[0])["seconds.write"] == host["write"]
    head = (out / "sweep.csv").read_text().splitlines()[0].split(",")
    assert head[-1] == "seconds.write" and head.index("seconds.one_off") == head.index("seconds.simulate") + 1
    assert (out / "points" / row["hash"] / "trace.json").is_file()


def test_a_row_of_a_results_json_without_write_seconds_has_none():
    res = {"cycles": {"vertex": 1}, "fps": 1.0, "timing": {"simpy_events": 1, "units": {}},
           "functional": {"cached": True}, "host_seconds": {"functional": 2.0, "simulate": 1.0, "one_off": 0.0}}
    assert result_fields(res)["seconds.write"] is None
    assert result_columns()[-4:] == ["seconds.functional", "seconds.simulate", "seconds.one_off", "seconds.write"]


# ------------------------------------------------------------------ config.resolved.yaml's text


def committed_configs() -> list[tuple[str, dict]]:
    """Every committed config resolved as a run or sweep point writes it, and the raw YAML of every committed
    config and scene file (the studies' and the scenes' odd values: long descriptions, nested lists)."""
    out = []
    for path in sorted((REPO / "configs").glob("*.yaml")):
        out.append((f"{path.name} (as written)", parse_yaml(path.read_text())))
        try:
            out.append((f"{path.name} (resolved)", to_dict(load_config(path)[0])))
            continue
        except InputError:  # (a sweep or a study: below)
            pass
        try:
            sweep = load_sweep(path)
        except InputError:  # (a study file: its base, where it has one)
            base = parse_yaml(path.read_text()).get("base")
            if isinstance(base, dict):
                out.append((f"{path.name} base", to_dict(config_from_dict(base))))
            continue
        out += [(f"{path.name} point {p.index}", p.config) for p in sweep.points]
    for path in sorted((REPO / "scenes").rglob("*.yaml")):
        out.append((str(path.relative_to(REPO)), parse_yaml(path.read_text())))
    return out


def test_config_text_is_safe_dumps_for_every_committed_config():
    configs = committed_configs()
    assert len(configs) > 250
    differ = [name for name, c in configs if config_text(c) != dump_yaml(c, sort_keys=False)]
    assert differ == []


ODD = {
    "long": "word " * 60, "long_bare": "x" * 400, "punct": "a: b # c - 'd' \"e\" [f] {g} & * ! | > % @ `",
    "looks_like": ["yes", "null", "~", "1e3", "0x10", "", " lead", "trail ", "-", "? q"],
    "floats": [0.1, 1e-300, 1e300, -0.0, math.inf, -math.inf, math.nan, 5e-324, 123456789.123456789, 1e16],
    "ints": [0, -1, 2**70, True, False, None], "nested": [[1, [2, [3, []]]], {}, {"a": [{"b": {"c": None}}]}],
    "unicode": "café – ☃ \U0001F600", "long_unicode": "é" * 200, "long_mixed": "mot é " * 40,
    "control": "tab\there\nnew line\x07", "crlf": "a\r\nb" * 30, "path": "/home/ünï/project/scenes/box.yaml",
    "keys": {"k" * 64: 1, "k" * 65: 2, "x" * 200: 3, "é": 4, "": 5, "a b": 6},
    "long_key": {"x" * 127: 3, "a b " * 32: 4}, "empty_key": {"": 5},
    "tuple_free": {"scene": "cornell", "resolution": [320, 240]},
}


@pytest.mark.parametrize("name", sorted(ODD))
def test_config_text_is_safe_dumps_for_odd_values(name):
    config = {"scene": "cornell", name: ODD[name], "render": {"spp": 4, "what": ODD[name]}}
    assert config_text(config) == dump_yaml(config, sort_keys=False)


def test_config_text_takes_libyamls_emitter_for_a_plain_config(monkeypatch):
    """A config of plain values is not given to PyYAML's own emitter (the C one writes it)."""
    if getattr(yaml, "CSafeDumper", None) is None:
        pytest.skip("PyYAML without libyaml")
    config = to_dict(load_config(REPO / "configs" / "cornell_pmap.yaml")[0])
    want = dump_yaml(config, sort_keys=False)
    monkeypatch.setattr("tlm.experiments.sweep_point.dump_yaml",
                        lambda *a, **k: pytest.fail("the pure-Python emitter was used"))
    assert config_text(config) == want


# ------------------------------------------------------------------ the last frame read, kept


@pytest.fixture
def loads(monkeypatch):
    """The frames Functional.load decompressed, by path."""
    got = []
    real = Functional.load.__func__

    def counted(cls, path):
        got.append(Path(path))
        return real(cls, path)

    monkeypatch.setattr(Functional, "load", classmethod(counted))
    monkeypatch.setattr(frames, "_LAST_FRAME", None, raising=False)  # (the process reads anew)
    return got


def test_the_points_of_a_frame_read_it_once_while_its_entry_is_that_file(loads, capsys):
    cfg = cfg_of(mode="rcast")
    first = cached_render(cfg)
    assert not first.cached and loads == []
    a, b = cached_render(cfg), cached_render(cfg)
    assert a.cached and b.cached and len(loads) == 1  # (was 2: each point decompressed the frame)
    assert b.functional is a.functional and a.functional == first.functional
    npz = cache_dir() / f"{a.key}.npz"
    # replaced under its key by another file (another process; here another frame, so that it shows), its
    # sidecar's checksum that file's: read anew, not the frame kept
    other = run.render(cfg_of(mode="rcast", cache={"pairs": 1})).functional()
    assert other != a.functional
    other.save(npz)
    side = npz.with_suffix(".json")
    side.write_text(json.dumps(frames.sealed({**json.loads(side.read_text()), "npz": file_digest(npz)})))  # (h514)
    c = cached_render(cfg)
    assert c.cached and len(loads) == 2 and c.functional == other
    # its bytes changed under an unchanged sidecar: damaged, said, rendered again; never the frame kept
    data = bytearray(npz.read_bytes())
    data[len(data) // 2] ^= 0xFF
    npz.write_bytes(bytes(data))
    d = cached_render(cfg)
    assert not d.cached and "damaged functional cache entry" in capsys.readouterr().err
    # removed (a prune): rendered again
    for f in cache_dir().glob(f"{a.key}*"):
        f.unlink()
    e = cached_render(cfg)
    assert not e.cached and e.functional == first.functional


def test_a_point_cannot_change_the_frame_the_next_one_reads(loads, tmp_path, monkeypatch):
    """The frame kept is the one every point of the group gets: its arrays are read-only, and a sweep's
    points leave it equal to the entry's file (kept here past the sweep's end, which drops it)."""
    import tlm.experiments.sweep as sweep_mod

    monkeypatch.setattr(sweep_mod, "forget_last_frame", lambda: None)
    path = tmp_path / "group.yaml"
    path.write_text(yaml.safe_dump({"base": {**SMALL, "mode": "pmap"}, "grid": {"arch.fifo_depth": [16, 64, 256]}}))
    done = run_sweep(path, tmp_path / "out", jobs=1)
    assert (done.ok, done.renders) == (3, 1) and len(loads) == 1  # (two points read it: one decompression)
    file, _, _, _, kept = frames._LAST_FRAME
    assert kept == Functional.load(Path(file))
    arrays = [w[k] for w in kept.work.values() for k in w] + [kept.photon_work[k] for k in kept.photon_work]
    assert arrays and not any(a.flags.writeable for a in arrays)
    with pytest.raises(ValueError):
        arrays[0][0] = 1
    assert dataclasses.is_dataclass(kept) and isinstance(arrays[0], np.ndarray)


def test_a_sweep_in_this_process_keeps_no_frame_after_it_ends(tmp_path, cache):
    """The last frame read is kept while a sweep's points run, not after (a library caller's process; a review)."""
    from tlm.experiments.sweep import run_sweep as sweep_here

    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": {"scene": "cornell", "mode": "rcast", "resolution": [8, 8],
                                             "arch": {"frames": 2, "trace": False}},
                                    "grid": {"arch.fifo_depth": [4, 16]}}))
    done = sweep_here(path, tmp_path / "o", jobs=1)
    assert (done.ok, done.failed) == (2, 0)
    assert frames._LAST_FRAME is None
