"""``seed`` takes 0 .. 2**64 - 1, the values the kernels keep apart (their hash key is the seed
masked to 64 bits): a larger seed would silently render the image of ``seed mod 2**64``, so it is
a one-line error naming the key and the value (exit 2 on the command line)."""

from __future__ import annotations

import numpy as np
import pytest

import tlm
from tlm.cli import main

TOP = 2**64 - 1
SMALL = {"mode": "reflect", "resolution": [16, 16], "render.spp": 1, "render.light_samples": 4}


def test_the_largest_seed_renders_its_own_image_and_one_more_is_refused():
    top = tlm.render_image(tlm.load_config("cornell", {**SMALL, "seed": TOP})).composite
    zero = tlm.render_image(tlm.load_config("cornell", {**SMALL, "seed": 0})).composite
    assert not np.array_equal(top, zero)
    for seed in (TOP + 1, 2**64 + 1, 2**70):
        with pytest.raises(tlm.InputError, match=rf"cornell\.yaml, with the overrides: seed: {seed} must be <= {TOP}$"):
            tlm.load_config("cornell", {**SMALL, "seed": seed})


def test_a_config_file_with_too_large_a_seed_names_the_file(tmp_path):
    path = tmp_path / "big.yaml"
    path.write_text(f"scene: cornell\nmode: rcast\nseed: {2**64}\n")
    with pytest.raises(tlm.InputError, match=rf"big\.yaml: seed: {2**64} must be <= {TOP}$"):
        tlm.load_config(path)


def test_the_command_line_refuses_too_large_a_seed_with_exit_2(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", "cornell", "--seed", str(2**64), "--out", str(out), "--set", "resolution=[16,16]",
                 "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2, err
    errors = [line for line in err.splitlines() if line.startswith("tlm: error:")]
    assert len(errors) == 1 and f"seed: {2**64} must be <= {TOP}" in errors[0], err
    assert "Traceback" not in err
    assert not out.exists() and list(tmp_path.iterdir()) == []
