"""``--set`` leftovers of ``tlm sweep`` and the report's ``tlm reference`` command of a thesis cell.

1. A sweep's ``--set`` that no point reads is said once, as a factor that no point reads is
   (:meth:`tlm.experiments.sweep_file.Sweep.inert_sets`, and after the points ran, a timing key:
   ``Sweep.unread_factors``); one some point reads is not.
2. A ``--set`` of a section that does not set a factor's key is taken (it merges into the base's section,
   as ``tlm run --set`` does; each point's factor then sets its key in it); one that sets it is refused,
   naming its other keys in the dotted form.
3. The report's command for a thesis cell without its reference runs (its ``config.resolved.yaml``, not
   the study file, which ``tlm reference`` refuses).
"""

from __future__ import annotations

import json
import shlex
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.config import load_config, to_dict
from tlm.errors import InputError
from tlm.experiments.sweep import run_sweep
from tlm.experiments.sweep_file import load_sweep
from tlm.report.collect import read
from tlm.report.images import images_section

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 1, "images_in_flight": 1, "trace": False, "packet_size": 16}}
NO_PMAP = "the photon-map pass does not run (mode 'rcast' does not include the pmap (photon-map) pass)"
HASH = "(though in every point's config and hash: a rerun into a folder swept without it runs its points again)"
SWITCH = "arch.images_in_flight is 1 (a PM never has an older image's job to switch to)"


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _sweep(tmp_path: Path, **body) -> Path:
    path = tmp_path / "sw.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, **body}, sort_keys=False))
    return path


# ------------------------------------------------------------------ 1: a --set no point reads


def test_a_set_no_point_reads_is_said_once_as_a_factor_is(tmp_path):
    path = _sweep(tmp_path, grid={"bsp.levels": [4, 5]})
    sw = load_sweep(path, ["estimate.k=5", "render={reflect_depth: 2, spp: 1}", "arch.fifo_depth=16"])
    assert sw.inert_sets() == [
        f"{path}: --set estimate.k=5 changes nothing in any point {HASH}: {NO_PMAP}",
        f"{path}: --set render={{reflect_depth: 2, spp: 1}}: render.reflect_depth changes nothing in any point "
        f"{HASH}: mode 'rcast' traces no mirror or glass paths (the reflect, refract and pmap passes do)"]
    # a key set twice: named by the --set that set it last, once
    assert load_sweep(path, ["estimate.k=5", "estimate.k=6"]).inert_sets() == [
        f"{path}: --set estimate.k=6 changes nothing in any point {HASH}: {NO_PMAP}"]


def test_a_set_some_point_reads_is_not_said(tmp_path):
    path = _sweep(tmp_path, grid={"mode": ["rcast", "pmap"]})
    assert load_sweep(path, ["photons.count=1000"]).inert_sets() == []  # (as for a factor: the pmap point reads it)
    # (estimate.k: read by no point, the pmap point's filter being mvoxel: said, with both reasons)
    assert load_sweep(path, ["estimate.k=5"]).inert_sets() == [
        f"{path}: --set estimate.k=5 changes nothing in any point {HASH}: estimate.filter is 'mvoxel': only 'kvoxel' "
        f"samples k voxels; {NO_PMAP}"]


def test_the_sweep_says_it_before_its_points_run(tmp_path):
    path = _sweep(tmp_path, grid={"bsp.levels": [4, 5]})
    said: list[str] = []
    done = run_sweep(path, tmp_path / "o", jobs=1, warn=said.append, overrides=["estimate.k=5"])
    line = f"{path}: --set estimate.k=5 changes nothing in any point {HASH}: {NO_PMAP}"
    assert done.ok == 2 and said == [line] and done.warnings == [line]


