"""`tlm report A B` of two runs of one scene-mode as a comparison of two designs (h530, h524's findings 1-4):
every run a bar of the frame-rate figure, B/A of the throughput cycles, frame rate and each PM's cycles against
the first run given, the baseline's bottleneck's busy share in both, what differs (config keys, seed, code), the
1% tie rule, a row per run in the bottleneck figure, the differences in §9, and one y scale for their breakdowns."""

from __future__ import annotations

import copy
import html
from pathlib import Path

from tlm.report.collect import Inputs, Run
from tlm.report.cycles import cycles_section
from tlm.report.provenance import provenance_section
from tlm.report.summary import summary_section

PMS = ("vertex", "traversal", "intersection", "fragment")
CONFIG = {"scene": "cornell", "mode": "rcast", "seed": 0, "resolution": [64, 64], "render": {"spp": 4},
          "arch": {"pipelines": 4, "packet_size": 256}}
# (h524's cA_p4 and cB_p8: Cornell rcast 64x64 at 4 and 8 pipelines, their results.json's cycles and busy shares)
A_CYCLES = {"vertex": 1448093, "traversal": 3891105, "intersection": 6428823, "fragment": 402864,
            "throughput": 7858395}
B_CYCLES = {"vertex": 1448093, "traversal": 2549156, "intersection": 4344030, "fragment": 238621,
            "throughput": 5671548}
CLOCK = 600e6


def run(name: str, cycles: dict, busy: dict, pipelines: int = 4, seed: int = 0, code: str = "7ef00ef36552ec68",
        **config) -> Run:
    """A ``tlm run`` of cornell rcast: its results' cycles, frame rate (the clock over the throughput), each PM's
    busy share and eq. 5.1 terms, and its resolved config (``config``'s keys over :data:`CONFIG`'s)."""
    units = {}
    for p in range(pipelines):
        for pm in PMS:
            elapsed = 5 * cycles["throughput"]
            units[f"pipe{p}.{pm}"] = {"T_norm": int(busy[pm] * elapsed), "T_ms": 0, "T_ps": 0, "T_ds": 0,
                                      "idle": int((1 - busy[pm]) * elapsed), "stall": {}, "elapsed": elapsed,
                                      "fractions": {"busy": busy[pm], "idle": 1 - busy[pm], "stalled": 0.0}}
    results = {"scene": {"name": "cornell"}, "mode": "rcast", "seed": seed, "code_fingerprint": code,
               "cycles": dict(cycles), "fps": CLOCK / cycles["throughput"],
               "pipelines": [{} for _ in range(pipelines)],
               "timing": {"frames": 5, "units": units}, "host_seconds": {"simulate": 0.3, "one_off": 16.0}}
    conf = copy.deepcopy(CONFIG)
    conf["seed"] = seed
    conf["arch"]["pipelines"] = pipelines
    for k, v in config.items():
        *head, last = k.split("__")
        at = conf
        for h in head:
            at = at.setdefault(h, {})
        at[last] = v
    return Run(Path(f"runs/{name}"), f"{name}: cornell/rcast", "run", results, conf)


A_BUSY = {"vertex": 0.18, "traversal": 0.49, "intersection": 0.80, "fragment": 0.05}
B_BUSY = {"vertex": 0.26, "traversal": 0.45, "intersection": 0.72, "fragment": 0.04}


def test_two_runs_of_a_scene_mode_are_each_drawn_and_said_as_b_over_a(tmp_path):
    a, b = run("cA", A_CYCLES, A_BUSY), run("cB", B_CYCLES, B_BUSY, pipelines=8)
    sec = summary_section(Inputs([], runs=[a, b]), tmp_path)
    lead = html.unescape(sec.lead)
    (fps,) = [f for f in sec.figures if f.file == "summary_fps.png"]
    assert "a bar per run, in the order given" in fps.caption and "not drawn" not in fps.caption
    assert "not in the figure" not in lead
    assert "from 76.4 FPS (cA RCast) to 106 FPS (cB RCast)." in lead
    assert "each against the first given, cA (the baseline, A" in lead
    assert ("<b>cB against cA</b> (B/A): throughput cycles 0.722x (7,858,395 → 5,671,548); frame rate 1.39x "
            "(76.4 → 106 FPS); per PM: TVert 1.000x, TTrav 0.655x, Tisct 0.676x, TFrag 0.592x; "
            "A's bottleneck, Tisct, busy 80% → 72% (-8 points). What differs: arch.pipelines 4 → 8.") in lead
    assert "Simulated cycles are deterministic" in lead and "Host seconds are the machine's" in lead
    # (the bottleneck: a row per run, each said, not the first run's alone)
    assert "the Tisct PM is the bottleneck in 2 of 2 runs, busy 72–80% of the time." in lead
    # (the other order: the other baseline, the ratio turned over)
    back = summary_section(Inputs([], runs=[run("cB", B_CYCLES, B_BUSY, pipelines=8), run("cA", A_CYCLES, A_BUSY)]),
                           tmp_path)
    assert "<b>cA against cB</b> (B/A): throughput cycles 1.39x" in html.unescape(back.lead)


