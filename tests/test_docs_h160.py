"""`tlm run --seed/--mode`: a bad value is named by the flag the user typed, not blamed on --set, and the
flags are still recorded in results.json's `overrides` as the --set they amount to (docs/usage.md, the
`config`, `overrides` row)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tlm.cli import main

REPO = Path(__file__).resolve().parents[1]
CORNELL = str(REPO / "configs" / "cornell.yaml")


@pytest.mark.parametrize("extra", [[], ["--set", "resolution=[8,8]", "--mode", "rcast"]])
def test_bad_seed_named_by_its_flag(tmp_path, capsys, extra):
    out = tmp_path / "r"
    assert main(["run", CORNELL, "--seed", "-1", "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == f"tlm: error: {CORNELL}, with --seed -1: seed: -1 must be >= 0"
    assert not out.exists()


def test_flags_recorded_as_set_and_only_a_bad_one_blamed(tmp_path, capsys):
    """Good flags are recorded as the --set they amount to; a bad --set beside a good --seed is still the --set's
    error, and a bad --seed beside a good --set is the --seed's."""
    out = tmp_path / "r"
    assert main(["run", CORNELL, "--set", "resolution=[8,8]", "--mode", "rcast", "--seed", "3", "--out", str(out),
                 "--no-report", "--no-progress"]) == 0
    results = json.loads((out / "results.json").read_text())
    assert results["overrides"] == ["resolution=[8,8]", "mode=rcast", "seed=3"]
    assert (results["seed"], results["mode"]) == (3, "rcast")
    capsys.readouterr()
    for sets, seed, said in ((["--set", "render.spp=0"], "1", "with --set: render.spp: 0 must be >= 1"),
                             (["--set", "render.spp=2"], "-2", "with --seed -2: seed: -2 must be >= 0")):
        bad = tmp_path / f"bad{seed}"
        assert main(["run", CORNELL, *sets, "--seed", seed, "--out", str(bad)]) == 2
        assert capsys.readouterr().err.strip().splitlines()[-1] == f"tlm: error: {CORNELL}, {said}"
        assert not bad.exists()
