"""What runs on a Dask worker, or checks one, has a module of its own
(:mod:`tlm.experiments.dask_workers`); :mod:`tlm.experiments.executors` keeps the executors
that hand the points out. A sweep point (:mod:`tlm.experiments.sweep_point`) imports the
worker's names from the new module, so a test that patches
``tlm.experiments.sweep_point.dask_worker_where`` still reaches the point; a patch of a
name that left executors fails loudly (no copy is left there to patch in vain)."""

from __future__ import annotations

import tlm.experiments.dask_workers as dask_workers
import tlm.experiments.executors as executors
import tlm.experiments.sweep_point as sweep_point

MOVED = ("dask_worker_threads", "dask_worker_where", "worker_versions", "check_worker_versions",
         "OtherVersionsOnWorker", "RESULT_VERSIONS", "SLOTS_TTL", "_SLOTS", "_VERSIONS", "_LABELS",
         "_result_version")
SWEEP_USES = ("dask_worker_threads", "dask_worker_where", "worker_versions", "check_worker_versions",
              "OtherVersionsOnWorker")


def test_the_dask_worker_side_lives_in_its_own_module_and_left_the_executors():
    for name in MOVED:
        assert hasattr(dask_workers, name), name
        assert not hasattr(executors, name), f"executors still holds {name}"
    for name in SWEEP_USES:
        assert getattr(dask_workers, name).__module__ == "tlm.experiments.dask_workers", name


def test_the_sweep_holds_the_dask_workers_own_objects_where_a_test_patches_them():
    """tests/test_sweep_worker_versions.py patches ``sweep_point.dask_worker_where``: run_point
    calls the name it imported, which must be the function itself (not a wrapper that looks it up
    elsewhere)."""
    for name in SWEEP_USES:
        assert getattr(sweep_point, name) is getattr(dask_workers, name), name
    assert dask_workers.dask_worker_where() is None and dask_workers.dask_worker_threads() is None  # (no worker)
