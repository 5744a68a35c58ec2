"""``tlm sweep --dry-run --reference`` looks at the cached references it counts (sweep_plan._cached_meta) without
using them: their files' access times stay as they were, which ``tlm cache prune`` reads as their last use (a
reference unused for 40 days was used now after a dry run, h517); a reference whose file is not the one its
meta.json describes is still not counted."""

from __future__ import annotations

import os
import time

import numpy as np

from tlm.experiments import sweep_plan
from tlm.experiments.reference_cache import save_reference

DAY = 86400.0


def test_a_dry_runs_look_at_a_cached_reference_is_no_use(cache):
    image = np.random.default_rng(1).random((8, 12, 3)).astype(np.float32)
    ref = save_reference("c" * 20, image, {"photons": 2000, "rounds": 4, "relative_standard_error": 0.01})
    files = sorted(ref.iterdir())
    t = time.time() - 40 * DAY
    for f in files:
        os.utime(f, (t, t))
    before = {f: (f.stat().st_atime_ns, f.stat().st_mtime_ns) for f in files}
    meta = sweep_plan._cached_meta("c" * 20)
    assert meta is not None and meta["rounds"] == 4
    assert {f: (f.stat().st_atime_ns, f.stat().st_mtime_ns) for f in files} == before
    data = bytearray((ref / "reference.npy").read_bytes())
    data[-1] ^= 0xFF  # (its bytes changed, its size not: the checksum tells)
    (ref / "reference.npy").write_bytes(bytes(data))
    assert sweep_plan._cached_meta("c" * 20) is None
    (ref / "reference.npy").unlink()
    (ref / "reference.npy").mkdir()  # (a folder in its place)
    assert sweep_plan._cached_meta("c" * 20) is None
