"""For the lead, with /tmp/h174/api.patch and /tmp/h174/sweep_file.patch (files outside h174's list):
``tlm reference --set render={}`` says it sets nothing, once; a sweep's factor ``photons: [{}, null]``
over a base without ``photons`` is refused naming the values that give one config, not with the
render.threads advice (which a render.threads factor keeps)."""

from __future__ import annotations

import pytest

from tests.helpers_yaml import yaml_file as _file
from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.sweep_file import load_sweep

WHY = "sets nothing (a mapping given for a section merges into it key by key, and this one names no key)"
REFERENCE = {"photons": 800, "k_nearest": 20, "tolerance": 0.5, "min_rounds": 2, "max_rounds": 2, "spp": 1}
BASE = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1}, "arch": {"frames": 1}}

pytestmark = pytest.mark.usefixtures("cache")


def test_tlm_reference_says_an_empty_set_once(tmp_path, capsys):
    cfg = _file(tmp_path, "c.yaml", {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "reference": REFERENCE})
    assert main(["reference", str(cfg), "--no-progress", "--set", "render={}", "--set", "render={}"]) == 0
    err = capsys.readouterr().err
    assert [line for line in err.splitlines() if "sets nothing" in line] == [
        f"tlm: warning: --set render={{}} has no effect in this run: it {WHY}; --set render=null gives the section "
        "at its defaults"]


def test_a_sweeps_values_of_one_config_are_named_without_the_threads_advice(tmp_path):
    path = _file(tmp_path, "sw.yaml", {"base": BASE, "grid": {"photons": [{}, {"count": 1000}, None]}})
    with pytest.raises(InputError) as e:
        load_sweep(path)
    assert "render.threads" not in str(e.value)
    assert "points 0 and 2 are one run: photons: {} and null give the same config" in str(e.value)
    threads = _file(tmp_path, "th.yaml", {"base": BASE, "grid": {"render": [{"threads": 1}, {"threads": 2}]}})
    with pytest.raises(InputError, match=r"give render\.threads under set:"):  # (the threads: the advice kept)
        load_sweep(threads)
