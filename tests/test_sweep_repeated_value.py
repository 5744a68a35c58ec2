"""A factor value given twice (``grid: {arch.fifo_depth: [1, 1]}``) is refused (exit 2, one line,
nothing written): its points are one run, and were run once but written as two rows of one hash
in ``sweep.csv``, which the report counted as two runs. As points that differ only in
``render.threads`` are refused as one run with two labels (sweep_checks.one_run_one_row)."""

from __future__ import annotations

import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.sweep_file import load_sweep

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [24, 16], "render": {"light_samples": 1},
        "arch": {"frames": 1, "trace": False, "packet_size": 32}}


def sweep_file(tmp_path, **body):
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, **body}, sort_keys=False))
    return path


@pytest.mark.parametrize("body, said", [
    ({"grid": {"arch.fifo_depth": [1, 1]}}, "grid.arch.fifo_depth: 1 given twice"),
    ({"grid": {"arch.fifo_depth": [1, 2], "seed": [0, 3, 0]}}, "grid.seed: 0 given twice"),
    ({"grid": {"resolution": [[24, 16], [16, 16], [24, 16]]}}, "grid.resolution: [24, 16] given twice"),
    ({"grid": {"scene": ["cornell", "cornell"]}}, "grid.scene: cornell given twice"),
    ({"zip": {"seed": [0, 1, 0]}}, "zip.seed: 0 given twice"),
    ({"zip": {"seed": [0, 1, 0], "arch.fifo_depth": [1, 2, 1]}}, "zip: seed=0, arch.fifo_depth=1 given twice "
                                                                  "(at 0 and 2)"),
    # one float written two ways: other values to the eye, one run
    ({"grid": {"arch.clock_hz": [1000000000, 1.0e9]}},
     "arch.clock_hz: points 0 and 1 are one run: 1000000000 and 1e9 are one value, given twice"),
])
def test_a_value_given_twice_exits_2_and_writes_nothing(tmp_path, capsys, body, said):
    path = sweep_file(tmp_path, **body)
    assert main(["sweep", str(path), "--out", str(tmp_path / "o"), "--jobs", "1", "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"tlm: error: {path}: {said}"]
    assert not (tmp_path / "o").exists()


def test_a_zip_repeats_only_where_all_its_values_do(tmp_path):
    """A zip key's value at two places is no repeat while another zip key's values there differ
    (two points); all of them alike is one."""
    points = load_sweep(sweep_file(tmp_path, zip={"seed": [0, 1, 0], "arch.fifo_depth": [1, 2, 3]})).points
    assert [(p.factors["seed"], p.factors["arch.fifo_depth"]) for p in points] == [(0, 1), (1, 2), (0, 3)]
    assert len({p.hash for p in points}) == 3
    with pytest.raises(InputError, match=r"zip: seed=0, arch.fifo_depth=3 given twice \(at 0 and 2\)"):
        load_sweep(sweep_file(tmp_path, zip={"seed": [0, 1, 0], "arch.fifo_depth": [3, 2, 3]}))
