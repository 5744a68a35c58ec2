"""``render.threads``: the kernels on several threads give the bits of one thread.

Renders (radiance, work counts, photon maps, simulated cycles) and kernel calls (hits,
counts, the nodes and leaves touched, gathers) are compared byte for byte at 1, 2 and 3
threads. The kernels' smallest chunks are lowered here so that the small test inputs
are really cut into many chunks (cuts in odd places, uneven chunks), as a full frame is.
"""

from __future__ import annotations

import itertools
import time
from pathlib import Path

import numpy as np
import pytest

from tlm.arch.costs import load_programs
from tlm.arch.model import simulate
from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.experiments.run import render
from tlm.kernels import bsp, emission, estimate, photons, threads, traverse
from tlm.kernels.bsp import build_point_tree
from tlm.kernels.memory import Accesses, Streams
from tlm.kernels.recording import Deferred
from tlm.kernels.traverse import any_hit, build_accel, closest_hit
from tlm.render import batches


@pytest.fixture
def small_chunks(monkeypatch):
    """Chunks of a few rays or queries, gather blocks of a few hundred queries, photon
    chunks of a few hundred photons, and (on several threads) batches of a few dozen
    pixels, cut at other pixels for every thread count, that run at once."""
    monkeypatch.setattr(traverse, "JIT_MIN_CHUNK", 37)
    monkeypatch.setattr(estimate, "GATHER_MIN_CHUNK", 23)
    monkeypatch.setattr(estimate, "QUERY_BLOCK", 301)
    monkeypatch.setattr(photons, "PHOTON_MIN_CHUNK", 700)
    monkeypatch.setattr(emission, "CONE_CHUNK", 3000)
    monkeypatch.setattr(batches, "MIN_BATCH_RAYS", 16)
    monkeypatch.setattr(bsp, "GROUP_MIN_ELEMENTS", 40)


def _cfg(scene: str, mode: str, **over):
    raw = {"scene": scene, "mode": mode, "resolution": [24, 20], "photons": {"count": 5000},
           "render": {"spp": 1, "batch_rays": 200}, "arch": {"frames": 2, "trace": False}}
    for k, v in over.items():
        raw.setdefault(k, {}).update(v)
    return raw


def _render(raw: dict, n: int):
    raw = {**raw, "render": {**raw["render"], "threads": n}}
    res = render(config_from_dict(raw))
    tm = simulate(res.functional(), load_programs(), res.cfg.arch)
    return res, tm


def _same_render(a, b) -> None:
    (ra, ta), (rb, tb) = a, b
    assert ra.radiance.keys() == rb.radiance.keys()
    for name in ra.radiance:
        assert ra.radiance[name].tobytes() == rb.radiance[name].tobytes(), name
    assert ra.work.keys() == rb.work.keys()
    for name in ra.work:
        for k in ra.work[name]:
            assert np.array_equal(ra.work[name][k], rb.work[name][k]), (name, k)
    assert ra.gather_maps == rb.gather_maps
    if ra.photons is not None:
        maps_a, maps_b = ra.photons.photons, rb.photons.photons
        assert (maps_a.global_map is None) == (maps_b.global_map is None)
        for ma, mb in zip((*maps_a.maps, maps_a.global_map), (*maps_b.maps, maps_b.global_map), strict=True):
            if ma is None:
                continue
            for k in ("position", "normal", "incoming", "power", "caustic"):
                assert getattr(ma, k).tobytes() == getattr(mb, k).tobytes(), k
            assert ma.tree.split.tobytes() == mb.tree.split.tobytes()
        for k, v in ra.photons.work.items():
            assert np.array_equal(v, rb.photons.work[k]), k
    assert ta.cycles == tb.cycles
    assert [f["done"] for f in ta.frames] == [f["done"] for f in tb.frames]


