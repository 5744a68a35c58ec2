"""benchmarks/bench_raytrace.py traces each kind of ray once outside its timed rounds."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("embreex")

from tlm.kernels.engine import engine
from tlm.kernels.traverse import any_hit, closest_hit


@pytest.mark.slow  # (a whole bench scene: Cornell BSP, Embree and two kernels; about 6 s CPU)
def test_the_bench_takes_the_hits_and_counts_from_the_untimed_first_trace(monkeypatch):
    """The compiled kernel's untimed first call on the eye rays (the one that loads it)
    gives the hits the shadow rays start from and the eye rays' work per ray; the shadow
    rays' untimed first call gives theirs: with ``--repeat 1`` the compiled kernel traces
    each kind of ray on the scene's tree twice (that call and the round), not three times,
    and the rows' work per ray is a fresh trace's."""
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    monkeypatch.delenv("TLM_KERNELS", raising=False)
    import bench_raytrace

    trees, calls, rays = [], Counter(), {}
    build = bench_raytrace.build_accel

    def built(*args, **kwargs):
        trees.append(build(*args, **kwargs))
        return trees[-1]

    def counted(fn):
        def call(accel, o, d, **kwargs):
            if accel is trees[0]:  # (the scene's tree, not the walk floor's copy)
                calls[fn.__name__, engine()] += 1
                rays[fn.__name__] = (o, d, kwargs)
            return fn(accel, o, d, **kwargs)
        return call

    monkeypatch.setattr(bench_raytrace, "build_accel", built)
    monkeypatch.setattr(bench_raytrace, "closest_hit", counted(closest_hit))
    monkeypatch.setattr(bench_raytrace, "any_hit", counted(any_hit))
    monkeypatch.setattr(bench_raytrace, "engine_time", lambda *_: 1.0)  # (the numpy reference's: slow, not checked)
    _, rows = bench_raytrace.bench_scene("cornell", 1)
    assert calls[("closest_hit", "numba")] == 2 and calls[("any_hit", "numba")] == 2, calls
    for (kind, n, *_, work), fn in zip(rows, (closest_hit, any_hit), strict=True):
        o, d, kwargs = rays[fn.__name__]
        fresh = fn(trees[0], o, d, **kwargs)
        assert n == o.shape[0] and work == bench_raytrace.per_ray(fresh.counts), (kind, work)
    assert [kind for kind, *_ in rows] == ["primary", "shadow"] and np.isfinite(rows[1][2].ours).all()
