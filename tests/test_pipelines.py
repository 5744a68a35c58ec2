"""N duplicated pipelines (thesis §V.D) and the dynamic scheduler."""

from __future__ import annotations

import dataclasses
import heapq
import itertools
import random
from fractions import Fraction

import numpy as np
import pytest
import simpy

from tlm.arch.costs import load_programs
from tlm.arch.frame_program import (
    FanOut,
    FrameProgram,
    JobSpec,
    PhaseSpec,
    Stage,
    Tile,
    frame_program,
    grid_shape,
    image_tiles,
)
from tlm.arch.model import PMS, simulate, simulate_program, steady_throughput
from tlm.config import config_from_dict
from tlm.experiments.frames import render_key
from tlm.kernels.work import MISS_KEYS
from tlm.render.frame import cast
from tlm.render.passes import PASS_FUNCTIONS
from tlm.render.pmap import pmap_pass

EQ_TERMS = ("T_norm", "T_ms", "T_ps", "T_ds", "idle")


def _with(a, **kw):
    return dataclasses.replace(a, **kw)


@pytest.fixture(scope="module")
def ring(tmp_path_factory):
    """The ring as the model of commit 2674e34 rendered it: flat shading (crease_angle 0),
    one eye ray per pixel (its mirror has no Fresnel term either way)."""
    from tlm.experiments.run import render

    scene = tmp_path_factory.mktemp("ring") / "ring_flat.yaml"
    scene.write_text("extends: ring\ncrease_angle: 0\n")
    cfg = config_from_dict({"scene": str(scene), "mode": "refract", "resolution": [32, 24], "render": {"spp": 1},
                            "arch": {"frames": 2, "packet_size": 16, "trace": False}}, "test")
    res = render(cfg)
    return cfg, res.functional(), load_programs(), res


@pytest.fixture(scope="module")
def cornell_pmap():
    from tlm.experiments.run import render

    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "resolution": [24, 24], "photons": {"count": 3000},
                            "arch": {"frames": 2, "packet_size": 32, "trace": False}}, "test")
    return cfg, render(cfg).functional(), load_programs()


# -- tiling ---------------------------------------------------------------------------------------

@pytest.mark.parametrize(("n", "w", "h", "want"), [
    (1, 320, 240, (1, 1)), (4, 320, 320, (2, 2)), (2, 320, 240, (1, 2)), (8, 320, 320, (2, 4)),
    (16, 320, 240, (4, 4)), (64, 320, 320, (8, 8)), (7, 320, 240, (1, 7)), (3, 10, 300, (3, 1))])
def test_grid_shape_is_the_most_nearly_square(n, w, h, want):
    assert grid_shape(n, w, h) == want


@pytest.mark.parametrize(("n", "w", "h"), [(1, 5, 3), (4, 32, 24), (7, 32, 24), (64, 32, 24), (64, 4, 3),
                                           (12, 1, 1)])
