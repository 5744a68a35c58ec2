"""The render's batch loop (:mod:`tlm.render.batches`) on a frame of its own.

What the loop promises beside the passes: by default the passes the planner runs, in
order; the whole image's radiance (for the passes that make one), work and primary AOVs
whatever the batches; the stages it books; and batch cuts that cover the image in
pixel order. Whole renders through ``tlm run`` are the other tests' concern.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from tlm.config import config_from_dict
from tlm.experiments.loading import load_frame
from tlm.progress import Timer
from tlm.render.batches import MIN_BATCH_RAYS, _put_counts, batches_for, render_batches
from tlm.render.frame import GBuffer, ImageGBuffer
from tlm.render.planner import WORK_PASSES, plan


def _frame(mode: str, batch_rays: int):
    raw = {"scene": "cornell", "mode": mode, "resolution": [12, 9], "photons": {"count": 800},
           "render": {"spp": 2, "threads": 1, "batch_rays": batch_rays}}
    return load_frame(config_from_dict(raw))


@pytest.fixture(scope="module")
def reflect_frames():
    return _frame("reflect", 1 << 20), _frame("reflect", 2 * 10)  # one batch; 11 of ten pixels


def test_the_loop_renders_the_planned_passes_and_books_their_stages(reflect_frames):
    frame = reflect_frames[0]
    timer = Timer()
    done = render_batches(frame, timer=timer)
    names = plan(frame.scene, frame.cfg).run_names
    assert list(done.work) == names and "reflect" in names
    assert list(done.radiance) == [n for n in names if n not in WORK_PASSES]
    assert all(r.shape == (9, 12, 3) for r in done.radiance.values())
    assert done.work["rcast"]["primary_rays"].shape == (9, 12) and done.work["rcast"]["primary_rays"].sum() == 216
    assert done.primary.rays == 216 and done.primary.triangle.shape == (108,)
    assert {"cast", *(f"pass_{n}" for n in names)} <= set(timer.seconds)
    assert isinstance(done.gbuffer, GBuffer) and done.photons is None and done.gather_maps is None
    only = render_batches(frame, ["rcast"])
    assert list(only.work) == ["rcast"]
    np.testing.assert_array_equal(only.radiance["rcast"], done.radiance["rcast"])


def test_batches_give_the_one_batch_render_bit_for_bit(reflect_frames):
    whole, cut = (render_batches(f) for f in reflect_frames)
    assert isinstance(cut.gbuffer, ImageGBuffer)
    for name in whole.radiance:
        assert whole.radiance[name].tobytes() == cut.radiance[name].tobytes(), name
    for name, counts in whole.work.items():
        for k, v in counts.items():
            np.testing.assert_array_equal(v, cut.work[name][k], err_msg=f"{name}.{k}")
    assert cut.work["rcast"]["trav_misses"].sum() > 0  # (the carried cache pairs: misses in pixel order)
    for f in ("origin", "direction", "t", "triangle", "normal", "sees_light"):
        np.testing.assert_array_equal(getattr(whole.primary, f), getattr(cut.primary, f), err_msg=f)
    assert (whole.primary.rays, whole.primary.hits) == (cut.primary.rays, cut.primary.hits)


@pytest.mark.parametrize("n_pixels, spp, batch_rays, n_threads", [
    (108, 2, 20, 1), (1000, 1, 1 << 20, 1), (100_000, 4, 131_072, 2), (100_000, 1, 131_072, 8), (50, 3, 7, 3)])
def test_batch_cuts_cover_the_image_in_pixel_order(n_pixels, spp, batch_rays, n_threads):
    cuts = batches_for(n_pixels, spp, batch_rays, n_threads)
    assert cuts[0].start == 0 and cuts[-1].stop == n_pixels
    assert all(a.stop == b.start for a, b in itertools.pairwise(cuts))
    rays = [(c.stop - c.start) * spp for c in cuts]
    if n_threads == 1:
        assert max(rays) <= max(batch_rays, spp)
    else:  # smaller batches, that run at once, but none under MIN_BATCH_RAYS (bar the last and one pixel)
        # (the window of twice the threads' batches in flight holds about one batch_rays)
        assert max(rays) <= max(spp, min(batch_rays, max(MIN_BATCH_RAYS, batch_rays // (2 * n_threads))))
        assert all(r >= min(MIN_BATCH_RAYS, batch_rays) - spp for r in rays[:-1])
    if n_pixels * spp >= 3 * n_threads * MIN_BATCH_RAYS and n_threads > 1:
        assert len(cuts) >= n_threads  # enough batches for every thread
    if n_threads > 1 and rays[0] >= 2 * MIN_BATCH_RAYS and cuts[0].stop - cuts[0].start >= 2 and len(cuts) > n_threads:
        assert max(rays[-n_threads:]) <= rays[0] // 2  # the threads end on small pieces


def test_image_counts_are_int32_until_a_count_does_not_fit(reflect_frames):
    done = render_batches(reflect_frames[1])
    assert all(v.dtype == np.int32 for counts in done.work.values() for v in counts.values())
    counts: dict[str, np.ndarray] = {}
    _put_counts(counts, "k", np.array([1, 2]), slice(0, 2), 6)
    assert counts["k"].dtype == np.int32
    big = np.iinfo(np.int32).max + 1
    _put_counts(counts, "k", np.array([big, 3]), slice(2, 4), 6)  # widened, the earlier counts kept
    _put_counts(counts, "k", np.array([4, 5]), slice(4, 6), 6)
    assert counts["k"].dtype == np.int64 and counts["k"].tolist() == [1, 2, big, 3, 4, 5]
    _put_counts(counts, "neg", np.array([-big - 1]), slice(0, 1), 1)  # (below int32 too)
    assert counts["neg"].dtype == np.int64 and counts["neg"][0] == -big - 1


def test_freed_memory_is_given_back_where_glibc_allows(monkeypatch):
    """``release_memory`` (glibc's malloc_trim, called between the render's stages) returns
    freed heap blocks, which the allocator tuning keeps otherwise; it leaves the allocator
    alone when asked to (``TLM_NO_MALLOPT=1``)."""
    import ctypes.util
    import platform

    from tlm.kernels import _malloc, release_memory

    def rss_mib() -> float:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * 4096 / 2**20

    if not (platform.system() == "Linux" and platform.libc_ver()[0] == "glibc" and ctypes.util.find_library("c")
            and _malloc.TUNED):
        pytest.skip("glibc's allocator, tuned, is what this checks")
    blocks = [np.ones(1 << 17) for _ in range(96)]  # 96 blocks of 1 MiB: heap, not mmap, under the trim threshold
    held = rss_mib()
    del blocks
    assert rss_mib() > held - 30  # (freed, but kept by the tuned allocator)
    assert release_memory() is True
    assert rss_mib() < held - 60  # given back
    monkeypatch.setenv("TLM_NO_MALLOPT", "1")
    assert release_memory() is False


_THREAD_MAPPED = """
import ctypes, ctypes.util, threading
import numpy as np
import tlm.kernels  # (tunes the allocator unless TLM_NO_MALLOPT is set)
class Info(ctypes.Structure):
    _fields_ = [(k, ctypes.c_size_t) for k in
                "arena ordblks smblks hblks hblkhd usmblks fsmblks uordblks fordblks keepcost".split()]
