"""A lost interrupt stops the command at its next checkpoint. The command line's handler turns
SIGINT / SIGTERM into a KeyboardInterrupt; raised where CPython drops exceptions (an llvmlite
ctypes callback during a numba compilation, an at-fork hook, a ``__del__``) it never reaches the
command, which used to run to its end (minutes, for a large render) before exiting 130 / 143.
Now the signal is noted too (:func:`tlm.progress.signal_taken`), and the top of the next render
batch, pass, photon chunk or sweep point (:func:`tlm.progress.checkpoint`) raises it again, once:
the command stops there as if the interrupt had landed (exit 130 / 143, its one line, nothing
half written, no worker left)."""

from __future__ import annotations

import ctypes
import json
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest
import yaml

from tlm import cli_signals, progress
from tlm.experiments import sweep as sweep_mod
from tlm.kernels import photons, threads
from tlm.kernels.traverse import build_accel
from tlm.scenes.loader import load_scene

REPO = Path(__file__).resolve().parents[1]


@ctypes.CFUNCTYPE(None, ctypes.c_int)
def _callback(sig):  # (CPython drops what a ctypes callback raises: "Exception ignored on calling ctypes callback")
    os.kill(os.getpid(), sig)
    for _ in range(10**7):  # (the handler raises at one of these instructions)
        pass


def lost(sig: int) -> None:
    """Signal this process where its KeyboardInterrupt is dropped, as in llvmlite's callbacks."""
    _callback(sig)


# a tiny ``tlm run`` (16x16, batches of 16 pixels) whose signal is lost in the main thread: at
# the first batch on one thread, before the batches on two forked workers; each batch begun (in
# whatever process) is a line of ``began``; its stdout's last line: its status and its workers left
SCRIPT = r"""
import ctypes, json, multiprocessing, os, signal, sys
import tlm.render.batches as batches
from tlm.cli import main
sig, forked = getattr(signal, sys.argv[1]), sys.argv[2] == "forked"

@ctypes.CFUNCTYPE(None)
def callback():
    os.kill(os.getpid(), sig)
    for _ in range(10**7):
        pass

real_batch, real_warm = batches._run_batch, batches._warm
n = []

def batch(*a, **k):
    with open("began", "a") as f:
        f.write(f"{os.getpid()}\n")
    n.append(1)
    if not forked and len(n) == 1:
        callback()
    return real_batch(*a, **k)

def warm(*a, **k):
    callback()
    return real_warm(*a, **k)

batches._run_batch, batches._warm = batch, warm
batches.MIN_BATCH_RAYS = 16  # (16x16 in batches of 16 pixels on two threads too)
rc = main(["run", sys.argv[3], "--out", "r", "--no-report", "--no-progress", "--set", "mode=reflect",
           "--set", "resolution=[16,16]", "--set", "render.spp=1", "--set", "render.light_samples=1",
           "--set", "render.batch_rays=" + ("64" if forked else "16"),
           "--set", "render.threads=" + ("2" if forked else "1")])
print(json.dumps({"rc": rc, "workers": len(multiprocessing.active_children()), "pid": os.getpid()}))
"""