def test_runs_that_differ_in_more_than_the_pipelines_say_every_difference(tmp_path):
    a = run("cA", A_CYCLES, A_BUSY)
    d = run("cD", {k: v // 2 for k, v in A_CYCLES.items()}, B_BUSY, pipelines=8, seed=5, resolution=[80, 80],
            render__spp=2, code="0b4cd0278b5b0f82")
    lead = html.unescape(summary_section(Inputs([], runs=[a, d]), tmp_path).lead)
    assert "8 pipelines" not in lead  # (not the pipelines' alone: h524's "146 FPS (8 pipelines)")
    assert ("What differs: seed 0 → 5; resolution [64, 64] → [80, 80]; render.spp 4 → 2; arch.pipelines 4 → 8; "
            "code 7ef00ef36552ec68 → 0b4cd0278b5b0f82 (5 differences: the ratios are their joint effect, no one of "
            "them alone).") in lead
    prov = provenance_section(Inputs([], runs=[a, d]), tmp_path)
    assert ("What differs from cA: cornell/rcast (the first given; resolved config, seed, code, scene): cD: seed "
            "0 → 5; resolution [64, 64] → [80, 80]; render.spp 4 → 2; arch.pipelines 4 → 8; code") in (
        html.unescape(prov.html))


def test_identical_and_seed_only_runs_tie_within_one_percent(tmp_path):
    a, same = run("cA", A_CYCLES, A_BUSY), run("cA2", A_CYCLES, A_BUSY)
    seed = run("cF", {**A_CYCLES, "throughput": 7878395, "intersection": 6448823}, A_BUSY, seed=7)
    apart = run("cG", {**A_CYCLES, "throughput": 8058395}, A_BUSY, arch__packet_size=64)
    lead = html.unescape(summary_section(Inputs([], runs=[a, same, seed, apart]), tmp_path).lead)
    assert ("throughput cycles 1.000x (7,858,395 → 7,858,395); frame rate 1.000x (76.4 → 76.4 FPS); per PM: "
            "TVert 1.000x, TTrav 1.000x, Tisct 1.000x, TFrag 1.000x; A's bottleneck, Tisct, busy 80% → 80% "
            "(within a point); identical cycles: a tie. What differs: nothing (one config, seed, code and scene): the "
            "same run twice.") in lead
    assert "throughput cycles 1.003x (7,858,395 → 7,878,395)" in lead
    assert "within 1% in throughput cycles: a tie. What differs: seed 0 → 7." in lead
    # (2.5% apart: no tie)
    (g,) = [line for line in lead.split("<br>") if line.startswith("<b>cG against cA</b>")]
    assert "1.03x" in g and "tie" not in g and "arch.packet_size 256 → 64" in g


def test_the_breakdowns_of_runs_compared_share_one_scale(tmp_path):
    a, b = run("cA", A_CYCLES, A_BUSY), run("cB", B_CYCLES, B_BUSY, pipelines=8)
    sec = cycles_section(Inputs([], runs=[a, b]), tmp_path)
    shown = [f for f in sec.figures if "breakdown" in f.file]
    assert len(shown) == 2 and all("On one y scale with the other runs of its scene-mode" in f.caption
                                   for f in shown)
    alone = cycles_section(Inputs([], runs=[a]), tmp_path)
    assert not any("On one y scale" in f.caption for f in alone.figures)
