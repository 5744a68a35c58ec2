"""The render bar's label follows the stage that runs (:class:`tlm.render.batches._Labels`),
also where batches run at once (threads > 1), on threads or forked workers: the photon trace,
then ``batch i/n <stage>`` of the first batch not done, not ``photon trace`` to the end. A
fake bar records the labels; the bar is display only (the same bits with and without it). The
photon trace and the warm-up have a bar of their own, with no steps, before the batches' bar
(whose steps, and so its rate and time left, are the batches' alone)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

import tlm.render.batches as batches
from tlm.config import config_from_dict
from tlm.experiments.loading import load_frame
from tlm.render.planner import plan

REPO = Path(__file__).resolve().parents[1]


class FakeBar:
    """What the render calls on its bar, recording each label and the thread that set it;
    a label set while another is being set (two threads at once) is an error."""

    disable = False

    def __init__(self, *args, **kwargs):
        self.labels: list[str] = []
        self.threads: set[str] = set()
        self.steps = 0
        self.inside = threading.Lock()
        self.overlaps = 0

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def set_postfix_str(self, s: str) -> None:
        if not self.inside.acquire(blocking=False):
            self.overlaps += 1
            self.inside.acquire()
        try:
            self.labels.append(s)
            self.threads.add(threading.current_thread().name)
        finally:
            self.inside.release()

    def update(self, n: int = 1) -> None:
        self.steps += n


def _frame(threads: int):
    raw = {"scene": "cornell", "mode": "pmap", "resolution": [16, 16], "photons": {"count": 800},
           "render": {"spp": 2, "light_samples": 1, "threads": threads, "batch_rays": 64}}
    return load_frame(config_from_dict(raw))


@pytest.mark.parametrize("n_threads", [1, 2])
def test_the_label_follows_each_batch_s_stages_on_threads(n_threads, monkeypatch):
    monkeypatch.setenv("TLM_FORK_WORKERS", "0")  # (batches at once on the threads' pool)
    monkeypatch.setattr(batches, "MIN_BATCH_RAYS", 16)
    frame = _frame(n_threads)
    names = plan(frame.scene, frame.cfg).run_names
    plain = batches.render_batches(frame)
    bars: list[FakeBar] = []
    monkeypatch.setattr(batches, "progress_bar", lambda *a, **k: bars.append(FakeBar()) or bars[-1])
    shown = batches.render_batches(frame, progress=True)
    before, bar = bars  # (the photon trace's and the warm-up's, then the batches')
    n = len(batches.batches_for(16 * 16, 2, 64, n_threads))
    assert n > 2 * n_threads
    assert before.steps == 0 and before.labels == ["photon trace", "prepare"][:n_threads]
    assert bar.steps == n * (1 + len(names)) and bar.overlaps == 0
    # the first batch's every stage, in order (it is the first not done while it runs), then later batches'
    first = [s for s in bar.labels if s.startswith(f"batch 1/{n} ")]
    assert first == [f"batch 1/{n} {stage}" for stage in ("cast", *names)], bar.labels
    order = [int(s.split()[1].split("/")[0]) for s in bar.labels if s.startswith("batch ")]
    assert order == sorted(order) and order[-1] > n // 2, bar.labels  # (the first not done: later and later)
    if n_threads > 1:
        assert any(t != threading.main_thread().name for t in bar.threads)  # (set live by the batches' threads)
    for name in plain.radiance:  # display only
        assert plain.radiance[name].tobytes() == shown.radiance[name].tobytes(), name


def test_labels_from_many_threads_at_once_end_on_the_board_s_state():
    bar = FakeBar()
    labels = batches._Labels(bar, 40, ("rcast", "pmap"))
    go = threading.Barrier(8)

    def run(k: int) -> None:
        go.wait()
        for i in range(k, 40, 8):
            for stage in ("cast", "rcast", "pmap"):
                labels.enter(i, stage)
            if i != 37:
                labels.enter(i, None)

    workers = [threading.Thread(target=run, args=(k,)) for k in range(8)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    assert bar.overlaps == 0
    assert bar.labels[-1] == "batch 38/40 pmap"  # (every batch done but batch 38, last in its pmap pass)
    assert labels.first == 37


SCRIPT = r"""
import json, os, sys, time
import tlm.render.batches as batches
from tlm.config import config_from_dict
from tlm.experiments.loading import load_frame
from tlm.kernels import threads

sys.path.insert(0, os.environ["TESTS_DIR"])
from test_render_bar_stage import FakeBar

bars, pids = [], os.environ["PIDS"]
batches.progress_bar = lambda *a, **k: bars.append(FakeBar()) or bars[-1]
batches.MIN_BATCH_RAYS = 16
real = batches.pmap_pass

def slow_pmap(*a, **k):  # (a pass long enough that a batch is in it when the one before is taken)
    with open(pids, "a") as f:
        f.write(f"{os.getpid()}\n")
    time.sleep(0.05)
    return real(*a, **k)

batches.pmap_pass = slow_pmap
raw = {"scene": "cornell", "mode": "pmap", "resolution": [16, 16], "photons": {"count": 800},
       "render": {"spp": 2, "light_samples": 1, "threads": 2, "batch_rays": 64}}
frame = load_frame(config_from_dict(raw))
assert threads.can_fork(2)
batches.render_batches(frame, progress=True)
print(json.dumps({"labels": [s for b in bars for s in b.labels], "pid": os.getpid()}))
"""


@pytest.mark.slow
@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork here")
def test_the_label_follows_forked_workers_stages(tmp_path):
    pids = tmp_path / "pids"
    env = {**os.environ, "TLM_FORK_WORKERS": "1", "TLM_CACHE": str(tmp_path / "cache"), "PIDS": str(pids),
           "PYTHONPATH": str(REPO), "TESTS_DIR": str(REPO / "tests")}
    out = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=300,
                         cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    workers = set(pids.read_text().split()) - {str(got["pid"])}
    assert workers, "the batches ran in this process: no forked workers"
    labels = got["labels"]
    assert labels[:2] == ["photon trace", "prepare"], labels
    # (read from the workers' board as each batch is taken: a later batch, in one of its stages)
    assert any(s.startswith("batch ") and not s.startswith("batch 1/") for s in labels), labels
