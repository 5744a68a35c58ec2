"""The typed seam between the functional layer and the timing model (tlm.arch.functional).

The render hands over plain dicts of per-item work (tlm.render.passes WORK_KEYS and
GATHER_KEYS, tlm.kernels.photons PHOTON_WORK, the BSP's LevelWork); Functional holds
them as frozen, validated dataclasses. These tests keep the two sides in step (a new work
key of the render cannot be dropped on the way to the timing model), and check the
validation and the .npz round trip.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tlm.arch.functional import (
    FORMAT,
    GATHER_PASS,
    RAY_PASSES,
    BuildLevelWork,
    Functional,
    GatherWork,
    PhotonWork,
    RayPassWork,
    TreeWork,
    WorkArrays,
)
from tlm.arch.program import PHOTON_TRACE, RAY_TRACE, SHADOW_TRACE
from tlm.arch.programs import load_programs, work_keys
from tlm.config import config_from_dict
from tlm.kernels.bsp import LevelWork
from tlm.kernels.photons import PHOTON_WORK
from tlm.render.passes import GATHER_KEYS, PASS_FUNCTIONS, WORK_KEYS
from tlm.render.planner import PASSES, WORK_PASSES

CLASSES = (RayPassWork, GatherWork, PhotonWork, BuildLevelWork)


@pytest.fixture(scope="module")
def res():
    from tlm.experiments.run import render

    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "resolution": [12, 10],
                            "photons": {"count": 600}, "estimate": {"final_gather": 0}}, "test")  # the four frames
    return render(cfg)


@pytest.fixture(scope="module")
def fn(res):
    return Functional.of(res)


# -- the two sides agree -------------------------------------------------------------------

def test_the_fields_are_the_renders_keys_in_order():
    assert RayPassWork.KEYS == WORK_KEYS
    assert GatherWork.KEYS == GATHER_KEYS
    assert PhotonWork.KEYS == PHOTON_WORK
    per_level = tuple(f.name for f in dataclasses.fields(LevelWork) if f.name != "level")
    assert per_level == BuildLevelWork.KEYS


def test_the_passes_are_the_planners():
    # the frames, and the work-only passes (final gathering's rays: a ray pass)
    assert (*(p for p in RAY_PASSES if p not in WORK_PASSES), GATHER_PASS) == PASSES
    assert set(WORK_PASSES) <= set(RAY_PASSES)
    assert tuple(PASS_FUNCTIONS) == RAY_PASSES


@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: c.__name__)
def test_every_field_is_documented_and_priceable(cls):
    keys = set(work_keys())
    for f in dataclasses.fields(cls):
        assert f.metadata.get("doc"), f"{cls.__name__}.{f.name} has no doc"
        assert f.name in keys, f"{cls.__name__}.{f.name} is not a work key of the program table"


def test_the_program_table_prices_only_known_work():
    progs = load_programs()
    keys = set(work_keys())
    for (pm, job), p in progs.jobs.items():
        assert set(p.instructions) | set(p.flushes) <= keys, (pm, job)


def test_the_trace_fields_name_fields_of_their_work():
    for trace, cls in ((RAY_TRACE, RayPassWork), (SHADOW_TRACE, RayPassWork), (PHOTON_TRACE, PhotonWork)):
        assert set(trace.rays) | {trace.tris, trace.isect_misses} <= set(cls.KEYS)


def test_a_new_render_key_is_not_dropped_silently():
    work = {k: np.zeros(4, dtype=np.int64) for k in WORK_KEYS}
    with pytest.raises(ValueError, match=r"unknown.*ray_budget"):
        RayPassWork.from_mapping({**work, "ray_budget": np.ones(4, dtype=np.int64)})
    del work["fragments"]
    with pytest.raises(ValueError, match=r"missing.*fragments"):
        RayPassWork.from_mapping(work)


# -- Functional.of -------------------------------------------------------------------------

def test_of_a_render_is_typed_and_keeps_every_count(res, fn):
    assert fn.passes == tuple(res.plan.run_names) == PASSES
    for p in PASSES[:-1]:  # (the fixture renders without final gathering: the thesis's four frames)
        assert type(fn.work[p]) is RayPassWork and fn.ray_work(p) is fn.work[p]
    assert type(fn.work[GATHER_PASS]) is GatherWork and fn.gather_work is fn.work[GATHER_PASS]
    assert type(fn.photon_work) is PhotonWork and type(fn.geometry.levels) is BuildLevelWork
    for p in fn.passes:
        assert fn.work[p].n == fn.pixels == 120
        for k in fn.work[p].KEYS:
            np.testing.assert_array_equal(getattr(fn.work[p], k), np.asarray(res.work[p][k]).reshape(-1))
    for k in PHOTON_WORK:
        np.testing.assert_array_equal(getattr(fn.photon_work, k), res.photons.work[k])
    assert fn.photon_work.n == 600 and fn.photon_work.totals()["photons_emitted"] == 600
    assert fn.geometry.n_levels == res.accel.tree.levels
    assert fn.photon_tree.n_elements == res.photons.photons.n


def test_the_work_reads_as_a_mapping(fn):
    w = fn.ray_work("rcast")
    assert list(w) == list(WORK_KEYS) == list(w.keys()) and len(w) == len(WORK_KEYS)
    assert w["tri_tests"] is w.tri_tests and w.get("nope") is None and "fragments" in w
    with pytest.raises(KeyError):
        w["nope"]
    assert dict(w.items()) == {k: getattr(w, k) for k in WORK_KEYS}


def test_the_work_is_frozen_and_read_only(fn):
    w = fn.ray_work("rcast")
    with pytest.raises(dataclasses.FrozenInstanceError):
        w.tri_tests = np.zeros(fn.pixels, dtype=np.int64)
    with pytest.raises(ValueError):
        w.tri_tests[0] = 5
    with pytest.raises(dataclasses.FrozenInstanceError):
        fn.pixels = 3


def test_replace_with_dicts_gives_typed_work(fn):
    """``dataclasses.replace(fn, work=...)`` with plain dicts (tests edit work that way) converts them."""
    work = {p: {k: v * 2 for k, v in w.items()} for p, w in fn.work.items()}
    doubled = dataclasses.replace(fn, work=work)
    assert type(doubled.work["pmap"]) is GatherWork
    assert doubled.ray_work("reflect").totals()["tri_tests"] == 2 * fn.ray_work("reflect").totals()["tri_tests"]
    assert doubled != fn and dataclasses.replace(fn) == fn


# -- validation ----------------------------------------------------------------------------

def _ray(n=4, **over):
    return RayPassWork(**{k: np.zeros(n, dtype=np.int64) for k in WORK_KEYS} | over)


@pytest.mark.parametrize("bad, match", [
    ({"tri_tests": np.zeros(4)}, "int64"),  # float
    ({"tri_tests": np.zeros(4, dtype=np.int32)}, "int64"),  # the constructor does not convert
    ({"tri_tests": np.zeros((2, 2), dtype=np.int64)}, "1-D"),
    ({"tri_tests": np.zeros(5, dtype=np.int64)}, "5 pixels"),
    ({"tri_tests": np.array([0, -1, 0, 0])}, "negative"),
    ({"tri_tests": [0, 0, 0, 0]}, "numpy array"),
])
def test_work_arrays_are_validated(bad, match):
    with pytest.raises(ValueError, match=match):
        _ray(**bad)


def test_from_mapping_converts_integers_and_shapes_but_not_floats():
    work = {k: np.zeros((2, 2), dtype=np.int32) for k in GATHER_KEYS}
    g = GatherWork.from_mapping(work)
    assert g.n == 4 and all(v.dtype == np.int64 and v.ndim == 1 for v in g.values())
    with pytest.raises(ValueError, match="integers"):
        GatherWork.from_mapping({**work, "gathers": np.zeros(4)})
    assert GatherWork.zeros(3) == GatherWork.from_mapping({k: [0, 0, 0] for k in GATHER_KEYS})


def test_functional_is_validated(fn):
    with pytest.raises(ValueError, match="passes"):
        dataclasses.replace(fn, passes=fn.passes[:-1])  # work of a pass not rendered
    with pytest.raises(ValueError, match="GatherWork"):
        dataclasses.replace(fn, work={**fn.work, "pmap": fn.work["rcast"]})
    with pytest.raises(ValueError, match="pixels"):
        dataclasses.replace(fn, pixels=fn.pixels - fn.width)
    with pytest.raises(ValueError, match="rows"):
        dataclasses.replace(fn, width=7)
    with pytest.raises(ValueError, match="together"):
        dataclasses.replace(fn, photon_tree=None)
    with pytest.raises(ValueError, match="unknown pass"):
        dataclasses.replace(fn, passes=("rcast", "smoke"), work={"rcast": fn.work["rcast"], "smoke": fn.work["rcast"]})
    with pytest.raises(ValueError, match="PhotonWork"):
        dataclasses.replace(fn, photon_work=fn.work["pmap"])
    with pytest.raises(ValueError, match="whole number"):
        dataclasses.replace(fn.geometry, nodes=-1)
    assert isinstance(fn.work["rcast"], WorkArrays)


def test_a_frame_without_photons():
    n = 6
    fn = Functional(("rcast",), {"rcast": {k: np.ones(n, dtype=np.int64) for k in WORK_KEYS}},
                    TreeWork({f: np.ones(2, dtype=np.int64) for f in BuildLevelWork.KEYS}, 10, 12, 7),
                    None, None, n, 3)
    assert fn.gather_work is None and fn.height == 2 and type(fn.geometry.levels) is BuildLevelWork


# -- persistence ---------------------------------------------------------------------------

def test_save_load_round_trip(fn, tmp_path):
    fn.save(tmp_path / "f.npz")
    back = Functional.load(tmp_path / "f.npz")
    assert back == fn
    assert type(back.work["pmap"]) is GatherWork and type(back.photon_work) is PhotonWork


def test_an_entry_that_does_not_fit_is_a_value_error(fn, tmp_path):
    """The functional cache (tlm.experiments.frames) renders again on a ValueError."""
    short = dataclasses.replace(fn, work={p: dict(w) for p, w in fn.work.items()})
    short.save(tmp_path / "ok.npz")
    with np.load(tmp_path / "ok.npz") as z:
        arrays = {k: z[k] for k in z.files if k != "work/rcast/fragments"}
    np.savez_compressed(tmp_path / "short.npz", **arrays)
    with pytest.raises(ValueError, match="fragments"):
        Functional.load(tmp_path / "short.npz")
    arrays["meta"] = np.frombuffer(bytes(arrays["meta"]).replace(FORMAT.encode(), b"functional/0"), np.uint8)
    np.savez_compressed(tmp_path / "old.npz", **arrays)
    with pytest.raises(ValueError, match="format"):
        Functional.load(tmp_path / "old.npz")


def test_pickled_work_is_validated_again(fn):
    """Sweeps may hand a Functional to a worker process: it arrives typed and read-only."""
    import pickle

    back = pickle.loads(pickle.dumps(fn))
    assert back == fn and type(back.work["rcast"]) is RayPassWork
    assert not back.work["rcast"].tri_tests.flags.writeable
