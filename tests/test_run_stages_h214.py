"""Where a run's host time went: its stages account for a cold run's compiling (``one_off``), the
render bar's steps are the batches' alone, and the radii record the rule that gave them."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

import tlm.render.batches as batches
from tlm.config import config_from_dict
from tlm.experiments.run import render, run
from tlm.kernels import threads
from tlm.progress import Timer
from tlm.render.pmap import FALLBACK_FRACTION, radii


def _compiling(seconds: float) -> None:
    """What numba compiling a kernel looks like to the one-off clock: its compiler lock's event held."""
    from numba.core import event

    with event.trigger_event("numba:compiler_lock"):
        time.sleep(seconds)


def test_time_booked_apart_leaves_the_stages_it_covers():
    timer = Timer()
    timer.seconds = {"cast": 3.0, "pass_fgather": 5.0, "write": 1.0}
    timer.spans = {"cast": [(0.0, 3.0)], "pass_fgather": [(3.0, 8.0)]}  # ("write": seconds alone, no spans)
    timer.book_apart("one_off", [(2.0, 4.0), (3.5, 6.0), (9.0, 9.5)])  # (overlapping spans counted once)
    assert timer.seconds["cast"] == pytest.approx(2.0)
    assert timer.seconds["pass_fgather"] == pytest.approx(2.0)
    assert timer.seconds["write"] == 1.0
    assert timer.seconds["one_off"] == pytest.approx(4.5)  # (2 .. 6 and 9 .. 9.5: between stages too)
    empty = Timer()
    empty.book_apart("one_off", [])
    assert empty.seconds == {"one_off": 0.0}


def test_a_cold_runs_warm_up_is_its_one_off_stage_and_the_stages_add_up(tmp_path, monkeypatch):
    """A warm-up that compiles for 1.5 s (batches run at once on 2 threads: batches._warm) was in no
    stage: the stages summed to 1.5 s less than the run took, and results.json had no one_off."""
    real = batches._warm

    def cold(frame, traced):
        _compiling(1.5)
        real(frame, traced)

    monkeypatch.setattr(batches, "_warm", cold)
    cfg = config_from_dict({"scene": "cornell", "mode": "rcast", "resolution": [64, 64], "render": {"threads": 2},
                            "arch": {"packet_size": 16}})
    t0 = time.perf_counter()
    results = run(cfg, tmp_path / "run", outputs=())
    wall = time.perf_counter() - t0
    host = results["host_seconds"]
    assert host == json.loads((tmp_path / "run" / "results.json").read_text())["host_seconds"]
    assert host["one_off"] >= 1.5
    assert host["prepare"] < 1.0  # (the warm-up's compiling is one_off's, not its stage's)
    assert sum(host.values()) >= wall - 0.5  # (what is in no stage: the plan, the claim, the folder's move)


def test_the_render_bar_counts_the_batches_steps_not_the_photon_trace(monkeypatch):
    """The photon trace was one step of the render bar, so its rate after the trace (16 s a step on the
    conference room) said minutes were left for the batches' 3 s."""
    made, traced_at = [], []
    real_bar, real_trace = batches.progress_bar, batches.trace_photon_map

    def bar(enabled, **kwargs):
        made.append((kwargs.get("total"), time.perf_counter()))
        return real_bar(enabled, **kwargs)

    def trace(*args, **kwargs):
        out = real_trace(*args, **kwargs)
        traced_at.append(time.perf_counter())
        return out

    monkeypatch.setattr(batches, "progress_bar", bar)
    monkeypatch.setattr(batches, "trace_photon_map", trace)
    res = render(config_from_dict({"scene": "cornell", "mode": "pmap", "resolution": [16, 16],
                                   "photons": {"count": 500}, "render": {"threads": 1}}))
    names = res.plan.run_names
    n = len(batches.batches_for(16 * 16, res.frame.spp, res.cfg.render.batch_rays, 1))
    stepped = [(total, at) for total, at in made if total is not None]
    assert [total for total, _ in stepped] == [n * (1 + len(names))]
    assert traced_at and stepped[0][1] >= traced_at[0]  # (its clock starts after the trace)


def test_an_empty_maps_radius_records_the_fallback_it_used():
    """No caustic photon (nor 2 indirect ones): the radius is the fallback fraction of the diagonal,
    recorded as such, not as the density rule (with its k) that could not measure the map."""
    res = render(config_from_dict({"scene": "cornell", "mode": "pmap", "resolution": [4, 4],
                                   "photons": {"count": 1}}))
    photons = res.photons.photons
    assert photons.caustic_map.n == 0 and photons.indirect_map.n < 2
    got = radii(res.frame, photons)
    diag = res.frame.accel.scale
    assert got["caustic_radius_rule"] == got["radius_rule"] == "fallback"
    assert got["caustic_radius"] == FALLBACK_FRACTION["caustic"] * diag
    assert got["caustic_radius_fraction"] == FALLBACK_FRACTION["caustic"]
    assert got["radius_fraction"] == FALLBACK_FRACTION["indirect"]
    assert "caustic_radius_photons" not in got and "radius_photons" not in got
    assert got["global_radius_rule"] == "fallback" and "global_radius_photons" not in got


