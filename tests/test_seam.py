"""The work schema (tlm.kernels.work) and the typed seam to the timing model (tlm.arch.functional).

The work that crosses from the render to the timing model is declared once, in
tlm.kernels.work; the render's key tuples, the typed arrays, the miss keys and the check
of a program table derive from it. These tests check that the schema is complete: every
work item a pass or the photon tracer produces is declared, the timing model charges
every declared item to exactly the units the schema names (or the schema says why none
does), and a program table that leaves out an item its job charges fails with a
one-line error. Then the validation of the typed work and the .npz round trip.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml

from tlm.arch.costs import DEFAULT_PATH, JOBS, load_programs
from tlm.arch.frame_program import frame_program
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
from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.kernels import work
from tlm.kernels.work import KINDS, MODEL_ITEMS
from tlm.render.passes import PASS_FUNCTIONS
from tlm.render.planner import PASSES, WORK_PASSES

ALL_PASSES = (*RAY_PASSES, GATHER_PASS)


@pytest.fixture(scope="module")
def res():
    from tlm.experiments.run import render

    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "resolution": [12, 10],
                            "photons": {"count": 600}, "estimate": {"final_gather": 2}}, "test")
    return render(cfg)  # the four frames and the final-gather rays


@pytest.fixture(scope="module")
def fn(res):
    return res.functional()


# -- the schema is complete ----------------------------------------------------------------

def test_every_item_a_pass_produces_is_declared(res):
    assert set(res.plan.run_names) == set(ALL_PASSES)
    for p in res.plan.run_names:
        assert tuple(res.work[p]) == work.pass_work_class(p).KEYS, p
    assert tuple(res.photons.work) == PhotonWork.KEYS


def test_the_passes_are_the_planners():
    # the frames, and the work-only passes (final gathering's rays: a ray pass)
    assert (*(p for p in RAY_PASSES if p not in WORK_PASSES), GATHER_PASS) == PASSES
    assert set(WORK_PASSES) <= set(RAY_PASSES)
    assert tuple(PASS_FUNCTIONS) == RAY_PASSES


@pytest.mark.parametrize("cls", [*KINDS, None], ids=lambda c: "MODEL_ITEMS" if c is None else c.__name__)
def test_every_item_says_what_it_counts_and_who_charges_it(cls):
    items = MODEL_ITEMS if cls is None else cls.ITEMS
    jobs = {f"{pm}.{job}" for pm, names in JOBS.items() for job in names}
    for i in items:
        assert i.doc and "\n" not in i.doc, i.name
        assert set(i.charged) <= jobs | set(work.FIXED_UNITS), i.name
        assert bool(i.charged) != bool(i.uncharged), i.name
    if cls is not None:
        assert [f.metadata["item"] for f in dataclasses.fields(cls)] == list(items)


def test_an_item_names_its_units_or_why_none():
    with pytest.raises(ValueError, match="say why"):
        work.Item("x", "a count")
    with pytest.raises(ValueError, match="no unit"):
        work.Item("x", "a count", ("traversal",))


def test_the_stream_and_miss_keys_derive_from_the_items():
    assert work.MISS_KEYS == ("trav_misses", "isect_misses", "shadow_trav_misses", "shadow_isect_misses",
                              "frag_misses", "gather_misses")
    assert work.STREAM_KEYS["shadow_vertices"] == "shadow_isect_misses"
    assert work.stream_keys(PhotonWork) == {"nodes": "trav_misses", "indices": "trav_misses",
                                            "vertices": "isect_misses"}
    assert all(k.endswith("_misses") for k in work.STREAM_KEYS.values())


def _charges(fn: Functional, programs) -> dict[str, tuple[int, int, int]]:
    """Per unit ("pm.job", "intersection", "crossbar"): its cycles, misses and flushes (the
    crossbar: its words) in the frame program built from ``fn``."""
    prog = frame_program(fn, programs, config_from_dict({"scene": "cornell"}, "test").arch)
    out: dict[str, np.ndarray] = {}

    def add(unit, *v):
        out[unit] = out.get(unit, np.zeros(3, dtype=np.int64)) + np.array(v, dtype=np.int64)

    for stage in prog.stages:
        for fo in stage.fan_out:
            add("crossbar", fo.words, 0, 0)
        for tile in stage.tiles:
            add("crossbar", tile.returns, 0, 0)
            for ph in tile.phases:
                add("crossbar", ph.copy_words, 0, 0)
                for j in ph.jobs:
                    add("intersection" if j.pm == "intersection" else f"{j.pm}.{j.kind}",
                        j.norm.sum(), j.misses.sum(), j.flushes.sum())
    return {u: tuple(int(x) for x in v) for u, v in out.items()}


def _doubled(fn: Functional, cls: type[WorkArrays], key: str) -> Functional:
    """``fn`` with every count of ``key`` in its ``cls`` work doubled (which items run a
    phase does not change: a zero stays zero)."""
    def twice(w):
        return type(w)(**{k: v * 2 if k == key else v for k, v in w.items()})

    if cls is BuildLevelWork:
        trees = {t: dataclasses.replace(getattr(fn, t), levels=twice(getattr(fn, t).levels))
                 for t in ("geometry", "photon_tree")}
        return dataclasses.replace(fn, **trees)
    if cls is PhotonWork:
        return dataclasses.replace(fn, photon_work=twice(fn.photon_work))
    return dataclasses.replace(fn, work={p: twice(w) if isinstance(w, cls) else w for p, w in fn.work.items()})


@pytest.mark.slow
@pytest.mark.parametrize(("cls", "item"), [(c, i) for c in KINDS for i in c.ITEMS],
                         ids=lambda x: getattr(x, "__name__", getattr(x, "name", "")))
def test_the_timing_model_charges_each_item_to_its_units(fn, cls, item):
    """More of an item changes what exactly the units the schema names charge (every
    programmable PM's instructions weighed alike, scale 1); an uncharged item changes nothing."""
    programs = load_programs().with_scales(dict.fromkeys(("vertex", "traversal", "fragment"), 1.0))
    assert any(getattr(w, item.name, np.zeros(1)).any() for w in (*fn.work.values(), fn.photon_work,
                                                                  fn.geometry.levels)), "the fixture lacks it"
    base, more = _charges(fn, programs), _charges(_doubled(fn, cls, item.name), programs)
    changed = {u for u in base.keys() | more.keys() if base.get(u) != more.get(u)}
    expected = set(item.charged)
    if cls is BuildLevelWork and not fn.photon_tree.levels[item.name].any():
        expected.discard("vertex.photon_bsp")  # (a photon, a point, is never copied to both sides)
    assert changed == expected, item.uncharged or item.charged


# -- a program table is checked against the schema -----------------------------------------

def _table(tmp_path, edit):
    """The default table, edited by ``edit(raw)``, written to ``p.yaml``."""
    raw = yaml.safe_load(DEFAULT_PATH.read_text())  # (a fresh copy)
    edit(raw)
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(raw))
    return tmp_path / "p.yaml"