def test_a_timing_set_no_point_read_is_said_after_they_ran(tmp_path):
    """arch.context_switch_cycles with one image in flight: the points' results name it (inert)."""
    path = _sweep(tmp_path, grid={"bsp.levels": [4, 5]})
    done = run_sweep(path, tmp_path / "o", jobs=1, overrides=["arch.context_switch_cycles=0"])
    assert done.ok == 2
    assert done.warnings == [f"{path}: --set arch.context_switch_cycles=0 changed nothing in any of the 2 points "
                             f"{HASH}: {SWITCH}"]


# ------------------------------------------------------------------ 2: a section beside a factor


def test_a_section_set_that_leaves_the_factor_is_taken_and_the_factor_set_in_it(tmp_path):
    path = _sweep(tmp_path, grid={"bsp.levels": [4, 5]})
    sw = load_sweep(path, ["bsp={memory_factor: 10}"])
    assert [(p.config["bsp"]["levels"], p.config["bsp"]["memory_factor"]) for p in sw.points] == [(4, 10), (5, 10)]
    # it merges into the base's section, as tlm run --set does (arch.pipelines of set: kept there too)
    path = _sweep(tmp_path, set={"arch.pipelines": 2}, grid={"arch.fifo_depth": [4, 16]})
    sw = load_sweep(path, ["arch={page_miss_cycles: 5}"])
    run_file = tmp_path / "run.yaml"
    run_file.write_text(yaml.safe_dump({**BASE, "arch": {**BASE["arch"], "pipelines": 2}}))
    cfg, _ = load_config(run_file, ["arch={page_miss_cycles: 5}"])
    for p, depth in zip(sw.points, (4, 16), strict=True):
        assert p.config["arch"] == {**to_dict(cfg)["arch"], "fifo_depth": depth}


def test_a_section_set_that_sets_the_factor_is_refused_with_the_dotted_form(tmp_path):
    path = _sweep(tmp_path, grid={"bsp.levels": [4, 5]})
    with pytest.raises(InputError) as e:
        load_sweep(path, ["bsp={levels: 3, memory_factor: 10}"])
    assert str(e.value) == (f"{path}: --set bsp={{levels: 3, memory_factor: 10}}: bsp holds bsp.levels, a factor of "
                            "the sweep (grid.bsp.levels), which gives each point its value: change its values in the "
                            "sweep file, not by --set; give its other keys one by one: --set bsp.memory_factor=10")
    with pytest.raises(InputError, match=r"bsp.levels is a factor of the sweep"):  # (the key itself, as before)
        load_sweep(path, ["bsp.levels=3"])


# ------------------------------------------------------------------ 3: a thesis cell's reference command


def test_the_reference_command_of_a_thesis_cell_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "th.yaml").write_text(yaml.safe_dump({
        "scenes": ["cornell"], "modes": ["pmap"],
        "base": {"resolution": [16, 16], "render": {"spp": 1, "light_samples": 1}, "photons": {"count": 1000},
                 "arch": {"frames": 1, "trace": False},
                 "reference": {"photons": 1000, "min_rounds": 2, "max_rounds": 4, "spp": 1}}}))
    assert main(["thesis", "th.yaml", "--out", "th", "--no-progress", "--no-report"]) == 0
    cell = tmp_path / "th" / "cornell" / "pmap"
    error = json.loads((cell / "results.json").read_text())["error"]
    assert error["available"] is False
    (tmp_path / "rep").mkdir()
    sec = images_section(read([cell]), tmp_path / "rep")
    said = [n for n in sec.notes if "error was not measured" in n]
    assert len(said) == 1, sec.notes
    command = said[0].split("compute it with: ", 1)[1].removesuffix(", then run it again")
    assert command == f"tlm reference {shlex.quote(str(cell / 'config.resolved.yaml'))}", command
    argv = shlex.split(command)
    capsys.readouterr()
    assert main([*argv[1:], "--no-progress"]) in (0, 1), capsys.readouterr()  # (1: not converged, cached)
    assert (tmp_path / "cache" / "references" / error["reference"] / "meta.json").is_file()  # (the cell's key)
