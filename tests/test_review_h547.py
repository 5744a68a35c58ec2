"""Review h547 of 0ed6c79 and d5bf3b6: Streams.of of a cache section given in part (a mapping, as a config file
gives it, or an object with some keys), and Timing.warnings kept by dataclasses.replace."""

from __future__ import annotations

import pickle
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from tlm.arch.frame_program import FrameProgram, JobSpec, PhaseSpec
from tlm.arch.model import simulate_program
from tlm.config import config_from_dict
from tlm.kernels.memory import PAGE_WORDS, PAIRS, Streams


def test_streams_of_a_section_given_in_part_takes_the_defaults_for_the_rest():
    assert Streams.of({"pairs": 2}).settings() == {"page_words": PAGE_WORDS, "pairs": 2}
    assert Streams.of(SimpleNamespace(block_words=8)).settings() == {"page_words": 8, "pairs": PAIRS}
    cfg = config_from_dict({"scene": "cornell", "cache": {"pairs": 2}}, "test")
    assert Streams.of(cfg.cache).settings() == Streams.of({"pairs": 2}).settings()
    with pytest.raises(ValueError, match=r"^cache\.ways is no setting of the cache model"):
        Streams.of({"pairs": 2, "ways": 4})


def test_a_timings_warnings_survive_replace_and_pickle():
    n = np.asarray([4, 4], dtype=np.int64)
    job = JobSpec("vertex", "test", 0, n, np.zeros_like(n), np.zeros_like(n), np.ones_like(n))
    arch = config_from_dict({"arch": {"frames": 1}}, "test").arch
    t = simulate_program(FrameProgram.linear([PhaseSpec("v", (job,), 0)]), arch)
    assert t.warnings is None  # (not made here: tlm.simulate makes them)
    t.warnings = ["a caveat"]
    assert replace(t, fps=1.0).warnings == ["a caveat"]
    assert pickle.loads(pickle.dumps(t)).warnings == ["a caveat"]
