"""A sweep's own line on a factor that no point read, judged after the points ran: the
timing keys each point changed from their defaults and never read (results.json
``inert``: tlm.experiments.run_warnings.inert_timing_changes), summed up once for the sweep
(tlm.experiments.sweep_file.Sweep.unread_factors), where each point's warnings say it
for the point alone."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tlm.experiments.sweep import run_sweep
from tlm.experiments.sweep_file import load_sweep

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 1, "images_in_flight": 1, "trace": False, "packet_size": 16}}
SWAP = "no PM moved to another module (timing.crossbar.swaps is 0)"
SWITCH = "arch.images_in_flight is 1 (a PM never has an older image's job to switch to)"


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _sweep(tmp_path: Path, name: str, **body) -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump({"base": BASE, **body}, sort_keys=False))
    return path


def test_a_factor_no_point_read_is_named_once_at_the_end(tmp_path, capsys):
    """One image in flight: no PM ever moves to another module, so arch.swap_cycles is read
    by no point (the run tells), and arch.context_switch_cycles by none (the config tells).
    Each point's warnings name them where it set them away from their defaults; the sweep
    names each once, with why, on stderr and in its outcome; a rerun (every point done
    before) says it again."""
    path = _sweep(tmp_path, "s.yaml", grid={"arch.swap_cycles": [2, 9], "arch.context_switch_cycles": [16, 0]})
    done = run_sweep(path, tmp_path / "o", jobs=1)
    assert done.ok == 4 and done.failed == 0
    lines = [f"{path}: the factor arch.swap_cycles changed nothing in any of the 4 points: {SWAP}",
             f"{path}: the factor arch.context_switch_cycles changed nothing in any of the 4 points: "
             f"{SWITCH}"]
    assert done.warnings == lines
    assert "the factor" not in capsys.readouterr().err  # (the library prints none: tlm sweep does)
    for row in done.rows:
        results = json.loads((tmp_path / "o" / "points" / row["hash"] / "results.json").read_text())
        assert results["inert"] == {**({"arch.context_switch_cycles": SWITCH} if row["arch.context_switch_cycles"] == 0
                                       else {}),
                                    **({"arch.swap_cycles": SWAP} if row["arch.swap_cycles"] == 9 else {})}
        assert (f"arch.swap_cycles = 9 has no effect in this run: {SWAP}" in results["warnings"]) == \
            (row["arch.swap_cycles"] == 9)
    assert len({r["cycles.throughput"] for r in done.rows}) == 1  # (the cycles bear it out)
    again = run_sweep(path, tmp_path / "o", jobs=1)
    assert again.skipped == 4 and again.warnings == lines


def test_a_factor_some_point_read_is_not_named(tmp_path, capsys):
    """With two images in flight the PMs move between the images' modules: arch.swap_cycles
    counts there, so no line for it, though the one-image points never read it."""
    path = _sweep(tmp_path, "s.yaml", set={"arch.frames": 2},
                  grid={"arch.images_in_flight": [1, 2], "arch.swap_cycles": [2, 9]})
    done = run_sweep(path, tmp_path / "o", jobs=1)
    assert done.ok == 4
    assert done.warnings == []
    assert "the factor" not in capsys.readouterr().err
    read = [r for r in done.rows if r["arch.images_in_flight"] == 2]
    assert len({r["cycles.throughput"] for r in read}) == 2  # (swap_cycles changed these points' cycles)


def test_unread_factors_judges_the_points_that_ran(tmp_path):
    """A point at the factor's default agrees (its run is the one the others equal), a point
    that read it disagrees, a failed point (not given) has no say, a factor named before the
    points ran is not named again."""
    path = _sweep(tmp_path, "s.yaml", grid={"arch.swap_cycles": [2, 9, 20], "photons.count": [1000, 2000]})
    sw = load_sweep(path)
    assert sw.inert_factors() == [f"{path}: the factor photons.count changes nothing in any point: the photon-map "
                                  "pass does not run (mode 'rcast' does not include the pmap (photon-map) pass)"]
    by_swap = {v: [p for p in sw.points if p.factors["arch.swap_cycles"] == v] for v in (2, 9, 20)}
    unread = {"inert": {"arch.swap_cycles": SWAP, "photons.count": "x"}}
    done = [(p, {"inert": {}}) for p in by_swap[2]] + [(p, unread) for p in by_swap[9] + by_swap[20]]
    assert sw.unread_factors(done) == [f"{path}: the factor arch.swap_cycles changed nothing in any of the 6 points: "
                                       f"{SWAP}"]
    read = done[:-1] + [(by_swap[20][-1], {"inert": {}})]  # (a point at 20 that read it)
    assert sw.unread_factors(read) == []
    assert sw.unread_factors(done[:-1]) != []  # (that point failed: the rest agree)
    assert sw.unread_factors([done[-1]]) == [f"{path}: the factor arch.swap_cycles changed nothing in the one point: "
                                             f"{SWAP}"]
    assert sw.unread_factors([(p, {"inert": {}}) for p in by_swap[2]]) == []  # (every point at the default)
    assert sw.unread_factors([(p, {}) for p in by_swap[9]]) == []  # (results without the record: unknown)
    assert sw.unread_factors([]) == []