def test_tiles_cover_every_pixel_once(n, w, h):
    tiles, info = image_tiles(w, h, n)
    assert len(tiles) == n == info["rows"] * info["cols"]
    every = np.concatenate(tiles)
    assert np.array_equal(np.sort(every), np.arange(w * h))
    for t, (x0, y0, x1, y1) in zip(tiles, info["tiles"]):
        assert t.size == (x1 - x0) * (y1 - y0)
        if t.size:
            assert np.all(np.diff(t) > 0)  # row-major inside the tile
            assert set(t % w) == set(range(x0, x1)) and set(t // w) == set(range(y0, y1))


def test_quadrants_for_four_pipelines():
    tiles, info = image_tiles(4, 4, 4)
    assert [sorted(t.tolist()) for t in tiles] == [[0, 1, 4, 5], [2, 3, 6, 7], [8, 9, 12, 13], [10, 11, 14, 15]]
    assert info["tiles"] == [[0, 0, 2, 2], [2, 0, 4, 2], [0, 2, 2, 4], [2, 2, 4, 4]]


# -- the program: every work item in exactly one tile ------------------------------------------------

def _totals(prog):
    items, norm, jobs = dict.fromkeys(PMS, 0), dict.fromkeys(PMS, 0), dict.fromkeys(PMS, 0)
    for ph in prog.phases:
        for js in ph.jobs:
            items[js.pm] += int(js.items.sum())
            norm[js.pm] += int(js.norm.sum())
            jobs[js.pm] += 1
    return items, norm, jobs


@pytest.mark.slow
@pytest.mark.parametrize("scheduler", ["static", "dynamic"])
@pytest.mark.parametrize("n", [2, 3, 4, 16, 64])
def test_work_is_conserved_over_tiles(ring, cornell_pmap, n, scheduler):
    for cfg, fn, progs, *_ in (ring, cornell_pmap):
        one = frame_program(fn, progs, cfg.arch)
        many = frame_program(fn, progs, _with(cfg.arch, pipelines=n, scheduler=scheduler))
        i1, n1, j1 = _totals(one)
        iN, nN, jN = _totals(many)
        assert iN == i1
        drain = progs.intersection["stages"] * progs.intersection["triangle_cycles"]
        for pm in ("vertex", "traversal", "fragment"):  # rounding on running totals: <= 1 cycle per job
            assert abs(nN[pm] - n1[pm]) <= jN[pm], pm
        # the Intersection PM drains its pipeline at the end of every job
        assert nN["intersection"] - n1["intersection"] == drain * (jN["intersection"] - j1["intersection"])
        tiled = [st for st in many.stages if not st.shared]
        want = n if scheduler == "static" else n * cfg.arch.tiles_per_pipeline
        assert all(len(st.tiles) == want for st in tiled)


def test_one_pipeline_is_the_single_pipeline_model(ring):
    """N = 1 gives the cycles the single-pipeline model gave before pipelines existed.

    The numbers were measured with the model of commit 2674e34 (one pipeline, no
    tiles) on this fixture's frame with packets of 64. Its throughput was the mean gap
    between the stream's first and last completions (587836), which the frame times
    still give; TThru is now measured over the steady-state window. The programs' scales
    are those of that commit's calibration (the table was refitted since).
    """
    cfg, fn, progs, _ = ring
    progs = progs.with_scales({"vertex": 7.44214, "traversal": 0.570522, "fragment": 2.57008},
                              {"vertex": 0.0, "traversal": 0.0, "fragment": 0.0})
    t = simulate(fn, progs, _with(cfg.arch, packet_size=64, pipelines=1, scheduler="static"))
    assert {k: v for k, v in t.cycles.items() if k != "throughput"} == {
        "vertex": 387755, "traversal": 196092, "intersection": 560966, "fragment": 52415, "latency": 1346159}
    done = [f["done"] for f in t.frames]
    assert round(Fraction(done[-1] - done[0], len(done) - 1)) == 587836
    assert t.cycles["throughput"] == steady_throughput(done, cfg.arch.images_in_flight)[0]
    assert t.crossbar["copies"] == 8
    assert t.pipelines == [{k: t.cycles[k] for k in PMS}]


# -- the simulation -------------------------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("scheduler", ["static", "dynamic"])
@pytest.mark.parametrize("n", [2, 4, 64])
def test_pipelines_finish_and_account_every_cycle(ring, cornell_pmap, n, scheduler):
    for cfg, fn, progs, *_ in (ring, cornell_pmap):
        t = simulate(fn, progs, _with(cfg.arch, pipelines=n, scheduler=scheduler))
        assert len(t.pipelines) == n
        scopes = set(t.units)
        assert "pipe0.vertex" in scopes and "pipe1.vertex" not in scopes  # one Vertex PM (§V.D)
        assert {f"pipe{p}.{pm}" for p in range(n) for pm in ("traversal", "intersection", "fragment")} <= scopes
        assert {f"mem{i}" for i in range(4 * n)} | {"compose", "xbar"} <= scopes
        for u in t.units.values():
            assert sum(u[k] for k in EQ_TERMS) == u["elapsed"]
        assert all(t.checks.values())
        # every pixel passes the crossbar to the top-level unit once per frame, a copy per tile
        tiles = t.program.stages[-1].tiles
        assert sum(tl.pixels for tl in tiles) == fn.pixels
        per_frame = sum(-(-tl.pixels // cfg.arch.copy_words_per_cycle) for tl in tiles)
        assert t.units["compose"]["T_norm"] == per_frame * len(t.frames)  # (a dynamic stream runs on until it settles)
        for k in PMS:
            assert t.cycles[k] == max(p[k] for p in t.pipelines)


@pytest.mark.slow
def test_more_pipelines_are_faster(ring):
    """This small frame is Vertex-bound (its throughput is the one Vertex PM's); the per-pipeline
    PMs shrink with N, and the latency down to 2 TVert, the steady state's once the Vertex PM is the
    limit (2 and 4 pipelines: 785,898 cycles each)."""
    cfg, fn, progs, _ = ring
    t = {n: simulate(fn, progs, _with(cfg.arch, pipelines=n, scheduler="dynamic")) for n in (1, 2, 4)}
    for key in ("traversal", "intersection", "fragment"):
        assert t[4].cycles[key] < t[2].cycles[key] < t[1].cycles[key], key
    assert t[4].cycles["latency"] == t[2].cycles["latency"] == 2 * t[4].cycles["vertex"] < t[1].cycles["latency"]
    assert t[4].cycles["vertex"] == t[1].cycles["vertex"]
    assert t[4].cycles["throughput"] >= t[4].cycles["vertex"]


def test_dynamic_scheduler_balances_an_unbalanced_image(ring):
    """All the work in one quadrant: static tiling leaves three pipelines idle, the queue does not."""
    cfg, fn, progs, _ = ring
    keep = np.zeros(fn.pixels, dtype=bool)
    rows, cols = np.divmod(np.arange(fn.pixels), fn.width)
    keep[(rows < fn.height // 2) & (cols < fn.width // 2)] = True
    work = {p: {k: np.where(keep, v, 0) for k, v in w.items()} for p, w in fn.work.items()}
    lopsided = dataclasses.replace(fn, work=work)
    a = _with(cfg.arch, pipelines=4, frames=5)
    static = simulate(lopsided, progs, _with(a, scheduler="static"))
    dynamic = simulate(lopsided, progs, _with(a, scheduler="dynamic", tiles_per_pipeline=4))
    # the slowest pipeline's Intersection PM (the frame waits for it) and the latency
    assert dynamic.cycles["intersection"] < 0.4 * static.cycles["intersection"]
    # (in the steady state both are Vertex-bound: the latency is 2 TVert under either scheduler)
    assert dynamic.cycles["latency"] == static.cycles["latency"] == 2 * dynamic.cycles["vertex"]
    idle_static = [static.units[f"pipe{p}.intersection"]["idle"] / static.units[f"pipe{p}.intersection"]["elapsed"]
                   for p in range(4)]
    assert max(idle_static) > 0.9  # three quadrants without work
    busy_dyn = [dynamic.units[f"pipe{p}.intersection"]["busy"] for p in range(4)]
    assert min(busy_dyn) > 0  # every pipeline took tiles


def test_serial_fanout_copies_once_per_pipeline(ring):
    cfg, fn, progs, _ = ring
    a = _with(cfg.arch, pipelines=4, frames=1)
    b = simulate(fn, progs, _with(a, fanout="broadcast"))
    s = simulate(fn, progs, _with(a, fanout="serial"))
    # broadcast: tree and vertices once each; serial: the tree to pipelines 1..3, the vertices to 0..3
    assert s.crossbar["copies"] - b.crossbar["copies"] == (3 - 1) + (4 - 1)
    assert s.units["xbar"]["busy"] > b.units["xbar"]["busy"]
    # (the latency is not ordered: the serial copies stagger the pipelines, and staggered
    # tiles queue less for the compose copies; on this frame serial is 1 cycle faster)
    assert s.units["xbar"]["busy"] - b.units["xbar"]["busy"] >= s.cycles["latency"] - b.cycles["latency"]


def _module_overlaps(t):
    """Pairs of slices on one memory module's row that overlap in time (two clients at once)."""
    rows = {tid: scope for scope, tid in t.trace.rows.items()}
    by_row = {}
    for e in t.trace.events:
        if rows[e["tid"]].startswith("mem") and e["name"] != "idle":
            by_row.setdefault(e["tid"], []).append((e["ts"], e["ts"] + e["dur"], e["name"]))
    bad = []
    for tid, spans in by_row.items():
        spans.sort()
        bad += [(rows[tid], a, b) for a, b in itertools.pairwise(spans) if b[0] < a[1]]
    return bad


@pytest.mark.slow
@pytest.mark.parametrize("fanout", ["broadcast", "serial"])
@pytest.mark.parametrize("scheduler", ["static", "dynamic"])
def test_a_module_never_has_two_clients(cornell_pmap, fanout, scheduler):
    """Copies (fan-out, fan-in, per phase, compose) and PMs' page misses never overlap on a module."""
    cfg, fn, progs = cornell_pmap
    t = simulate(fn, progs, _with(cfg.arch, pipelines=3, frames=3, trace=True, fanout=fanout, scheduler=scheduler))
    assert _module_overlaps(t) == []


@pytest.fixture(scope="module")
def cornell_tiles():
    """A non-square Cornell frame with every pass: Reflect and Refract (secondary rays) and the photon map."""
    from tlm.experiments.run import render

    cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "resolution": [32, 24], "photons": {"count": 3000},
                            "arch": {"frames": 2, "packet_size": 16, "trace": False}}, "test")
    res = render(cfg)
    fn = res.functional()
    # with final gathering (the default): its rays are a ray pass of their own, tiled as the others
    assert res.plan.run_names == ["rcast", "reflect", "refract", "pmap", "fgather"]
    assert fn.work["fgather"]["secondary_rays"].sum() > 0
    assert all(fn.work[p]["secondary_rays"].sum() > 0 for p in ("reflect", "refract"))
    assert fn.work["pmap"]["gathers"].sum() > 0
    return res, fn, load_programs()


def _render_alone(res, pixels):
    """Pass -> (radiance, work) of ``pixels`` rendered on their own, as one pipeline renders its tile
    (with the frame's photon map: the shared stage traces it once for every pipeline)."""
    g = cast(res.frame, pixels)
    return {p: pmap_pass(res.frame, g, res.photons.photons) if p == "pmap" else PASS_FUNCTIONS[p](res.frame, g)
            for p in res.plan.run_names}


def _charged(tile):
    """What the timing model charges a tile, per (phase, PM): work items and FIFO entries."""
    return {(ph.name, j.pm): (int(j.items.sum()), None if j.entries is None else int(j.entries.sum()))
            for ph in tile.phases for j in ph.jobs}


def _charged_by_the_render(alone):
    """The same from the work of the tile's own render (the phases ``frame_program`` builds)."""
    out = {}
    for p, (_, w) in alone.items():
        if p == "pmap":
            if w["gathers"].any():
                out["pmap.gather", "fragment"] = (int((w["gathers"] > 0).sum()), None)
            continue
        for trace, frag, r, tris in (("rays", "shade", w["primary_rays"] + w["secondary_rays"], w["tri_tests"]),
                                     ("shadow", "light", w["shadow_rays"], w["shadow_tri_tests"])):
            if r.any():
                n, entries = int((r > 0).sum()), int(tris[r > 0].sum())
                out[f"{p}.{trace}", "traversal"] = (n, entries)
                out[f"{p}.{trace}", "intersection"] = (int(r.sum()), entries)
                out[f"{p}.{frag}", "fragment"] = (n, None)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("scheduler", ["static", "dynamic"])
@pytest.mark.parametrize("n", [1, 2, 3, 4, 7, 16, 64])
def test_the_programs_tiles_rendered_alone_compose_the_image(cornell_tiles, n, scheduler):
    """The image does not depend on N or the scheduler because each tile the timing model uses,
    rendered on its own, gives its pixels' radiance of the whole-image render, and the tiles
    partition the image. (``render`` never reads ``arch``: comparing whole renders across N
    could not fail.) Each tile's pixels, from the program's bounds, are also those whose work
    the program charges to it."""
    res, fn, progs = cornell_tiles
    w, h = fn.width, fn.height
    prog = frame_program(fn, progs, _with(res.cfg.arch, pipelines=n, scheduler=scheduler))
    want = n if scheduler == "static" else n * res.cfg.arch.tiles_per_pipeline
    stage, bounds = prog.stages[-1], prog.tiling["tiles"]
    assert stage.name == "pixels" and len(stage.tiles) == len(bounds) == want
    photon_tiles = next(st for st in prog.stages if st.name == "photons").tiles
    assert len(photon_tiles) == want  # the photon chunks partition the traced photons
    assert sum(_charged(t).get(("photons.trace", "traversal"), (0,))[0]
               for t in photon_tiles) == fn.photon_work["photons_emitted"].shape[0]

    passes = res.plan.run_names
    count = np.zeros(w * h, dtype=np.int64)
    radiance = {p: np.full((w * h, 3), np.nan) for p in passes}
    work = {p: {k: np.full(w * h, -1, dtype=np.int64) for k in res.work[p] if k not in MISS_KEYS} for p in passes}
    for tile, (x0, y0, x1, y1) in zip(stage.tiles, bounds):
        idx = (np.arange(y0, y1)[:, None] * w + np.arange(x0, x1)[None, :]).reshape(-1)
        np.add.at(count, idx, 1)
        alone = _render_alone(res, idx)
        assert _charged(tile) == _charged_by_the_render(alone), tile.name
        assert tile.pixels == (idx.size if n > 1 else 0)
        for p, (rad, wk) in alone.items():
            radiance[p][idx] = rad
            for k in work[p]:
                work[p][k][idx] = wk[k]
    assert np.array_equal(count, np.ones(w * h, dtype=np.int64))  # every pixel in exactly one tile
    composite = np.zeros((h, w, 3))
    for p in passes:
        for k, v in work[p].items():
            assert np.array_equal(v.reshape(h, w), res.work[p][k]), (p, k)
        if p not in res.radiance:  # (final gathering's rays: work only, their light is the pmap frame's)
            assert not radiance[p].any()
            continue
        assert np.array_equal(radiance[p].reshape(h, w, 3), res.radiance[p]), p
        composite = composite + radiance[p].reshape(h, w, 3)
    assert np.array_equal(composite, res.composite)


def _assert_partition(tiles, bounds, w, h):
    """Every pixel of the w x h image in exactly one tile (by its pixels, and by its bounds)."""
    if tiles is not None:
        every = np.concatenate(tiles)
        assert every.size == w * h and every.min() >= 0 and every.max() < w * h
        assert np.array_equal(np.bincount(every, minlength=w * h), np.ones(w * h, dtype=np.int64))
    painted = np.zeros((h, w), dtype=np.int64)
    for x0, y0, x1, y1 in bounds:
        painted[y0:y1, x0:x1] += 1
    assert (painted == 1).all()


@pytest.mark.slow
@pytest.mark.parametrize(("w", "h"), [(1, 1), (3, 5), (7, 1), (1, 9), (15, 9), (31, 23), (33, 65)])
def test_static_and_dynamic_tilings_partition_odd_images(w, h):
    """Static: N tiles; dynamic: N x tiles_per_pipeline; for every N in 1..64 (more tiles than
    pixels leaves tiles empty, never a pixel twice or out)."""
    for n in range(1, 65):
        for tiles_per_pipeline in (None, 1, 3, 4):
            count = n if tiles_per_pipeline is None else n * tiles_per_pipeline
            rows, cols = grid_shape(count, w, h)
            assert rows * cols == count
            tiles, info = image_tiles(w, h, count)
            assert len(tiles) == len(info["tiles"]) == count and (info["rows"], info["cols"]) == (rows, cols)
            _assert_partition(tiles, info["tiles"], w, h)


@pytest.fixture(scope="module")
def odd_frame():
    from tlm.experiments.run import render

    cfg = config_from_dict({"scene": "cornell", "mode": "rcast", "resolution": [15, 9], "render": {"light_samples": 1},
                            "arch": {"frames": 2, "packet_size": 8, "trace": False}}, "test")
    return cfg, render(cfg).functional(), load_programs()


@pytest.mark.slow
@pytest.mark.parametrize("scheduler", ["static", "dynamic"])
@pytest.mark.parametrize("n", [1, 2, 3, 5, 7, 16, 64])
def test_the_frame_programs_tiles_partition_the_image(odd_frame, n, scheduler):
    cfg, fn, progs = odd_frame
    assert (fn.width, fn.height) == (15, 9)
    a = _with(cfg.arch, pipelines=n, scheduler=scheduler, tiles_per_pipeline=3)
    prog = frame_program(fn, progs, a)
    want = n if scheduler == "static" else 3 * n
    bounds = prog.tiling["tiles"]
    assert len(bounds) == want
    _assert_partition(None, bounds, fn.width, fn.height)
    pixels = prog.stages[-1]
    assert len(pixels.tiles) == want
    if n > 1:  # each tile composes its own pixels into the image
        assert [t.pixels for t in pixels.tiles] == [(x1 - x0) * (y1 - y0) for x0, y0, x1, y1 in bounds]


def test_the_functional_key_leaves_the_architecture_out():
    """Points that differ only in ``arch`` share one render; the rest of the config does not."""
    base = {"scene": "cornell", "mode": "rcast", "resolution": [15, 9], "render": {"light_samples": 1}}

    def key(**changes):
        raw = {**base, **{k: v for k, v in changes.items() if k != "arch"}, "arch": changes.get("arch", {})}
        return render_key(config_from_dict(raw, "test"))

    one = key()
    for arch in ({"pipelines": 8}, {"scheduler": "dynamic", "tiles_per_pipeline": 2}, {"packet_size": 1},
                 {"pipelines": 64, "scheduler": "dynamic", "packet_size": 4096, "fifo_depth": 1, "frames": 3}):
        assert key(arch=arch) == one, arch
    assert key(resolution=[9, 15]) != one
    assert key(resolution=[16, 9]) != one
    assert key(mode="reflect") != one


# -- random small programs: never a deadlock, never a result that depends on event order ------------

class _Reversed(simpy.Environment):
    """Runs events of one cycle and one priority in the reverse of the order they were scheduled."""

    def schedule(self, event, priority=1, delay=0):
        heapq.heappush(self._queue, (self._now + delay, priority, -next(self._eid), event))


def _job(pm, role, n, rng, entries=None):
    norm = np.array([rng.randint(1, 6) * 4 for _ in range(n)], dtype=np.int64)
    misses = np.array([rng.randint(0, 2) for _ in range(n)], dtype=np.int64)
    return JobSpec(pm, "test", role, norm, misses, np.zeros(n, np.int64), np.ones(n, np.int64), entries)


def _tile(name, rng, pixels):
    phases = []
    for j in range(rng.randint(0, 3)):
        n = rng.randint(1, 4)
        entries = np.array([rng.randint(0, 6) for _ in range(n)], dtype=np.int64)
        phases.append(PhaseSpec(f"p{j}.ti", (_job("traversal", 0, n, rng, entries),
                                            _job("intersection", 1, n, rng, entries)), rng.choice([0, 0, 6])))
        if rng.random() < 0.7:
            phases.append(PhaseSpec(f"p{j}.f", (_job("fragment", 1, rng.randint(1, 3), rng),), 0))
    return Tile(name, tuple(phases), pixels, rng.choice([0, 4]))


def _random_program(rng, n_pipes, scheduler, tiles):
    def shared(name):
        return Stage(name, True, (Tile(name, (PhaseSpec(name, (_job("vertex", 0, rng.randint(1, 3), rng),), 0),)),))

    out = (FanOut("tree", 8, 0, 0), FanOut("vertices", 6, 0, 1))
    stages = [shared("geometry"),
              Stage("photons", False, tuple(_tile(f"c{i}", rng, 0) for i in range(tiles)), out),
              shared("photon tree"),
              Stage("pixels", False, tuple(_tile(f"t{i}", rng, rng.randint(0, 5) if n_pipes > 1 else 0)
                                           for i in range(tiles)), (FanOut("photon tree", 4, 0, 1),))]
    return FrameProgram(tuple(stages), {}, n_pipes, scheduler)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(300))
def test_random_programs_finish_without_a_module_shared(seed):
    """Random small programs (1-3 pipelines, both schedulers and fan-outs, FIFOs of 1-4, 1 or 2
    images) never deadlock, account every cycle and never give a module two clients."""
    rng = random.Random(seed)
    n_pipes, scheduler = rng.choice([1, 2, 3]), rng.choice(["static", "dynamic"])
    tiles = n_pipes if scheduler == "static" else n_pipes * rng.choice([1, 2])
    a = config_from_dict({"arch": {
        "pipelines": n_pipes, "scheduler": scheduler, "fanout": rng.choice(["broadcast", "serial"]),
        "images_in_flight": rng.choice([1, 2]), "frames": rng.choice([2, 3, 4]), "fifo_depth": rng.choice([1, 2, 4]),
        "swap_cycles": rng.choice([0, 2]), "context_switch_cycles": rng.choice([0, 4]),
        "page_miss_cycles": rng.choice([0, 4]), "trace": True}}, "test").arch
    t = simulate_program(_random_program(rng, n_pipes, scheduler, tiles), a)
    assert all(t.checks.values())
    assert _module_overlaps(t) == []
    for u in t.units.values():
        assert sum(u[k] for k in EQ_TERMS) == u["elapsed"]


@pytest.mark.slow
@pytest.mark.parametrize(("n", "scheduler", "fanout"), [(2, "dynamic", "serial"), (3, "dynamic", "broadcast"),
                                                        (4, "static", "serial"), (1, "static", "broadcast")])
def test_real_frames_do_not_depend_on_the_order_of_same_cycle_events(cornell_pmap, n, scheduler, fanout, monkeypatch):
    """The crossbar's arbitration and the tile queue decide ties by frame and pipeline, once the
    cycle's other events have run; the same frame simulated with same-cycle events in reverse
    order gives the same cycles, unit by unit."""
    cfg, fn, progs = cornell_pmap
    a = _with(cfg.arch, pipelines=n, scheduler=scheduler, fanout=fanout, packet_size=8, frames=3)
    t = simulate(fn, progs, a)
    monkeypatch.setattr(simpy, "Environment", _Reversed)
    r = simulate(fn, progs, a)
    assert (t.cycles, t.frames, t.units) == (r.cycles, r.frames, r.units)


@pytest.mark.parametrize("env", [simpy.Environment, _Reversed])
def test_the_crossbar_serves_same_cycle_copies_by_frame_and_pipeline(env, monkeypatch):
    """Both pipelines need a copy the cycle the shared stage ends: pipeline 0's goes first,
    whatever the order in which SimPy runs the two requests."""
    monkeypatch.setattr(simpy, "Environment", env)

    def tile(name):
        return Tile(name, (PhaseSpec("f", (_job("fragment", 1, 1, random.Random(1)),), 6),))

    geometry = PhaseSpec("g", (_job("vertex", 0, 1, random.Random(2)),), 0)
    prog = FrameProgram((Stage("g", True, (Tile("g", (geometry,)),)), Stage("px", False, (tile("t0"), tile("t1")))),
                        {}, 2, "static")
    t = simulate_program(prog, config_from_dict({"arch": {"pipelines": 2, "frames": 1, "images_in_flight": 1,
                                                          "page_miss_cycles": 0}}, "test").arch)
    starts = [(what, cycle) for what, cycle in t.model.xbar.unit.log if what.endswith("start")]
    assert [w.split(":")[0] for w, _ in starts] == ["copy mem0->mem1", "copy mem2->mem3"]
    assert starts[1][1] == starts[0][1] + 3  # 6 words at 2 per cycle, one copy at a time


@pytest.mark.slow
@pytest.mark.parametrize(("pipelines", "scheduler"), [(1, "static"), (4, "static"), (4, "dynamic")])
def test_the_steady_state_throughput_does_not_depend_on_the_stream_length(cornell_pmap, pipelines, scheduler):
    """From the shortest stream with a steady window (5 frames) on, a longer stream gives the
    same TThru: the completions are periodic once the warm-up is over, and the window ends
    before the drain. The mean gap over the whole stream, the estimator before, moves."""
    cfg, fn, progs = cornell_pmap
    runs = {f: simulate(fn, progs, _with(cfg.arch, frames=f, pipelines=pipelines, scheduler=scheduler))
            for f in (4, 5, 6, 8, 12)}
    # (a dynamic stream runs on past arch.frames until its completions repeat: steady at 4 frames too)
    assert runs[4].throughput_estimate["steady"] is (scheduler == "dynamic")
    assert all(runs[f].throughput_estimate["steady"] for f in (5, 6, 8, 12))
    thr = [runs[f].cycles["throughput"] for f in (5, 6, 8, 12)]
    assert max(thr) - min(thr) <= 1  # one period's cycles split between its frames: rounding to whole cycles
    lat = [runs[f].cycles["latency"] for f in (5, 6, 8, 12)]
    assert max(lat) - min(lat) <= 1

    def gap_mean(t):
        done = sorted(f["done"] for f in t.frames)
        return (done[-1] - done[0]) / (len(done) - 1)

    if scheduler == "static":  # (a dynamic stream runs on to the same frame from each of these lengths: one stream)
        assert len({round(gap_mean(runs[f])) for f in (5, 6, 8, 12)}) > 1