@pytest.mark.parametrize(("edit", "key", "what"), [
    (lambda r: r["fragment"]["light"]["flushes"].pop("shadow_hits"), "fragment.light",
     "does not price the work item 'shadow_hits'"),
    (lambda r: r["traversal"]["rays"]["records"].remove("primary_rays")
     or r["traversal"]["rays"]["instructions"].pop("primary_rays"), "traversal.rays",
     "does not price the work item 'primary_rays'"),
    (lambda r: r["vertex"]["photon_emit"].update(misses=None), "vertex.photon_emit",
     "does not price the work item 'stream_restarts'"),
    (lambda r: r["traversal"]["rays"]["instructions"].update(photons_tested=1),
     "traversal.rays.instructions.photons_tested", "unknown work item"),  # a gather's item, not a ray pass's
    (lambda r: r["traversal"]["rays"].update(misses="gather_misses"), "traversal.rays.misses",
     "'gather_misses' must be a work key or null (did you mean 'trav_misses'?)"),
])
def test_a_table_must_price_the_items_of_its_jobs(tmp_path, edit, key, what):
    path = _table(tmp_path, edit)
    with pytest.raises(InputError) as err:
        load_programs(path)
    assert str(err.value).startswith(f"{path}: {key}: {what}") and "\n" not in str(err.value)