@pytest.mark.parametrize("scene, mode, over", [
    pytest.param("cornell", "pmap", {"estimate": {"final_gather": 4}},  # mirror, glass sphere, final gathering
                 marks=pytest.mark.slow),
    ("cornell-water", "refract", {}),  # a glass (water) surface over most of the image
])
@pytest.mark.parametrize("workers", ["processes", "threads"])
def test_renders_are_bit_identical_for_any_thread_count(small_chunks, monkeypatch, workers, scene, mode, over):
    if workers == "processes":  # (forked workers on 2 and 3 threads too, as past DEFAULT_MAX_THREADS)
        monkeypatch.setenv("TLM_FORK_WORKERS", "1")
    monkeypatch.setattr(batches, "BATCH_WORKERS", workers)  # where whole batches run at once
    raw = _cfg(scene, mode, **over)
    one = _render(raw, 1)
    if mode == "pmap":
        assert one[0].plan.runs("fgather") and one[0].work["fgather"]["secondary_rays"].sum() > 0
    assert one[0].work["rcast"]["primary_rays"].sum() == 24 * 20
    for n in (2, 3):
        _same_render(one, _render(raw, n))


def _rays(rng, r: int):
    o = rng.random((r, 3)) * 1.4 - 0.2
    d = rng.normal(size=(r, 3))
    d[::17, 0] = 0.0  # axis-parallel rays too
    return o, d


def _same_traversal(a, b) -> None:
    for f in ("node_visits", "leaves_crossed", "leaf_visits", "tri_tests"):
        assert np.array_equal(getattr(a.counts, f), getattr(b.counts, f)), f
    for f in ("node_ptr", "node_ids", "leaf_ptr", "leaf_ids"):
        x, y = getattr(a.touched, f), getattr(b.touched, f)
        assert x.dtype == y.dtype and np.array_equal(x, y), f


def test_kernels_are_bit_identical_for_any_thread_count(small_chunks):
    rng = np.random.default_rng(5)
    accel = build_accel(rng.random((800, 3, 3)))
    o, d = _rays(rng, 5000)
    ignore = rng.integers(-1, 800, 5000)
    eye = np.broadcast_to(np.array([0.5, 0.5, -1.0]), (3000, 3))
    eye_d = rng.normal(size=(3000, 3)) * [0.3, 0.3, 0.0] + [0.0, 0.0, 1.0]
    out = {}
    for n in (1, 3):
        with threads.using(n):
            out[n] = (closest_hit(accel, o, d, tmin=1e-6, ignore=ignore, record=True),
                      any_hit(accel, o, d, tmax=0.4, record=True),
                      closest_hit(accel, eye, eye_d, record=True, shared_origin=True))
    for a, b in zip(out[1], out[3], strict=True):
        _same_traversal(a, b)
    for a, b in ((out[1][0], out[3][0]), (out[1][2], out[3][2])):
        assert a.t.tobytes() == b.t.tobytes() and a.u.tobytes() == b.u.tobytes() and a.v.tobytes() == b.v.tobytes()
        assert np.array_equal(a.triangle, b.triangle)
    assert np.array_equal(out[1][1].occluded, out[3][1].occluded)
    assert out[1][0].counts.leaf_visits.sum() > 0 and out[1][1].occluded.any() and (out[1][2].triangle >= 0).any()

    # the m-voxel and disk gathers: densities, counts and the leaf reads' misses (cache pairs carried)
    pos = rng.random((20000, 3))
    power = rng.random((20000, 3)) * 1e-3
    inc = rng.normal(size=(20000, 3))
    tree = build_point_tree(pos, levels=9)
    pts = rng.random((2000, 3))
    nrm = rng.normal(size=(2000, 3))
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    got = {}
    for n in (1, 3):
        with threads.using(n):
            s = Streams(64, 4)
            got[n] = (estimate.mvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.05, streams=s),
                      estimate.disk_estimate(pos, power, inc, tree, pts, nrm, 0.08, streams=s))
    for a, b in zip(got[1], got[3], strict=True):
        assert a.density.tobytes() == b.density.tobytes()
        for k in ("node_visits", "leaves_visited", "photons_tested", "photons_accepted", "gather_misses"):
            assert np.array_equal(getattr(a, k), getattr(b, k)), k
    assert got[1][0].photons_accepted.sum() > 0 and got[1][0].gather_misses.sum() > 0


