"""h453: (A) a photon-map run that emits more than BLUR_RATIO times its reference's photons a round is
warned of (tlm.experiments.run_warnings.blur_warnings; per photon map since h465: tests/test_blur_warning_h465.py):
the reference's k-NN kernel is so much wider that the pmap error against it measures mostly the reference's blur.
Said by the run (``warnings``, ``results.json``), and by a frame read from the cache
(tlm.experiments.frames.cached_render), where it follows the reference of the config that reads it, not the
one the frame was cached with.
(B) A steady state of a period of two frames or more whose gaps differ by PERIOD_WARNING of TThru is
warned of (period_warnings): TThru is the mean over the period, which a small change of the work moves
a lot."""

from __future__ import annotations

import json
from dataclasses import replace
from types import SimpleNamespace

import tlm
from tlm.config import config_from_dict
from tlm.experiments.frames import cached_render
from tlm.experiments.run_warnings import (
    BLUR_RATIO,
    PERIOD_WARNING,
    blur_warnings,
    emitted_photons,
    period_gaps,
    period_warnings,
    stream_warnings,
)

# (a reference of a few hundred photons, four rounds of 8x8 pixels: well under a second)
TINY = {"mode": "pmap", "resolution": [8, 8], "render.spp": 1, "render.light_samples": 1,
        "photons.count": 2000, "reference.k_nearest": 20, "reference.spp": 1, "reference.min_rounds": 2,
        "reference.max_rounds": 4, "arch.packet_size": 16, "arch.frames": 2}
BLUR = "measure the reference's blur more"


def _blur(lines: list[str]) -> list[str]:
    return [w for w in lines if BLUR in w]


def test_a_run_past_the_ratio_warns_and_one_at_it_does_not(tmp_path, cache):
    assert BLUR_RATIO == 4
    past = tlm.run(tlm.load_config("cornell", {**TINY, "reference.photons": 400}), tmp_path / "p", outputs="images")
    error = past["error"]
    assert error["available"] and past["photons"]["emitted"] == 2000
    # (per map since h465: the global map, final gathering's, gets the run's 1000 not aimed at the glass, and the
    # reference's half of its 400; its caustic map, as many, ties)
    assert _blur(past["warnings"]) == [
        f"the photon-map frame's global map gets 1000 of the 2000 photons it emits, and that map of its reference "
        f"{error['reference']} gets 200 a round (half of reference.photons 400): each k-NN round of the reference (20 "
        "photons: reference.k_nearest) gathers in a map 5.00x sparser than this run's, so the pmap error against it "
        "(error.rmse, error.rel_mse) may measure the reference's blur more than this run's noise; raise "
        "reference.photons to 500 or more (at most 4x this run's on that map) and compute it again with "
        "'tlm reference'"]
    assert json.loads((tmp_path / "p" / "results.json").read_text())["warnings"] == past["warnings"]
    at = tlm.run(tlm.load_config("cornell", {**TINY, "reference.photons": 500}), tmp_path / "a", outputs="images")
    assert at["error"]["available"] and _blur(at["warnings"]) == []


def test_a_null_reference_count_is_the_scenes_and_caustic_photons_count(cache):
    # (the run's photons: its caustic group's own caustic_count beside count)
    res = tlm.render_image(tlm.load_config("cornell", {**TINY, "resolution": [4, 4], "photons.count": 200,
                                                       "photons.caustic_count": 800, "reference.auto": False}))
    assert emitted_photons(res)["emitted"] == 1000
    # (cornell's scene file gives 120000: a null reference.photons takes it, half of it its global group's; the run's
    # 482000 half too, 4.02x that)
    error = {"available": True, "reference": "k"}
    cfg = config_from_dict({"scene": "cornell", "mode": "pmap"}, "t")
    line = blur_warnings(error, cfg, 482000, 120000)
    assert len(line) == 1 and "global map gets 241000 of the 482000 photons it emits, and that map of its reference " \
        "k gets 60000 a round (half of the scene's 120000: reference.photons null)" in line[0] \
        and "4.02x sparser" in line[0] and "raise reference.photons to 120500 or more" in line[0]
    assert blur_warnings(error, cfg, 480000, 120000) == []  # (4x: not past the ratio)
    assert blur_warnings({"available": False, "reference": "k"}, cfg, 482000, 120000) == []  # (no error measured)
    assert blur_warnings(error, cfg, None, 120000) == []  # (no photon-map pass)


