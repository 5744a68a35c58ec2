"""A `tlm thesis` cell is comparable with the thesis only at the thesis's whole setting.

The seven checks of :func:`tlm.experiments.thesis.mismatches` (the scene file, the
resolution, the photons, the sampling, one pipeline, 600 MHz) missed every other key: a
``--set bsp.levels=3``, a cache block or FIFO depth, a reflect depth or a packet size of
another hardware or another work left the cells "comparable", and their error against the
thesis was quoted (the median, the report, calibrate's permission to overwrite the
packaged table) as if they were the thesis's setting. Now every key of the cell's resolved
config that changes the cycles or the image, at another value than the built-in
``configs/thesis.yaml``'s, makes it not comparable, named with both values; the keys that
change neither (threads, batches, the trace, ``reference.*``), those its mode never reads,
the seed and the instruction table (the calibrated model itself) do not.
"""

from __future__ import annotations

import json

import pytest
import yaml

import tlm.experiments.thesis as thesis_mod
from tlm.builtin import configs_dir
from tlm.cli import main
from tlm.config import MODES, apply_overrides, config_from_dict, to_dict
from tlm.experiments.study import read_study
from tlm.scenes.loader import scenes_dir

TINY = {"seed": 0, "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1}, "photons": {"count": 2000},
        "arch": {"frames": 2, "packet_size": 64, "trace": False}}
SIZES = {"ring": [320, 240], "room": [320, 240], "cornell": [320, 320]}
PHOTONS = {"ring": 20_000, "room": 80_000, "cornell": 120_000}


def _thesis_cell(table: str, mode: str, overrides: tuple[str, ...] = ()) -> tuple[dict, dict]:
    """``(results, config)`` of a cell of the committed configs/thesis.yaml with ``overrides``
    (``--set`` strings) on its base, its results as a run at the thesis's sizes writes them."""
    _, base, _ = read_study(configs_dir() / "thesis.yaml", ("scenes", "modes"))
    base = apply_overrides(base, list(overrides)) if overrides else base
    config = to_dict(config_from_dict({**base, "scene": thesis_mod.THESIS_SCENES[table], "mode": mode}))
    runs = list(MODES[:MODES.index(mode) + 1])
    results = {"scene": {"source": str(scenes_dir() / f"{thesis_mod.THESIS_SCENES[table]}.yaml"),
                         "resolution": SIZES[table]},
               "plan": {"run": runs}, "photons": {"emitted": PHOTONS[table]} if "pmap" in runs else None,
               "timing": {"clock_hz": 600e6}}
    return results, config


@pytest.mark.parametrize("table", ["ring", "room", "cornell"])
def test_a_cell_off_the_thesis_hardware_names_each_key_and_nothing_that_changes_nothing(table):
    """On the old code each of these cells was comparable (its seven checks all pass)."""
    assert all(thesis_mod.run_mismatches(table, *_thesis_cell(table, m)) == [] for m in MODES)
    sets = ("bsp.levels=3", "arch.fifo_depth=64", "cache.block_words=512", "render.threads=1",
            "render.batch_rays=4096", "render.batch=8", "arch.trace=false", "arch.max_events=1000000",
            "reference.tolerance=0.5", "render.exposure=2.0", "seed=7", "arch.programs=/elsewhere/programs.yaml")
    for mode in MODES:
        assert thesis_mod.run_mismatches(table, *_thesis_cell(table, mode, sets)) == [
            "bsp.levels 3 (thesis: floor(ln n))", "cache.block_words 512 (thesis: 1024)",
            "arch.fifo_depth 64 (configs/thesis.yaml: 1024; not in the thesis)"], mode