@pytest.mark.parametrize("engine", ["numba", "numpy"])
def test_trees_are_the_same_for_any_thread_count(monkeypatch, engine):
    """A level of the BSP build cut into groups of whole nodes, one per thread (the compiled
    engine): the same tree, byte for byte, for points, triangles with the expansion pass and
    a tree cut short where the reserved memory runs out; and the levels were cut."""
    monkeypatch.setenv("TLM_KERNELS", engine)
    monkeypatch.setattr(bsp, "GROUP_MIN_ELEMENTS", 50)
    cut = []
    real = bsp._node_groups
    monkeypatch.setattr(bsp, "_node_groups", lambda starts, n: cut.append(len(real(starts, n))) or real(starts, n))
    rng = np.random.default_rng(9)
    pts = np.concatenate([rng.random((6000, 3)), np.repeat(rng.random((5, 3)), 400, axis=0)])  # coincident clumps
    tri = rng.random((3000, 1, 3)) + rng.normal(scale=0.03, size=(3000, 3, 3))
    trees = {}
    for n in (1, 2, 3):
        with threads.using(n):
            trees[n] = (bsp.build_point_tree(pts, levels=11), bsp.build_triangle_tree(tri),
                        bsp.build_triangle_tree(tri, levels=14, memory_factor=1.5))
    for n in (2, 3):
        for a, b in zip(trees[1], trees[n], strict=True):
            assert a.levels == b.levels and a.truncated == b.truncated and a.work == b.work
            for k in ("first", "last", "split", "lo", "hi", "items"):
                assert getattr(a, k).tobytes() == getattr(b, k).tobytes(), (n, k)
    assert trees[1][2].truncated
    if engine == "numba":
        assert max(cut) == 3 and 1 in cut  # levels cut for three threads (and the root's, not)
    else:
        assert cut == []  # (the numpy reference builds each level whole)


def test_spans_cover_in_order():
    assert threads.spans(10, 100, threads=4) == [(0, 10)]
    assert threads.spans(1000, 10, threads=1) == [(0, 1000)]
    s = threads.spans(1003, 10, threads=3)
    assert len(s) == 3 * threads.CHUNKS_PER_THREAD and s[0][0] == 0 and s[-1][1] == 1003
    assert all(a[1] == b[0] for a, b in itertools.pairwise(s))
    assert list(threads.ordered(lambda x: x * x, range(50), threads=3)) == [x * x for x in range(50)]


@pytest.mark.parametrize("weighed", [True, False])
def test_light_calls_run_behind_a_heavy_one(weighed):
    """With weights, the window of ``ordered`` holds calls by weight: the eight light calls
    all start while the caller waits for the heavy first one. By count (twice the two
    threads: four calls in flight), three do."""
    started, seen = [], []

    def call(i: int) -> int:
        if i == 0:  # the heavy one: waits until the light ones have started (at most 5 s; 0.5 by count)
            deadline = time.monotonic() + (5.0 if weighed else 0.5)
            while len(started) < 8 and time.monotonic() < deadline:
                time.sleep(0.005)
            seen.append(len(started))
        else:
            started.append(i)
        return i

    weights = [4, 1, 1, 1, 1, 1, 1, 1, 1] if weighed else None
    assert list(threads.ordered(call, range(9), threads=2, weights=weights)) == list(range(9))
    assert seen == [8 if weighed else 3]
    with pytest.raises(ValueError, match="weights"):
        list(threads.ordered(call, range(3), threads=2, weights=[1, 0, 1]))