@pytest.mark.parametrize("how", ["one thread", "forked"])
def test_a_lost_interrupt_stops_the_run_at_its_next_batch(how, tmp_path):
    """16 batches of 16 pixels: the run stops after the first (one thread) or the first
    batches in flight (forked workers), not at its end; no results, one line, no worker left."""
    sig = signal.SIGTERM if how == "one thread" else signal.SIGINT
    env = {**os.environ, "TLM_CACHE": str(tmp_path / "cache"), "PYTHONPATH": str(REPO),
           "TLM_FORK_WORKERS": "1" if how == "forked" else "0"}
    env.pop("TLM_KERNELS", None)
    proc = subprocess.run([sys.executable, "-c", SCRIPT, signal.Signals(sig).name, how.split()[0],
                           str(REPO / "configs" / "cornell.yaml")],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    began = (tmp_path / "began").read_text().split()
    line = "tlm: interrupted" if sig == signal.SIGINT else "tlm: terminated (SIGTERM)"
    pid = str(got.pop("pid"))
    assert got == {"rc": 128 + sig, "workers": 0}, proc.stdout
    assert proc.stderr == line + "\n"  # (not "..., but the command ran to its end", nor a traceback)
    if how == "one thread":
        assert began == [pid]  # (16 before: every batch)
    else:
        assert began and pid not in began  # (run by the forked workers)
        assert len(began) <= 8, began  # (the first batches in flight, of 16)
    assert [p.name for p in tmp_path.iterdir() if p.name != "cache"] == ["began"]  # no run folder, nothing half written


def test_a_checkpoint_raises_a_lost_signal_once_in_the_process_and_thread_that_took_it(monkeypatch):
    seen: list[BaseException] = []

    def elsewhere() -> None:
        try:
            progress.checkpoint()
        except BaseException as e:  # (pytest would only warn of it)
            seen.append(e)

    with cli_signals.signals():
        progress.checkpoint()  # no signal: nothing
        lost(signal.SIGINT)  # (its KeyboardInterrupt dropped)
        assert cli_signals.signalled() == signal.SIGINT
        worker = threading.Thread(target=elsewhere)
        worker.start()
        worker.join()
        assert seen == []  # not on another thread: the main one's next checkpoint takes it
        pid = os.getpid()
        with monkeypatch.context() as m:  # a forked worker inherits the list: not there either
            m.setattr(progress.os, "getpid", lambda: pid + 1)
            progress.checkpoint()
        with pytest.raises(KeyboardInterrupt):
            progress.checkpoint()
        progress.checkpoint()  # once only
    with cli_signals.signals():
        lost(signal.SIGTERM)
    progress.checkpoint()  # the command over (a notebook's calls after it): nothing


def test_without_the_command_line_a_signal_is_nothing_to_a_checkpoint(monkeypatch):
    """A notebook's Ctrl-C (Python's own handler) is not the command line's: no checkpoint raises it."""
    dropped: list = []
    monkeypatch.setattr(sys, "unraisablehook", dropped.append)
    before = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        lost(signal.SIGINT)
    finally:
        signal.signal(signal.SIGINT, before)
    assert [type(u.exc_value) for u in dropped] == [KeyboardInterrupt]  # (lost)
    progress.checkpoint()


def test_a_lost_interrupt_stops_the_photon_trace_at_its_next_chunk(monkeypatch):
    scene = load_scene("cornell")
    accel = build_accel(scene.triangles)
    real = threads.ordered
    began: list = []

    def ordered(fn, items, *a, **k):
        if fn.__qualname__ != "trace_photons.<locals>.trace":  # (the kernels' own chunks)
            return real(fn, items, *a, **k)

        def one(item):
            began.append(item)
            if len(began) == 1:
                lost(signal.SIGTERM)
            return fn(item)
        return real(one, items, *a, **k)

    monkeypatch.setattr(threads, "ordered", ordered)
    n = 3 * photons.PHOTON_MIN_BATCH
    with cli_signals.signals(), pytest.raises(KeyboardInterrupt):
        photons.trace_photons(scene, accel, n, max_bounces=2, batch_rays=1)
    assert began == [(0, photons.PHOTON_MIN_BATCH)]  # (of three chunks)


def test_a_lost_interrupt_stops_the_sweep_at_its_next_point(tmp_path, monkeypatch, cache):
    base = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1},
            "arch": {"frames": 1, "trace": False, "packet_size": 16}}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": base, "grid": {"seed": [0, 1, 2]}}))
    real = sweep_mod.run_point
    began: list = []

    def run_point(task):
        began.append(task.hash)
        if len(began) == 1:
            lost(signal.SIGINT)
        return real(task)

    monkeypatch.setattr(sweep_mod, "run_point", run_point)
    out = tmp_path / "out"
    with cli_signals.signals(), pytest.raises(KeyboardInterrupt):
        sweep_mod.run_sweep(path, out, jobs=1)
    assert len(began) == 1  # (of three points)
    assert [p.name for p in (out / "points").iterdir() if p.name.startswith(".")] == []  # nothing half written