libc = ctypes.CDLL(ctypes.util.find_library("c"))
libc.mallinfo2.restype = Info
mapped = []
def work():
    for _ in range(2):
        a = np.ones(96 << 17)  # 96 MiB
        mapped.append(libc.mallinfo2().hblkhd)  # bytes in blocks mapped on their own
        del a
t = threading.Thread(target=work)
t.start()
t.join()
print(*mapped)
"""


def test_a_worker_thread_allocates_large_arrays_from_the_tuned_heap():
    """The render's worker threads allocate from the tuned arena: an array of 96 MiB made
    in a thread comes from the heap (where a freed one is reused), not from a mapping of
    its own (a page fault per page, every time). Untuned (``TLM_NO_MALLOPT=1``), and with
    the thresholds alone, glibc gives the thread an arena of its own, which maps every
    array over 64 MiB afresh: what the check can see."""
    import ctypes
    import ctypes.util
    import os
    import platform
    import subprocess
    import sys

    if not (platform.system() == "Linux" and platform.libc_ver()[0] == "glibc" and ctypes.util.find_library("c")
            and hasattr(ctypes.CDLL(ctypes.util.find_library("c")), "mallinfo2")):
        pytest.skip("glibc's allocator (2.33 or later: mallinfo2) is what this checks")
    size = 96 << 20

    def mapped(**env) -> list[int]:
        own = {k: v for k, v in os.environ.items()  # (glibc's own settings from the environment left out)
               if not k.startswith("MALLOC_") and k not in ("GLIBC_TUNABLES", "TLM_NO_MALLOPT")}
        out = subprocess.run([sys.executable, "-c", _THREAD_MAPPED], env={**own, **env}, check=True,
                             capture_output=True, text=True).stdout
        return [int(x) for x in out.split()]

    assert min(mapped(TLM_NO_MALLOPT="1")) >= size
    assert max(mapped()) < size