def test_calls_in_flight_share_the_memory_budget():
    """A worker of ``ordered`` is told how many calls may be in flight (twice the threads),
    and a pass there takes that part of ``render.batch_rays`` as its ray budget."""
    from tlm.render.frame import ray_budget

    frame = type("F", (), {"cfg": config_from_dict({"scene": "cornell", "render": {"batch_rays": 1200}})})()
    assert threads.share() == 1 and ray_budget(frame) == 1200
    assert set(threads.ordered(lambda _: (threads.share(), ray_budget(frame)), range(9), threads=3)) == {(6, 200)}
    assert list(threads.ordered(lambda _: threads.share(), range(2), threads=1)) == [1, 1]  # (plain calls)
    assert set(threads.ordered(lambda _: threads.share(), range(2), threads=3)) == {2}  # (two calls: two shares)
    if threads.can_fork():  # (opt-in: TLM_FORK_WORKERS=1) forked workers are told the same
        assert set(threads.forked(lambda _: threads.share(), range(5), 2)) == {4}


@pytest.mark.parametrize("value, says", [(0, "must be >= 1"), (-2, "must be >= 1"), ("two", "is not"),
                                         (1.5, "is not"), (True, "is not")])
def test_bad_threads_is_an_input_error(value, says):
    with pytest.raises(InputError) as e:
        config_from_dict({"scene": "cornell", "render": {"threads": value}}, "t.yaml")
    assert "render.threads" in str(e.value) and says in str(e.value)


def test_threads_do_not_enter_the_keys():
    from tlm.config import to_dict
    from tlm.experiments.frames import functional_key
    from tlm.experiments.sweep_file import config_hash

    a = to_dict(config_from_dict({"scene": "cornell", "render": {"threads": 1}}))
    b = to_dict(config_from_dict({"scene": "cornell", "render": {"threads": 7}}))
    c = to_dict(config_from_dict({"scene": "cornell"}))
    assert len({functional_key(x, "s", "c") for x in (a, b, c)}) == 1
    assert len({config_hash(x) for x in (a, b, c)}) == 1
    assert config_hash(to_dict(config_from_dict({"scene": "cornell", "render": {"batch_rays": 7}}))) != config_hash(c)


def test_sweep_workers_share_the_cpus(monkeypatch):
    from tlm.experiments import executors
    from tlm.experiments.sweep_point import _with_threads

    monkeypatch.setattr(threads, "available", lambda: 16)
    assert executors.kernel_threads(4, None, 10) == 4
    assert executors.kernel_threads(4, "local", 2) == 8  # no more workers than points
    assert executors.kernel_threads(32, None, 40) == 1
    assert executors.kernel_threads(1, None, 10) is None  # one worker: all the CPUs
    assert executors.kernel_threads(4, "tcp://host:8786", 10) is None  # another machine's CPUs
    assert _with_threads({"render": {"threads": None}}, 4)["render"]["threads"] == 4
    assert _with_threads({"render": {"threads": 3}}, 4)["render"]["threads"] == 3  # set in the config: kept
    assert _with_threads({"render": {"threads": None}}, None)["render"]["threads"] is None


def test_deferred_packets_settled_in_order_give_the_carried_misses():
    """Packets charged on cold pairs (:class:`Deferred`) and settled in order on one carried
    :class:`Streams` give the misses (per owner, per stream) and the end states of the
    packets charged in order: random streams on shared and own pairs, pages of a few words
    (runs that continue across packets and calls, armed prefetches), empty charges."""
    rng = np.random.default_rng(1)
    for _ in range(400):
        pw, pairs, owners = int(rng.choice([4, 8, 16])), int(rng.choice([1, 2, 4])), 6
        packets = [[[(str(name), Accesses.of_words(int(rng.integers(0, 5)) * pw
                                                   + np.cumsum(rng.integers(0, pw, k)),
                                                   np.sort(rng.integers(0, owners, k)), pw))
                     for name in rng.permutation(["nodes", "indices", "vertices"])[:rng.integers(1, 4)]
                     for k in [int(rng.integers(0, 6))]]
                    for _ in range(int(rng.integers(0, 4)))] for _ in range(int(rng.integers(1, 5)))]
        carried, settled = Streams(pw, pairs), Streams(pw, pairs)
        for calls in packets:
            got = []
            for pairs_of in (carried, Deferred.like(settled)):
                t, i = np.zeros(owners, np.int64), np.zeros(owners, np.int64)
                for parts in calls:
                    pairs_of.charge_owner_major(parts, owners, {"nodes": t, "indices": t, "vertices": i})
                if isinstance(pairs_of, Deferred):
                    settled.settle(pairs_of)
                got.append((t, i))
            assert all(np.array_equal(a, b) for a, b in zip(*got, strict=True))
        live = {k: v for k, v in carried.states.items() if v.page >= 0}
        assert live == {k: v for k, v in settled.states.items() if v.page >= 0}


