"""A ``--dask local`` worker keys its frames with the sweep's code fingerprint (h182): the cluster is the
sweep's own (same machine, same files), its points' hashes hold the sweep's fingerprint, and a worker
that hashed the package on the disk at its first point, after an edit of the checkout meanwhile, filed the
frames of the code it loaded under another code's key (a local pool's worker takes the sweep's already:
tests/test_sweep_damaged_once.py). A remote scheduler's worker of other code is refused, with why, as
before (tests/test_dask_cluster.py, ``OtherCodeOnWorker``)."""

from __future__ import annotations

import json

import pytest
import yaml

from tlm import fingerprint
from tlm.config import config_from_dict
from tlm.experiments import frames
from tlm.experiments.sweep import run_sweep

pytest.importorskip("distributed")

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False}}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


@pytest.mark.slow
def test_a_dask_local_worker_keys_its_frame_with_the_sweeps_code_fingerprint(tmp_path, monkeypatch):
    """The package edited since this process took its code fingerprint (as a checkout worked on while a
    sweep runs): the points' results hold the frame key the sweep computed, and the frame is cached under
    it. The worker took the disk's fingerprint: another key, a frame filed under another code's key."""
    monkeypatch.setattr(fingerprint, "_CODE", "0123456789abcdef")  # (not the disk's: as after an edit)
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [1, 16]}}))
    done = run_sweep(path, tmp_path / "o", jobs=1, dask="local")
    assert (done.ok, done.failed, done.renders) == (2, 0, 1), done.rows
    key = frames.render_key(config_from_dict(BASE, "base"))
    held = [json.loads((tmp_path / "o" / "points" / r["hash"] / "results.json").read_text())
            for r in done.rows]
    assert [r["functional"]["key"] for r in held] == [key, key]
    assert [r["code_fingerprint"] for r in held] == ["0123456789abcdef"] * 2
    assert frames.is_cached(key)
    assert sorted(r["functional_cached"] for r in done.rows) == [False, True]  # (the second read the first's)