def test_a_key_is_judged_in_the_modes_that_read_it():
    """render.reflect_depth in rcast, and the photon sections outside pmap, change nothing."""
    sets = ("render.reflect_depth=1", "photons.leaf_photons=8", "estimate.final_gather=16", "arch.packet_size=64")
    got = {m: thesis_mod.run_mismatches("cornell", *_thesis_cell("cornell", m, sets)) for m in MODES}
    assert got["rcast"] == ["arch.packet_size 64 (configs/thesis.yaml: 256; not in the thesis)"]
    assert got["reflect"] == got["refract"] == ["render.reflect_depth 1 (configs/thesis.yaml: 4; not in the thesis)",
                                                "arch.packet_size 64 (configs/thesis.yaml: 256; not in the thesis)"]
    assert got["pmap"] == ["render.reflect_depth 1 (configs/thesis.yaml: 4; not in the thesis)",
                           "photons.leaf_photons 8 (thesis: floor(ln n))", "estimate.final_gather 16 (thesis: 0)",
                           "arch.packet_size 64 (configs/thesis.yaml: 256; not in the thesis)"]


def test_a_pmap_cell_whose_photon_pass_was_left_out_is_not_comparable():
    """--set photons.count=0: the PMap cell emitted no photons; the old rule judged no photons at all."""
    results, config = _thesis_cell("ring", "pmap", ("photons.count=0",))
    results = {**results, "plan": {"run": ["rcast", "reflect", "refract"]}, "photons": None}
    assert thesis_mod.run_mismatches("ring", results, config) == ["0 photons (thesis 20,000)"]


def test_tlm_thesis_set_of_bsp_and_arch_is_said_and_threads_is_not(tmp_path, cache, capsys):
    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump({"base": TINY, "scenes": ["thesis/ring"], "modes": ["rcast"]}))
    out = tmp_path / "out"
    assert main(["thesis", str(study), "--out", str(out), "--no-progress", "--no-report", "--set", "bsp.levels=3",
                 "--set", "arch.page_miss_cycles=20", "--set", "render.threads=1"]) == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "thesis_summary.json").read_text())
    said = summary["not_comparable"]["ring"]
    assert "bsp.levels 3 (thesis: floor(ln n))" in said and "arch.page_miss_cycles 20 (thesis: 12)" in said
    assert not any("threads" in w for w in said)
    assert "bsp.levels 3 (thesis: floor(ln n))" in summary["median_withheld"]
    assert "arch.page_miss_cycles 20 (thesis: 12)" in printed


def test_calibrate_says_a_study_off_the_thesis_hardware_is_not_comparable(tmp_path, cache):
    """The report's not_comparable is what keeps such a fit off the packaged table."""
    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump({"base": {**TINY, "bsp": {"levels": 3}}, "scenes": ["thesis/ring", "cornell"],
                                     "modes": ["rcast"]}))
    _, report = thesis_mod.calibrate(study, iterations=1)
    for table in ("ring", "cornell"):
        assert "bsp.levels 3 (thesis: floor(ln n))" in report["not_comparable"][table]


def test_tlm_thesis_at_the_thesis_size_is_comparable_but_for_a_set_that_changes_the_cycles(tmp_path, cache, capsys):
    """The thesis's ring, ray casting, at its whole setting (a few seconds a run): --set
    render.threads keeps the median; --set bsp.levels=3 withholds it (the old code quoted it)."""
    study = tmp_path / "study.yaml"
    raw = yaml.safe_load((configs_dir() / "thesis.yaml").read_text())
    study.write_text(yaml.safe_dump({**raw, "scenes": ["thesis/ring"], "modes": ["rcast"]}))
    medians = {}
    for item in ("render.threads=1", "bsp.levels=3"):
        out = tmp_path / item.partition("=")[0]
        assert main(["thesis", str(study), "--out", str(out), "--no-progress", "--no-report", "--set", item]) == 0
        medians[item] = json.loads((out / "thesis_summary.json").read_text())
    assert medians["render.threads=1"]["not_comparable"] == {}
    assert medians["render.threads=1"]["median_abs_rel_error_held_out"] is not None
    assert medians["bsp.levels=3"]["not_comparable"] == {"ring": ["bsp.levels 3 (thesis: floor(ln n))"]}
    assert medians["bsp.levels=3"]["median_abs_rel_error_held_out"] is None
    capsys.readouterr()