_KILLED_WORKER = """
import os, signal, sys
from concurrent.futures.process import BrokenProcessPool
from tlm.kernels import threads

def work(i):
    if i == 2:
        os.kill(os.getpid(), signal.SIGKILL)  # a worker killed (out of memory, say)
    return i

got = []
try:
    for r in threads.forked(work, range(6), 2):
        got.append(r)
except BrokenProcessPool:
    print("broken after", got)
    sys.exit(0)
print("no error", got)
sys.exit(1)
"""


def test_a_killed_forked_worker_fails_the_call_not_hangs(tmp_path):
    """The opt-in forked workers (TLM_FORK_WORKERS=1): a worker that dies ends the call
    with BrokenProcessPool, in order up to it, instead of waiting for its result forever
    (run in a fresh interpreter, with a guard against the hang it checks)."""
    import multiprocessing
    import subprocess
    import sys

    if "fork" not in multiprocessing.get_all_start_methods():
        pytest.skip("no fork on this platform")
    script = tmp_path / "killed.py"
    script.write_text(_KILLED_WORKER)
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120,
                          cwd=Path(__file__).resolve().parents[1])
    assert done.returncode == 0, done.stdout + done.stderr
    # the results before the dead worker's come in order (those still running may be lost with it)
    assert done.stdout.strip() in ("broken after []", "broken after [0]", "broken after [0, 1]")


def test_forked_workers_past_the_threads_maximum_or_where_asked_never_in_a_daemon(monkeypatch):
    """``TLM_FORK_WORKERS`` unset or empty: forked workers on more than DEFAULT_MAX_THREADS
    threads (where the batches run at once: the callers ask on more than one); ``1``:
    forked workers on any count; ``0``: threads on any count. Never in a daemon (a Dask
    worker may not have children), nor where there is no fork."""
    import multiprocessing

    fork = "fork" in multiprocessing.get_all_start_methods()
    for value in (None, ""):
        if value is None:
            monkeypatch.delenv("TLM_FORK_WORKERS", raising=False)
        else:
            monkeypatch.setenv("TLM_FORK_WORKERS", value)
        assert not threads.can_fork()  # (one thread: current())
        assert [threads.can_fork(n) for n in (2, 8, 9, 64)] == [False, False, fork, fork]
        with threads.using(9):
            assert threads.can_fork() == fork
    monkeypatch.setenv("TLM_FORK_WORKERS", "0")
    assert [threads.can_fork(n) for n in (2, 8, 9, 64)] == [False] * 4
    monkeypatch.setenv("TLM_FORK_WORKERS", "1")
    assert threads.can_fork() == fork
    assert [threads.can_fork(n) for n in (2, 8, 9, 64)] == [fork] * 4
    monkeypatch.setattr(multiprocessing.current_process(), "daemon", True, raising=False)
    assert not threads.can_fork()
    monkeypatch.delenv("TLM_FORK_WORKERS")
    assert not threads.can_fork(64)


@pytest.mark.parametrize("n", [1, 2, 3])
def test_background_runs_on_a_worker_and_hands_back_its_outcome(n):
    """``threads.background``: on several threads the call runs on a pool worker (whose
    kernels do not split again) while the caller goes on; on one, in the caller. Its result
    and its error come back through ``result()``."""
    import threading

    seen = {}

    def job():
        seen["thread"], seen["threads"] = threading.current_thread(), threads.current()
        return 42

    def fails():
        raise ValueError("no layout")

    with threads.using(n):
        assert threads.background(job).result() == 42
        assert (seen["thread"] is threading.main_thread()) == (n == 1) and seen["threads"] == 1
        with pytest.raises(ValueError, match="no layout"):
            threads.background(fails).result()