def test_a_cached_frame_says_the_line_of_the_reference_that_reads_it(tmp_path, cache):
    cfgs = {n: tlm.load_config("cornell", {**TINY, "reference.photons": n}) for n in (400, 2000)}
    for n, cfg in cfgs.items():  # (each computes and caches its reference)
        assert tlm.run(cfg, tmp_path / str(n), outputs="images")["error"]["available"]
    first = cached_render(cfgs[400].settings, cfgs[400].base, cfgs[400].label)
    assert not first.cached and len(_blur(first.summary["warnings"])) == 1
    side = json.loads(next((cache / "functional").glob("*.json")).read_text())
    assert _blur(side["warnings"]) == []  # (the frame's key holds no reference setting: measured when read)
    other = cached_render(cfgs[2000].settings, cfgs[2000].base, cfgs[2000].label)
    assert other.cached and other.key == first.key and _blur(other.summary["warnings"]) == []
    again = cached_render(cfgs[400].settings, cfgs[400].base, cfgs[400].label)
    assert again.cached and _blur(again.summary["warnings"]) == _blur(first.summary["warnings"])



# B: Cornell refract, one eye ray a pixel, one pipeline, two images: at 31x31 the stream settles into a period of
# two frames whose gaps are 2515016 and 1811230 cycles here (fps 277.4, where 31x30 gives 259.0 and 33x32 237.2;
# the cycles follow the sampled directions, whose last bits differ by CPU: tests/golden.py, so not asserted)
RACE = {"mode": "refract", "resolution": [31, 31], "render.spp": 1, "arch.trace": False}
PERIOD = "the stream settled into a period of"


def _period(lines: list[str]) -> list[str]:
    return [w for w in lines if w.startswith(PERIOD)]


def _line(gaps: list[int]) -> str:
    share = (max(gaps) - min(gaps)) / (sum(gaps) / len(gaps))
    return (f"the stream settled into a period of 2 frames whose gaps differ by {share:.0%} of cycles.throughput "
            f"({gaps[0]} and {gaps[1]} cycles; timing.frame_times): the 2 images in flight take turns, and "
            "cycles.throughput and fps are the mean over the period, which a small change of the work (a few pixels "
            "more, another render.spp) can move by more than the work changed, even the other way (the turns "
            "change); treat differences between runs smaller than that as noise, or compare with "
            "arch.images_in_flight = 1 (each frame alone, no turns)")


def test_a_period_whose_gaps_differ_is_warned_of(tmp_path, cache):
    results = tlm.run(tlm.load_config("cornell", RACE), tmp_path / "r", outputs="images")
    est = results["timing"]["throughput_estimate"]
    assert est["settled"] is True and est["period"] == 2
    done = sorted(f["done"] for f in results["timing"]["frame_times"])
    a = est["window"][0]
    gaps = [done[a + 1] - done[a], done[a + 2] - done[a + 1]]
    assert (max(gaps) - min(gaps)) / (sum(gaps) / 2) >= 0.2  # (33% here)
    assert _period(results["warnings"]) == [_line(gaps)]
    assert json.loads((tmp_path / "r" / "results.json").read_text())["warnings"] == results["warnings"]


def test_a_static_period_from_the_warm_up_and_one_image(cache):
    res = tlm.render_image(tlm.load_config("cornell", RACE))
    settled = tlm.simulate(res, {"trace": False})
    # (9 frames asked: their steady gaps repeat with a period of 2 from the first, no run-on, no 'period' key)
    nine = tlm.simulate(res, {"frames": 9, "trace": False})
    assert nine.throughput_estimate.get("period") is None and nine.throughput_estimate.get("settled") is None
    assert period_gaps(nine) == period_gaps(settled) and len(period_gaps(nine)) == 2
    assert _period(stream_warnings(nine, res.cfg)) == [_line(period_gaps(nine))]
    assert period_warnings(nine, 1) == []  # (one image in flight: no turns to take)
    one = tlm.simulate(res, {"images_in_flight": 1, "trace": False})
    assert len(period_gaps(one)) == 1 and _period(stream_warnings(one, replace(res.cfg, arch=replace(
        res.cfg.arch, images_in_flight=1)))) == []


def _timing(gaps: list[int], periods: int = 6, settled: bool | None = True) -> SimpleNamespace:
    done = [1000]
    for g in gaps * periods:
        done.append(done[-1] + g)
    est = {"steady": True, "window": [1, len(done)], "settled": settled,  # (after the warm-up completion 0)
           **({"period": len(gaps)} if settled else {})}
    return SimpleNamespace(throughput_estimate=est, frames=[{"done": d} for d in [0, *done]])


def test_the_share_from_which_it_warns():
    assert PERIOD_WARNING == 0.10
    assert len(period_warnings(_timing([1050, 950]), 2)) == 1  # (100 of a mean of 1000: 10%)
    assert period_warnings(_timing([1049, 951]), 2) == []  # (9.8%)
    assert period_warnings(_timing([1000]), 2) == []  # (a period of one frame)
    assert "from 900 to 1100 cycles" in period_warnings(_timing([900, 1000, 1000, 1000, 1100]), 2)[0]
    assert period_warnings(_timing([1200, 800], settled=False), 2) == []  # (not settled: said otherwise)
    assert period_warnings(_timing([1200, 800], periods=1, settled=None), 2) == []  # (one period: no repeat shown)