def test_a_table_missing_an_item_exits_2(tmp_path, capsys):
    from tlm.cli import main

    def edit(raw):
        for part in ("instructions", "flushes"):
            del raw["fragment"]["shade"][part]["fragments"]

    _table(tmp_path, edit)
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({"scene": "ring", "arch": {"programs": "p.yaml"}}))
    assert main(["run", str(cfg), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "p.yaml: fragment.shade: does not price the work item 'fragments'" in err[0]


def test_a_weight_of_zero_prices_an_item(tmp_path):
    path = _table(tmp_path, lambda r: r["fragment"]["light"]["flushes"].update(shadow_hits=0))
    assert load_programs(path).jobs[("fragment", "light")].flushes["shadow_hits"] == 0.0


# -- Functional.of: what the render produced, typed ----------------------------------------

def test_of_a_render_is_typed_and_keeps_every_count(res, fn):
    assert fn.passes == tuple(res.plan.run_names)
    for p in RAY_PASSES:
        assert type(fn.work[p]) is RayPassWork and fn.ray_work(p) is fn.work[p]
    assert type(fn.work[GATHER_PASS]) is GatherWork and fn.gather_work is fn.work[GATHER_PASS]
    assert type(fn.photon_work) is PhotonWork and type(fn.geometry.levels) is BuildLevelWork
    for p in fn.passes:
        assert fn.work[p].n == fn.pixels == 120 and fn.width == 12
        for k in fn.work[p].KEYS:
            np.testing.assert_array_equal(getattr(fn.work[p], k), np.asarray(res.work[p][k]).reshape(-1))
    for k in PhotonWork.KEYS:
        np.testing.assert_array_equal(getattr(fn.photon_work, k), res.photons.work[k])
    assert fn.photon_work.n == 600 and fn.photon_work.totals()["photons_emitted"] == 600
    assert fn.geometry.n_levels == res.accel.tree.levels
    assert fn.photon_tree == TreeWork.of_maps(res.photons.photons)
    without = Functional.of({"rcast": res.work["rcast"]}, res.accel.tree, None, 12)
    assert without.passes == ("rcast",) and without.photon_work is None and without.photon_tree is None


def test_a_new_render_key_is_not_dropped_silently():
    w = RayPassWork.zeros(4).as_dict()
    with pytest.raises(ValueError, match=r"unknown.*ray_budget"):
        RayPassWork.from_mapping({**w, "ray_budget": np.ones(4, dtype=np.int64)})
    del w["fragments"]
    with pytest.raises(ValueError, match=r"missing.*fragments"):
        RayPassWork.from_mapping(w)


def test_the_work_reads_as_a_mapping(fn):
    w = fn.ray_work("rcast")
    assert list(w) == list(RayPassWork.KEYS) == list(w.keys()) and len(w) == len(RayPassWork.KEYS)
    assert w["tri_tests"] is w.tri_tests and w.get("nope") is None and "fragments" in w
    with pytest.raises(KeyError):
        w["nope"]
    assert dict(w.items()) == {k: getattr(w, k) for k in RayPassWork.KEYS}


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
    doubled = dataclasses.replace(fn, work={p: {k: v * 2 for k, v in w.items()} for p, w in fn.work.items()})
    assert type(doubled.work["pmap"]) is GatherWork
    assert doubled.ray_work("reflect").totals()["tri_tests"] == 2 * fn.ray_work("reflect").totals()["tri_tests"]
    assert doubled != fn and dataclasses.replace(fn) == fn


# -- validation ----------------------------------------------------------------------------

@pytest.mark.parametrize("bad, match", [
    ({"tri_tests": np.zeros(4)}, "int64"),  # float
    ({"tri_tests": np.zeros(4, dtype=np.int16)}, "int64"),  # the constructor does not convert
    ({"tri_tests": np.zeros((2, 2), dtype=np.int64)}, "1-D"),
    ({"tri_tests": np.zeros(5, dtype=np.int64)}, "5 pixels"),
    ({"tri_tests": np.array([0, -1, 0, 0])}, "negative"),
    ({"tri_tests": [0, 0, 0, 0]}, "numpy array"),
])
def test_work_arrays_are_validated(bad, match):
    with pytest.raises(ValueError, match=match):
        RayPassWork(**RayPassWork.zeros(4).as_dict() | bad)


def test_from_mapping_converts_integers_and_shapes_but_not_floats():
    w = {k: np.zeros((2, 2), dtype=np.int16) for k in GatherWork.KEYS}
    g = GatherWork.from_mapping(w)
    assert g.n == 4 and all(v.dtype == np.int64 and v.ndim == 1 for v in g.values())
    # int32, what a render keeps where the counts fit, is kept (not copied to int64)
    w32 = {k: np.arange(4, dtype=np.int32).reshape(2, 2) for k in GatherWork.KEYS}
    g32 = GatherWork.from_mapping(w32)
    assert all(v.dtype == np.int32 and v.ndim == 1 for v in g32.values())
    assert g32 == GatherWork.from_mapping({k: v.astype(np.int64) for k, v in w32.items()})
    with pytest.raises(ValueError, match="integers"):
        GatherWork.from_mapping({**w, "gathers": np.zeros(4)})
    assert GatherWork.zeros(3) == GatherWork.from_mapping({k: [0, 0, 0] for k in GatherWork.KEYS})


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
    fn = Functional(("rcast",), {"rcast": {k: np.ones(n, dtype=np.int64) for k in RayPassWork.KEYS}},
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
    fn.save(tmp_path / "ok.npz")
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


def test_a_scale_too_large_for_a_float_is_a_one_line_error(tmp_path):
    """An integer beyond float64 (``scale: 1e400`` written out) is no number of cycles: a
    one-line InputError naming the key, not an overflow inside the check."""
    path = _table(tmp_path, lambda r: r["vertex"].update(scale=10**400))
    with pytest.raises(InputError) as err:
        load_programs(path)
    assert str(err.value).startswith(f"{path}: vertex.scale: ") and "must be a number >= 0" in str(err.value)