ROOT = Path(__file__).resolve().parents[1]


def test_tlm_run_where_numba_does_not_import_times_first_imports_alone(tmp_path, cache):
    """numba not importable (the numpy kernels run): the one-off clock's numba listener made `tlm run`
    an internal error (ImportError from error_cost_clock); now the import hook alone times it."""
    shim = tmp_path / "nonumba" / "numba"
    shim.mkdir(parents=True)
    (shim / "__init__.py").write_text('raise ImportError("no numba")\n')
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path / "nonumba"), str(ROOT)]),
           "TLM_KERNELS": ""}
    done = subprocess.run([sys.executable, "-m", "tlm", "run", str(ROOT / "configs" / "cornell.yaml"),
                           "--set", "resolution=[8,8]", "--out", str(tmp_path / "run"), "--no-progress"],
                          capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "one_off" in json.loads((tmp_path / "run" / "results.json").read_text())["host_seconds"]


def test_the_clock_imports_no_numba_for_the_numpy_kernels(tmp_path):
    """With TLM_KERNELS=numpy the clock imported numba (its listener) just to time a run that never compiles."""
    script = ("import sys\nfrom tlm.experiments.error_cost_clock import CompileClock\nclock = CompileClock()\n"
              "with clock.running():\n    import colorsys  # noqa\n"
              "print('numba' in sys.modules, clock.within(0.0, 1e12) > 0)\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TLM_KERNELS": "numpy"}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, cwd=tmp_path,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["False", "True"]  # (no numba; the first import timed)


def test_clocks_that_stop_out_of_order_leave_the_import_statement_as_it_was():
    """A run's clock and a sweep point's (two threads) entered a, b and left a, b: builtins.__import__
    stayed wrapped for the life of the process, and the run's clock went on recording."""
    import builtins

    import tlm.experiments.run as runs
    import tlm.experiments.sweep_point as sweep_point

    real = builtins.__import__
    a = runs.one_off_clock()
    a.__enter__()
    b = sweep_point._one_off_clock()
    b.__enter__()
    a.__exit__(None, None, None)
    assert builtins.__import__ is not real  # (the point's clock still runs)
    b.__exit__(None, None, None)
    assert builtins.__import__ is real
    n = len(runs._CLOCK.spans)
    import xml.dom.pulldom  # noqa: F401  (a first import, no clock running)

    assert len(runs._CLOCK.spans) == n


def test_another_threads_compiling_is_not_the_runs_one_off_but_its_kernel_threads_is(tmp_path, monkeypatch):
    """Another thread's compile (0.8 s) while the run's warm-up worked (1 s) was booked to the run's
    one_off and taken out of its prepare; the kernel pool's compile for the run (0.6 s) is the run's."""
    real = batches._warm
    began = threading.Event()

    def other():
        began.wait(30)
        _compiling(0.8)

    def warm(frame, traced):
        began.set()
        time.sleep(1.0)  # (the run's own work, meanwhile)
        threads.background(lambda: _compiling(0.6)).result()  # (on a kernel thread, for the run)
        real(frame, traced)

    monkeypatch.setattr(batches, "_warm", warm)
    beside = threading.Thread(target=other)
    beside.start()
    try:
        cfg = config_from_dict({"scene": "cornell", "mode": "rcast", "resolution": [64, 64],
                                "render": {"threads": 2}, "arch": {"packet_size": 16}})
        host = run(cfg, tmp_path / "run", outputs=())["host_seconds"]
    finally:
        began.set()
        beside.join()
    assert 0.55 <= host["one_off"] < 1.2
    assert host["prepare"] >= 0.9


def test_a_span_of_the_runs_still_open_as_it_writes_is_its_one_off(tmp_path, monkeypatch):
    """A compile for the run still under way when results.json's seconds were measured was left out."""
    import tlm.experiments.run as runs

    real = runs.results_dict
    pending = []

    def record(*args, **kwargs):
        with threads.using(2):
            pending.append(threads.background(lambda: _compiling(1.0)))
        time.sleep(0.5)
        return real(*args, **kwargs)

    monkeypatch.setattr(runs, "results_dict", record)
    cfg = config_from_dict({"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"threads": 1}})
    try:
        host = run(cfg, tmp_path / "run", outputs=())["host_seconds"]
    finally:
        for f in pending:
            f.result()
    assert host["one_off"] >= 0.45


def test_the_photon_trace_bar_is_redrawn_at_its_chunks_checkpoints():
    """The photon trace's bar was drawn once (render [00:00, photon trace]) while the trace ran; where it
    may fork (no Ticking thread) the chunks' checkpoints redraw it, in the thread that entered it only."""
    from tlm.progress import Redrawn, checkpoint

    class Bar:
        disable, drawn = False, 0

        def refresh(self):
            self.drawn += 1

    bar = Bar()
    with Redrawn(bar, every=0.05):
        checkpoint()
        assert bar.drawn == 0  # (at most every 0.05 s)
        time.sleep(0.06)
        elsewhere = threading.Thread(target=checkpoint)
        elsewhere.start()
        elsewhere.join()
        assert bar.drawn == 0
        checkpoint()
        assert bar.drawn == 1
    time.sleep(0.06)
    checkpoint()
    assert bar.drawn == 1


def test_the_photon_trace_bar_ticks_where_the_render_forks_no_worker(monkeypatch):
    """One thread: a Ticking thread redraws the photon trace's bar (its elapsed time)."""
    made = []

    class Probe:
        def __init__(self, bar):
            made.append(type(self).__name__)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return None

    monkeypatch.setattr(batches, "Ticking", type("Ticking", (Probe,), {}))
    monkeypatch.setattr(batches, "Redrawn", type("Redrawn", (Probe,), {}))
    bar = SimpleNamespace(disable=False)  # (a bar drawn: at a terminal)
    with threads.using(1):
        batches._kept_alive(bar)
    monkeypatch.setenv("TLM_FORK_WORKERS", "1")
    with threads.using(2):
        batches._kept_alive(bar)
    assert made == ["Ticking", "Redrawn"]


@pytest.fixture
def hooks_kept(monkeypatch):
    """The process's import statement and the clock's shared hooks put back after the test (whatever it left)."""
    import builtins

    import tlm.experiments.error_cost_clock as ecc

    for name in ("_ACTIVE", "_REAL_IMPORT", "_LISTENER"):
        monkeypatch.setattr(ecc, name, getattr(ecc, name))
    monkeypatch.setattr(builtins, "__import__", builtins.__import__)
    return ecc


def test_a_ctrl_c_while_the_hooks_go_on_leaves_them_off(hooks_kept, monkeypatch):
    """A KeyboardInterrupt while numba's first import ran (inside _hooks_on) left the import hook
    installed and the clock listed as running, for the life of the process."""
    import builtins

    ecc = hooks_kept
    real, before = builtins.__import__, ecc._ACTIVE

    def interrupted():
        raise KeyboardInterrupt

    monkeypatch.setattr(ecc, "_wants_numba", lambda: True)
    monkeypatch.setattr(ecc, "_numba_listener", interrupted)
    with pytest.raises(KeyboardInterrupt), ecc.CompileClock().running():
        pass
    assert builtins.__import__ is real and ecc._ACTIVE is before


def test_another_threads_compile_open_as_the_clock_stops_is_in_no_later_window(hooks_kept):
    """A compile on another thread still under way as the last clock stopped (its end never heard:
    the listener gone) stayed open on the clock: every later window's one_off covered it whole."""
    from numba.core import event

    clock = hooks_kept.CompileClock()
    began, done = threading.Event(), threading.Event()

    def compiling():
        with event.trigger_event("numba:compiler_lock"):
            began.set()
            done.wait(30)

    other = threading.Thread(target=compiling)
    with clock.running():
        other.start()
        assert began.wait(30)
    done.set()
    other.join()
    with clock.running():
        t0 = time.perf_counter()
        time.sleep(0.3)
        t1 = time.perf_counter()
        assert clock.within(t0, t1) < 0.05  # (was 0.3)


def test_a_ctrl_c_as_the_import_hook_starts_its_span_leaves_none_open(hooks_kept, tmp_path, monkeypatch):
    """A KeyboardInterrupt between the clocks' start and the hook's try: the span stayed open (the
    rest of the run's windows covered it) and the thread's stack dirty."""
    module = f"tlm_h225_probe_{os.getpid()}"
    (tmp_path / f"{module}.py").write_text("X = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, module, raising=False)

    class Interrupted(hooks_kept.CompileClock):
        interrupt = False

        def _start(self):
            super()._start()
            if self.interrupt:
                self.interrupt = False
                raise KeyboardInterrupt

    clock = Interrupted()
    with clock.running():
        clock.interrupt = True
        with pytest.raises(KeyboardInterrupt):
            __import__(module)  # (a first import: through builtins.__import__)
        t0 = time.perf_counter()
        time.sleep(0.3)
        t1 = time.perf_counter()
        assert clock.within(t0, t1) < 0.05  # (was 0.3)
    sys.modules.pop(module, None)


def test_the_import_hook_goes_on_again_after_a_library_restored_the_import_statement(hooks_kept):
    """A library's hook put over the clock's and then taken off (the original put back): no later
    clock wrapped the import statement again, and first imports went untimed."""
    import builtins

    ecc = hooks_kept
    real = builtins.__import__
    clock = ecc.CompileClock()
    with clock.running():
        builtins.__import__ = lambda *a, **k: real(*a, **k)  # (the library's, over the clock's)
    builtins.__import__ = real  # (the library taken off: what it saved put back)
    with clock.running():
        assert builtins.__import__ is ecc._timed_import
    assert builtins.__import__ is real