def test_the_numpy_engine_is_bit_identical_for_any_thread_count(small_chunks, monkeypatch):
    """The reference engine (``TLM_KERNELS=numpy``) too: whole batches test their blocks on
    several threads at once, each in scratch of its own (a shared one was overwritten under
    another thread's block, and the images changed from run to run)."""
    monkeypatch.setenv("TLM_KERNELS", "numpy")
    monkeypatch.setattr(batches, "BATCH_WORKERS", "threads")
    raw = _cfg("cornell-water", "refract")
    one = _render(raw, 1)
    for n in (2, 2, 3):
        _same_render(one, _render(raw, n))


@pytest.mark.slow
def test_the_thread_bench_ceiling_renders_the_same_frame_in_each_process(monkeypatch):
    """``bench_threads.py --ceiling``: the one-thread renders that run at once in processes
    of their own (the machine's ceiling for the work) render the frame the bench renders,
    bit for bit, and each reports its own wall and CPU seconds."""
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_threads

    path = Path(__file__).resolve().parents[1] / "configs" / "cornell.yaml"
    overrides = ["resolution=[12,10]"]
    _, res, _ = bench_threads.timed(path, overrides, 1)
    got = bench_threads.processes(path, overrides, 2)
    assert len(got) == 2
    assert {d for _, _, d in got} == {bench_threads.digest(res)}
    assert all(w > 0 and c > 0 for w, c, _ in got)
    # a process of another frame gives another digest: the comparison is of the frame
    other = bench_threads.processes(path, ["resolution=[10,12]"], 1)
    assert other[0][2] != bench_threads.digest(res)
    # a process that fails says so at once (a config that is not there), not at a timeout
    t0 = time.perf_counter()
    with pytest.raises(RuntimeError, match="failed warming up"):
        bench_threads.processes(path.with_name("no_such_config.yaml"), overrides, 2)
    assert time.perf_counter() - t0 < 60


def _cgroups(tmp_path: Path, files: dict[str, str], self_lines: str) -> tuple[Path, Path]:
    """A control-group tree under ``tmp_path`` (``files``: path -> text) and a
    ``/proc/self/cgroup`` that places the process in it."""
    root = tmp_path / "cgroup"
    root.mkdir()
    for rel, text in files.items():
        f = root / rel
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(text)
    me = tmp_path / "self_cgroup"
    me.write_text(self_lines)
    return root, me


@pytest.mark.parametrize("files, self_lines, cpus", [
    ({"cpu.max": "max 100000\n"}, "0::/\n", None),  # cgroup v2, no quota
    ({"cpu.max": "150000 100000\n"}, "0::/\n", 2),  # 1.5 CPUs: 2
    ({"cpu.max": "800000 100000\n", "a/b/cpu.max": "100000 100000\n"}, "0::/a/b\n", 1),  # the smallest on the path
    ({"a/cpu.max": "300000 100000\n", "a/b/cpu.max": "max 100000\n"}, "0::/a/b\n", 3),  # a parent's quota holds
    ({"cpu/cpu.cfs_quota_us": "-1\n", "cpu/cpu.cfs_period_us": "100000\n"}, "3:cpu,cpuacct:/\n", None),  # v1, none
    ({"cpu,cpuacct/docker/x/cpu.cfs_quota_us": "250000\n", "cpu,cpuacct/docker/x/cpu.cfs_period_us": "100000\n"},
     "5:memory:/docker/x\n4:cpu,cpuacct:/docker/x\n", 3),  # v1 in a container's group
    ({"cpu,cpuacct/cpu.cfs_quota_us": "200000\n", "cpu,cpuacct/cpu.cfs_period_us": "100000\n"},
     "4:cpu,cpuacct:/docker/x\n", 2),  # v1 in Docker: the container's group mounted as the root
    ({"cpu.max": "200000 100000\n"}, "0::/system.slice/docker-x.scope\n", 2),  # v2 likewise
    ({"cpu.max": "300000 100000\n", "../cpu.max": "100000 100000\n"}, "0::/../x\n", 3),  # no path leaves the mount
    ({"cpu.max": "lots 100000\n", "cpu/cpu.cfs_quota_us": "50000\n"}, "0::/\n", None),  # not understood: no guess
    ({}, "", None),  # no control groups at all
])
def test_the_cpu_quota_is_read_from_the_control_groups(tmp_path, files, self_lines, cpus):
    root, me = _cgroups(tmp_path, files, self_lines)
    assert threads.quota_cpus(root, me) == cpus


