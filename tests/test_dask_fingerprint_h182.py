"""A worker of the sweep's own ``--dask local`` cluster runs the code the sweep hashed, or its points fail
with why (h182, after a review): the cluster's workers are new interpreters that import tlm from the disk
as they start, so a package edited after the sweep took its code fingerprint is other code; its frames
must be filed under neither the sweep's key (another code's frames under it) nor a key of their own that
the sweep does not read. A local pool's worker takes the sweep's (its fork server imported the code at the
sweep's start: tests/test_sweep_damaged_once.py); a remote worker of other code is refused the same way
(tests/test_dask_cluster.py, ``OtherCodeOnWorker``)."""

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
def test_a_dask_local_worker_of_other_code_than_the_sweeps_fails_its_points_with_why(tmp_path, monkeypatch):
    """The package edited since this process took its code fingerprint (as a checkout worked on while a
    sweep runs; here the sweep's fingerprint is not the disk's): each point fails naming both
    fingerprints, and no frame is filed under the sweep's key. Before, the worker took the sweep's
    fingerprint and filed the frames of the code it had imported under it."""
    monkeypatch.setattr(fingerprint, "_CODE", "0123456789abcdef")  # (not the disk's: as after an edit)
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [1, 16]}}))
    done = run_sweep(path, tmp_path / "o", jobs=1, dask="local")
    assert (done.ok, done.failed) == (0, 2), done.rows
    disk = fingerprint.fingerprint()
    for r in done.rows:
        error = json.loads((tmp_path / "o" / "points" / r["hash"] / "error.json").read_text())
        assert error["type"] == "OtherCodeOnWorker", error
        assert disk in error["message"] and "the sweep's 0123456789abcdef" in error["message"], error
    assert not frames.is_cached(frames.render_key(config_from_dict(BASE, "base")))
