"""A notebook cell that shows a render's result or its timing prints a few short lines (the
scene, the resolution, the passes and their work, the photons, the throughput), not the
dataclass repr of every array; a Timing that was pickled shows the same lines."""

from __future__ import annotations

import dataclasses
import pickle

import pytest

import tlm
from tlm.arch.model import MODEL_NOT_KEPT, Timing
from tlm.experiments.run import RenderResult, programs_for, simulate_render

SMALL = {"scene": "cornell", "resolution": [20, 12], "render": {"spp": 1, "light_samples": 1}}
MODES = {"rcast": {"mode": "rcast"}, "pmap": {"mode": "pmap", "photons": {"count": 200}}}


@pytest.fixture(scope="module")
def renders(tmp_path_factory) -> dict[str, tuple[RenderResult, RenderResult]]:
    """Mode -> a tiny render of it and the same simulated (its ``timing`` set), made on first use."""
    class Renders(dict):
        def __missing__(self, mode: str) -> tuple[RenderResult, RenderResult]:
            with pytest.MonkeyPatch.context() as mp:
                mp.setenv("TLM_CACHE", str(tmp_path_factory.mktemp("cache")))
                res = tlm.render_image({**SMALL, **MODES[mode]})
            self[mode] = (res, simulate_render(res, programs_for(res.cfg, None)))
            return self[mode]

    return Renders()


@pytest.fixture(params=sorted(MODES))
def done(request, renders) -> tuple[RenderResult, RenderResult]:
    return renders[request.param]


def test_render_result_repr_is_a_few_lines(done):
    res, simulated = done
    text = repr(res)
    lines = text.splitlines()
    assert len(text) < 1000 and all(len(line) < 120 for line in lines)
    head = lines[0]
    assert "'cornell'" in head and f"{res.scene.n_triangles:,} triangles" in head and "20x12" in head
    assert f"mode {res.cfg.mode!r}" in head
    # one line per pass run, in order, with its main work totals as work_totals() gives them
    runs = res.plan.run_names
    assert [line.split(":")[0].strip() for line in lines[1:1 + len(runs)]] == list(runs)
    totals = res.work_totals()
    rcast = lines[1]
    for key in ("primary_rays", "shadow_rays", "tri_tests"):
        assert f"{key} {totals['rcast'][key]:,}" in rcast
    # (what the result holds: tlm.simulate returns a timing and leaves the render as it is)
    assert lines[-1].strip() == ("timing: not in this result: tlm.simulate(result) returns it (cycles, frames per "
                                 "second)")
    assert "None" not in text  # (in words, not the attribute's value)
    shown = repr(simulated).splitlines()
    assert shown[:-1] == lines[:-1]
    assert shown[-1].strip() == (f"simulated: throughput {simulated.timing.cycles['throughput']:,} cycles per "
                                 f"frame, {simulated.timing.fps:,.1f} fps")


def test_render_result_repr_names_the_photons(renders):
    res, _ = renders["pmap"]
    photons = [line for line in repr(res).splitlines() if line.strip().startswith("photons:")]
    maps = res.photons.photons
    assert photons == [f"  photons: {maps.emitted:,} emitted; stored {maps.caustic_map.n:,} caustic, "
                       f"{maps.indirect_map.n:,} indirect"
                       + (f", {maps.global_map.n:,} global" if maps.global_map is not None else "")]
    pmap = next(line for line in repr(res).splitlines() if line.startswith("  pmap:"))
    assert f"gathers {res.work_totals()['pmap']['gathers']:,}" in pmap


def test_render_result_repr_shortens_a_long_scene_name(done):
    res, _ = done
    long = dataclasses.replace(res, scene=dataclasses.replace(res.scene, name="a" * 500))
    head = repr(long).splitlines()[0]
    assert "'" + "a" * 37 + "...'" in head and len(head) < 160


def check_timing_repr(timing: Timing) -> None:
    text = repr(timing)
    lines = text.splitlines()
    assert len(text) < 1000 and len(lines) == 3 and all(len(line) < 120 for line in lines)
    cyc = timing.cycles
    assert lines[0] == (f"Timing: throughput {cyc['throughput']:,} cycles per frame, latency {cyc['latency']:,}, "
                        f"{timing.fps:,.1f} fps")
    for pm in ("vertex", "traversal", "intersection", "fragment"):
        assert f"{pm} {cyc[pm]:,}" in lines[1]
    pipes = timing.program.pipelines
    assert lines[2] == (f"  {pipes} pipeline{'s' if pipes != 1 else ''}, {len(timing.frames)} frames, "
                        f"{timing.events:,} SimPy events")


def test_timing_repr_is_a_few_lines(done):
    _, simulated = done
    check_timing_repr(simulated.timing)
    four = tlm.simulate(simulated, {"pipelines": 4})
    check_timing_repr(four)
    assert "  4 pipelines, " in repr(four)


def test_unpickled_timing_repr(done):
    _, simulated = done
    again = pickle.loads(pickle.dumps(simulated.timing))
    assert again.model is MODEL_NOT_KEPT
    check_timing_repr(again)
    assert repr(again) == repr(simulated.timing)


def test_a_slow_frame_shows_its_fps_in_three_figures(done):
    _, simulated = done
    slow = dataclasses.replace(simulated.timing, fps=0.0012345)
    assert ", 0.00123 fps\n" in repr(slow)
    assert repr(dataclasses.replace(simulated, timing=slow)).endswith(" cycles per frame, 0.00123 fps")
    fast = dataclasses.replace(simulated.timing, fps=12345.67)
    assert ", 12,345.7 fps\n" in repr(fast)