def test_the_cpus_available_stay_within_the_quota(monkeypatch, tmp_path):
    """A container's CPU quota caps the default of ``render.threads`` and of a sweep's ``--jobs``."""
    from tlm.experiments import sweep

    root, me = _cgroups(tmp_path, {}, "")
    monkeypatch.setattr(threads, "CGROUP_ROOT", root)
    monkeypatch.setattr(threads, "SELF_CGROUP", me)
    mask = threads.available()  # (no quota: the affinity mask, or the CPU count)
    (root / "cpu.max").write_text("100000 100000\n")
    (me).write_text("0::/\n")
    assert threads.available() == 1
    with threads.using(None) as n:
        assert n == 1 == threads.current()
    seen = []

    def no_pool(stack, jobs, dask, points, dask_wait=None):
        seen.append(jobs)
        raise KeyboardInterrupt  # (stops the sweep before it writes anything)

    monkeypatch.setattr(sweep, "open_executor", no_pool)
    path = tmp_path / "sweep.yaml"
    path.write_text("base: {scene: cornell, mode: rcast, resolution: [8, 8]}\ngrid: {arch.page_miss_cycles: [0, 12]}\n")
    with pytest.raises(KeyboardInterrupt):
        sweep.run_sweep(path, tmp_path / "out")
    assert seen == [1]
    (root / "cpu.max").write_text(f"{100000 * (mask + 5)} 100000\n")  # a quota above the mask: the mask
    assert threads.available() == mask
    (root / "cpu.max").write_text("max 100000\n")
    assert threads.available() == mask


def test_a_dask_workers_points_share_its_machines_cpus(monkeypatch):
    """On a Dask cluster the sweep cannot size a point's threads (the machines are not its
    own): a point sizes itself on its worker, the CPUs over the task slots of every worker
    on that machine; outside a worker, nothing changes."""
    import logging

    import distributed
    from distributed import Client, LocalCluster

    from tlm.experiments import dask_workers
    from tlm.experiments.dask_workers import dask_worker_threads

    assert dask_worker_threads() is None  # (not in a worker)
    monkeypatch.setattr(threads, "available", lambda: 16)
    monkeypatch.setattr(dask_workers, "_SLOTS", {})
    with LocalCluster(n_workers=2, threads_per_worker=3, processes=False, dashboard_address="127.0.0.1:0",
                      scheduler_kwargs={"dashboard": False}, silence_logs=logging.CRITICAL) as cluster, \
            Client(cluster) as client:
        for address in client.scheduler_info(n_workers=-1)["workers"]:  # (each worker asks the scheduler once)
            got = client.submit(dask_worker_threads, pure=False, workers=[address]).result()
            assert got == 16 // 6  # two workers of 3 slots here

        def unreachable(*args, **kwargs):
            raise RuntimeError("no scheduler")

        monkeypatch.setattr(distributed, "get_client", unreachable)
        got = client.map(lambda _: dask_worker_threads(), range(8), pure=False)
        assert set(client.gather(got)) == {16 // 6}  # what the scheduler said, kept: not asked again
        dask_workers._SLOTS.clear()
        assert client.submit(dask_worker_threads, pure=False).result() == 16 // 3  # unreachable: its own slots


def test_a_sweep_point_takes_its_workers_share_where_the_sweep_gave_none(monkeypatch, tmp_path):
    from tlm.experiments import sweep_point

    seen = []

    def render_nothing(cfg, folder, source):
        seen.append(cfg.render.threads)
        raise RuntimeError("stop here")

    monkeypatch.setattr(sweep_point, "cached_render", render_nothing)
    monkeypatch.setattr(sweep_point, "dask_worker_threads", lambda: 3)
    base = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8]}
    task = sweep_point.Task("h", base, {}, str(tmp_path), "sweep.yaml", str(tmp_path / "p"), {}, threads=None)
    assert sweep_point.run_point(task)["status"] == "failed"
    task = sweep_point.Task("h", base, {}, str(tmp_path), "sweep.yaml", str(tmp_path / "q"), {}, threads=2)
    sweep_point.run_point(task)
    task = sweep_point.Task("h", {**base, "render": {"threads": 5}}, {}, str(tmp_path), "sweep.yaml",
                            str(tmp_path / "r"), {}, threads=None)
    sweep_point.run_point(task)
    assert seen == [3, 2, 5]  # the worker's share; the sweep's; the config's own


