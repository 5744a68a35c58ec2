"""A sweep's per-point overheads (h239): the report reads a point's YAML with libyaml's parser (its values and
its errors as PyYAML's own); a point's write looks for killed writers' leftovers in ``points/`` once per process,
not by a listing of the whole folder at every point; renders of one scene and BSP one after another (the design
space's cache.pairs) build the BSP once, and one BSP is kept."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import tlm.storage as storage
from tlm.errors import InputError
from tlm.report import checks

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"light_samples": 1},
        "arch": {"frames": 1, "trace": False}}


@pytest.mark.skipif(getattr(yaml, "CSafeLoader", None) is None, reason="PyYAML built without libyaml")
def test_the_report_reads_yaml_with_libyaml_and_words_a_damaged_file_as_before(tmp_path, monkeypatch):
    good = tmp_path / "config.resolved.yaml"
    good.write_text(yaml.safe_dump({"scene": "cornell", "resolution": [16, 16], "arch": {"clock_hz": 3.0e8},
                                    "on": True, "none": None, "when": "2026-11-30", "n": 1e6}, sort_keys=False))
    expected = yaml.safe_load(good.read_text())
    with monkeypatch.context() as m:  # (PyYAML's own parser is not what reads a good file)
        m.setattr(checks.yaml, "safe_load", lambda *a, **k: pytest.fail("read by the pure-Python parser"))
        assert checks.read_yaml(good) == expected
    # a damaged file: the words of PyYAML's own parser (libyaml's differ), its line and column
    for text, said in (("a: [1, 2", "expected ',' or ']', but got '<stream end>': line 1 column 9"),
                       ("a: 1\n b: 2\n", "mapping values are not allowed here: line 2 column 3"),
                       ("- 1\nb: 2", "expected <block end>, but found '?': line 2 column 1")):
        bad = tmp_path / "bad.yaml"
        bad.write_text(text)
        with pytest.raises(InputError, match="is not valid YAML") as got:
            checks.read_yaml(bad)
        assert f"(cannot read: {said}): a damaged or edited copy" in str(got.value)


def test_a_points_write_lists_its_folder_once_per_process(tmp_path, monkeypatch):
    points = tmp_path / "points"
    points.mkdir()
    dead = points / f".p9.tmp-{storage.process_tag().rsplit('-', 1)[0]}-{2 ** 22 + 7}-0"  # (no such process)
    dead.mkdir()
    monkeypatch.setattr(storage, "pid_alive", lambda pid: pid != 2 ** 22 + 7)
    listed = []
    real = storage._left_by_the_gone
    monkeypatch.setattr(storage, "_left_by_the_gone", lambda folder, *a: listed.append(folder) or real(folder, *a))
    monkeypatch.setattr(storage, "_CLEANED", set(), raising=False)
    for n in range(5):
        with storage.atomic_folder(points / f"p{n}", "results.json", clean_once=True) as tmp:
            (tmp / "results.json").write_text("{}")
    assert listed == [points]  # (the first write's: every point's leftovers, a killed writer's of p9 too)
    assert not dead.exists() and sorted(p.name for p in points.iterdir()) == [f"p{n}" for n in range(5)]
    with storage.atomic_folder(points / "p0", "results.json") as tmp:  # (any other writer: as before, each time)
        (tmp / "results.json").write_text("{}")
    assert listed == [points, points]


def test_a_sweeps_points_list_their_folder_once(tmp_path, monkeypatch, cache):
    monkeypatch.setenv("TLM_KERNELS", "numpy")  # (quick: the frame is the same)
    from tlm.experiments.sweep import run_sweep

    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.page_miss_cycles": [0, 3, 6, 9, 12]}}))
    listed = []
    real = storage._left_by_the_gone
    monkeypatch.setattr(storage, "_left_by_the_gone", lambda d, *a: listed.append(Path(d)) or real(d, *a))
    monkeypatch.setattr(storage, "_CLEANED", set(), raising=False)
    run_sweep(path, tmp_path / "o", jobs=1)
    # the sweep's own cleaning at its start and end, and the first point's: not one listing for each of 5 points
    assert listed.count(tmp_path / "o" / "points") == 3, listed


def test_renders_of_one_scene_and_bsp_build_it_once_and_keep_one(monkeypatch):
    """The design space's frames that differ in cache.pairs (not a BSP input) share one BSP build: the same
    accel, its arrays as a fresh build's; another BSP is built after the kept one is let go."""
    import numpy as np

    import tlm.experiments.loading as loading
    from tlm.config import config_from_dict

    monkeypatch.setenv("TLM_KERNELS", "numpy")
    built = []
    real = loading.build_accel
    monkeypatch.setattr(loading, "build_accel", lambda *a, **k: built.append(k) or real(*a, **k))
    if hasattr(loading, "forget_accel"):
        loading.forget_accel()
    raw = {**BASE, "bsp": {"levels": 6}}
    alone = [loading.load_frame(config_from_dict({**raw, "cache": {"pairs": pairs}})) for pairs in (1, 2)]
    assert len(built) == 2 and loading._LAST_ACCEL == [], built  # (outside a sweep: nothing kept)
    built.clear()
    with loading.keeping_accel():
        kept_sweep(loading, config_from_dict, raw, built, real, np, alone)
    assert loading._LAST_ACCEL == []  # (the sweep's end lets it go)


def kept_sweep(loading, config_from_dict, raw, built, real, np, alone):
    """What a sweep in this process builds: one BSP for the frames that differ in cache.pairs."""
    frames = [loading.load_frame(config_from_dict({**raw, "cache": {"pairs": pairs}})) for pairs in (1, 2)]
    assert len(built) == 1 and frames[0].accel is frames[1].accel
    fresh = real(frames[1].scene.triangles, levels=6, memory_factor=20.0)
    for name in ("first", "last", "split", "lo", "hi", "items"):  # (the same bits: split is NaN on leaves)
        kept, want = getattr(frames[1].accel.tree, name), getattr(fresh.tree, name)
        assert np.asarray(kept).tobytes() == np.asarray(want).tobytes(), name
    assert frames[1].accel.leaf_first.tobytes() == fresh.leaf_first.tobytes()
    other = loading.load_frame(config_from_dict({**raw, "bsp": {"levels": 7}}))
    assert len(built) == 2 and other.accel is not frames[0].accel
    assert [entry[2] for entry in loading._LAST_ACCEL] == [other.accel]  # (one kept)
    assert alone[0].accel.leaf_first.tobytes() == frames[0].accel.leaf_first.tobytes()