def test_a_null_thread_count_takes_at_most_the_default_maximum_unless_forked(monkeypatch):
    """``render.threads: null`` takes the CPUs available, at most DEFAULT_MAX_THREADS (8) where
    the batches run on threads: on 16 cores 16 threads rendered slower than 8 (the interpreter
    lock). Where they run on forked workers (no shared lock: ``TLM_FORK_WORKERS`` unset past
    8 CPUs, or ``1``) it takes every CPU, but not where another thread runs beside the render
    (forked would fall back to threads). ``0``: threads, at most 8. A count asked for is kept;
    a sweep's worker share is capped unless ``TLM_FORK_WORKERS=1`` (the worker is another
    process, maybe a daemon)."""
    import multiprocessing

    from tlm.experiments import executors

    fork = "fork" in multiprocessing.get_all_start_methods()
    monkeypatch.setattr(threads, "_other_threads", lambda pools=True: [])  # (this test process: quiet)
    monkeypatch.setenv("TLM_FORK_WORKERS", "0")
    assert threads.DEFAULT_MAX_THREADS == 8
    monkeypatch.setattr(threads, "available", lambda: 16)
    with threads.using(None) as n:
        assert n == 8 == threads.current()
    with threads.using(12) as n:
        assert n == 12
    for value in ("0", "", None):
        if value is None:
            monkeypatch.delenv("TLM_FORK_WORKERS", raising=False)
        else:
            monkeypatch.setenv("TLM_FORK_WORKERS", value)
        monkeypatch.setattr(threads, "available", lambda: 16)
        assert executors.kernel_threads(2, None, 10) == 8  # (16 CPUs over 2 workers: 8 each)
        monkeypatch.setattr(threads, "available", lambda: 32)
        assert executors.kernel_threads(2, None, 10) == 8  # (16 each, capped)
        assert executors.kernel_threads(8, None, 10) == 4
        monkeypatch.setattr(threads, "available", lambda: 4)
        with threads.using(None) as n:
            assert n == 4
    monkeypatch.setattr(threads, "available", lambda: 16)
    with threads.using(None) as n:  # (unset)
        assert n == (16 if fork else 8)
    monkeypatch.setattr(threads, "_other_threads", lambda pools=True: ["a-user-thread"])
    with threads.using(None) as n:
        assert n == 8
    monkeypatch.setenv("TLM_FORK_WORKERS", "1")
    monkeypatch.setattr(threads, "_other_threads", lambda pools=True: [])
    with threads.using(None) as n:
        assert n == (16 if fork else 8)
    monkeypatch.setattr(threads, "available", lambda: 32)
    assert executors.kernel_threads(2, None, 10) == (16 if fork else 8)
