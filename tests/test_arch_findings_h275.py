"""An architecture researcher's findings (h275), mended.

1. docs/architecture.md gave the image side at which the throughput leaves T_vert0 as about 48x48 pixels per
   pipeline "for both schedulers" (96x96 at N = 4, already 18% / 30% above T_vert0): it now gives what
   benchmarks/vertex_crossover.py measures per N and scheduler, checked here at N = 4.
2. A sweep among a report's inputs that a scaling study among them was fitted from was fitted again: every
   scaling result shown twice (the summary's "thesis/ring (eq52) 5.3x ..., thesis/ring (pipes) 5.3x", two §3
   figures per scene); now it is shown through the study's fit alone, as ``tlm plots`` shows it.
3. ``tlm scaling`` of a sweep whose points all have one N advised "fit them from separate sweeps": it now says
   the sweep has one value of N and eq. 5.2 needs a sweep over arch.pipelines (exit 2 still).
4. "What limits it" gave the busiest pipeline's busy share as "busy": it says so, and that sweep.csv's busy
   columns are means over the pipelines.
5. docs/architecture.md said TThru and the latency grow with every added memory cycle; ``memory: copy`` has a
   lower TThru than ``swap`` in places: the docs' figures of it are checked here.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.scaling import fit_group
from tlm.report.collect import Run, read
from tlm.report.scaling import fit_sources, scaling_section
from tlm.report.summary import summary_section
from tlm.report.summary_points import bottleneck_of_points

ROOT = Path(__file__).resolve().parents[1]
BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False}}


def _sweep(root: Path, name: str, spec: dict) -> Path:
    (root / f"{name}.yaml").write_text(yaml.safe_dump({"base": BASE, **spec}, sort_keys=False))
    assert main(["sweep", str(root / f"{name}.yaml"), "--out", str(root / name), "--jobs", "1", "--no-progress",
                 "--no-report"]) == 0
    return root / name


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """Tiny real sweeps of cornell at 16x16: N in 1, 2 (and its eq. 5.2 fit); N = 2 over the page-miss cost."""
    root = tmp_path_factory.mktemp("h275")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        _sweep(root, "pipes", {"grid": {"arch.pipelines": [1, 2]}})
        _sweep(root, "miss", {"set": {"arch.pipelines": 2}, "grid": {"arch.page_miss_cycles": [0, 12]}})
        assert main(["scaling", str(root / "pipes"), "--out", str(root / "eq52"), "--no-report"]) == 0
    return root


def _words(html: str) -> str:
    return " ".join(re.sub(r"<[^>]+>", " ", html).split())


# ------------------------------------------------------------------ 2: a fitted sweep is shown through its fit


@pytest.mark.slow
def test_a_sweep_that_a_scaling_study_among_the_inputs_was_fitted_from_is_shown_once(folders, tmp_path):
    inputs = read([folders / "pipes", folders / "eq52"])
    notes: list[str] = []
    assert [label for _, label, *_ in fit_sources(inputs, notes)] == ["eq52"]
    assert "pipes: fitted by the scaling study eq52 among the inputs: shown through that fit, not fitted again" \
        in notes
    assert fit_sources(inputs, [], studies=False) == []  # (the summary's sweeps: none of its own)
    sec = scaling_section(inputs, tmp_path)
    files = sorted(f.file for f in sec.figures)
    assert [f for f in files if f.startswith("scaling_")] == ["scaling_eq52_cornell.png"], files
    assert [f for f in files if f.startswith("idle_")] == ["idle_pipes_cornell.png"], files  # (still drawn)
    lead = _words(summary_section(inputs, tmp_path).lead)
    said = re.search(r"Does it scale: (.*?) \(static tiles", lead)
    assert said and re.fullmatch(r"cornell \d+\.\dx at N = 2", said.group(1)), lead
    # the sweep alone is still fitted as before
    assert [label for _, label, *_ in fit_sources(read([folders / "pipes"]), [])] == ["pipes"]


# ------------------------------------------------------------------ 3: one value of N


def _point(n: int, miss: int) -> dict:
    return {"pipelines": n, "T_vert0": 100, "sum_max": 1000, "max_max": 500, "latency": 2000 + miss,
            "throughput": 1000 + miss, "settings": {"arch.pipelines": str(n), "arch.page_miss_cycles": str(miss)}}


def test_points_of_one_n_are_said_to_need_a_sweep_over_the_pipelines():
    with pytest.raises(InputError) as e:
        fit_group([_point(4, m) for m in (0, 12, 48)], "throughput", source="runs/mem")
    said = str(e.value)
    assert "all have N = 4 (they differ in arch.page_miss_cycles): the sweep has one value of N (4)" in said, said
    assert "eq. 5.2 needs a sweep over arch.pipelines" in said and "separate sweeps" not in said, said
    # (two values of N, one of them twice, keep their message)
    with pytest.raises(InputError, match="so fit them from separate sweeps"):
        fit_group([_point(1, 0), _point(2, 0), _point(2, 12)], "throughput")


@pytest.mark.slow
def test_tlm_scaling_of_a_sweep_of_one_n_exits_2_naming_it(folders, tmp_path, capsys):
    assert main(["scaling", str(folders / "miss"), "--out", str(tmp_path / "eq"), "--no-report"]) == 2
    err = capsys.readouterr().err
    assert "the sweep has one value of N (2), and eq. 5.2 needs a sweep over arch.pipelines" in err, err
    assert "separate sweeps" not in err and not (tmp_path / "eq").exists()


# ------------------------------------------------------------------ 4: the busiest pipeline's busy share

N2 = {"pipe0.vertex": 0.3, "pipe0.traversal": 0.2, "pipe0.intersection": 0.4, "pipe0.fragment": 0.05,
      "pipe1.traversal": 0.3, "pipe1.intersection": 0.9, "pipe1.fragment": 0.05}


def _run(kind: str) -> Run:
    return Run(Path(f"runs/{kind}"), "n2", kind, {"scene": {"name": "cornell"}, "mode": "rcast", "fps": 40.0,
                                                  "timing": {"units": {k: {"fractions": {"busy": v}}
                                                                       for k, v in N2.items()}}}, {})


def test_the_points_bottleneck_says_its_busy_share_is_the_busiest_pipelines():
    from tlm.report.collect import Inputs

    text = bottleneck_of_points(Inputs([], runs=[_run("sweep-point")]))
    assert "Tisct in 1, busy 90% of the time (busy: the PM's busiest pipeline's share of the time; " \
           "sweep.csv's busy.* columns are means over the pipelines)." in text, text


@pytest.mark.slow
def test_the_sweeps_bottlenecks_beside_a_run_say_the_busiest_pipeline(folders, tmp_path):
    inputs = read([folders / "pipes"])
    inputs.runs.append(_run("run"))
    lead = _words(summary_section(inputs, tmp_path).lead)
    at = lead.index("Across the sweeps' points (not drawn): pipes:")
    assert "Busy: the PM's busiest pipeline's share of the time; sweep.csv's busy.* columns are means over the " \
           "pipelines." in lead[at:], lead[at:]


# ------------------------------------------------------------------ 1 and 5: the docs' figures, measured


def _flat(path: str) -> str:
    return " ".join((ROOT / path).read_text().split())


def _throughput(side: int, **arch):
    import tlm

    cfg = tlm.load_config("cornell", {"mode": "rcast", "resolution": [side, side], "render.spp": 1,
                                      "render.light_samples": 1, "arch.trace": False,
                                      **{k: v for k, v in arch.items() if k.startswith("cache.")}})
    res = tlm.render_image(cfg)
    return lambda **sim: tlm.simulate(res, {**{k: v for k, v in arch.items() if not k.startswith("cache.")},
                                            **sim})


@pytest.mark.slow
def test_the_vertex_crossover_the_docs_give_at_four_pipelines_is_measured(tmp_path, monkeypatch):
    """docs/architecture.md: "N = 4: 80 -> 88 / 72 -> 80" (static / dynamic): the largest side at T_vert0 and
    the next (was: "about 48x48 pixels per pipeline, for both schedulers ... 96x96 for 4")."""
    text = _flat("docs/architecture.md")
    assert "N = 4: 80 -> 88 / 72 -> 80;" in text and "for both schedulers: 48x48" not in text
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    for sched, at, above in (("static", 80, 88), ("dynamic", 72, 80)):
        t_at = _throughput(at)(pipelines=4, scheduler=sched).cycles
        t_above = _throughput(above)(pipelines=4, scheduler=sched).cycles
        assert t_at["throughput"] == t_at["vertex"] == 1_448_093, (sched, t_at)
        assert t_above["throughput"] > t_above["vertex"] == 1_448_093, (sched, t_above)


@pytest.mark.slow
def test_copy_memory_can_lower_tthru_as_the_docs_say(tmp_path, monkeypatch):
    """docs/architecture.md: at 1 cache pair of 256-word blocks, misses of 12 cycles, `memory: copy` lowers
    TThru from 3,071,482 to 3,059,076 while every PM's cycles and the fifth frame's completion rise (was: "TThru and the
    latency grow with every added memory cycle")."""
    text = _flat("docs/architecture.md")
    assert "grow with every added memory cycle" not in text
    assert "TThru falls from 3,071,482 to 3,059,076" in text and "(16,844,470 -> 16,887,986" in text
    assert "(47,522,910 -> 47,427,061)" in text
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    sim = _throughput(128, **{"cache.pairs": 1, "cache.block_words": 256})
    swap, copy = (sim(pipelines=4, page_miss_cycles=12, memory=m) for m in ("swap", "copy"))
    assert (swap.cycles["throughput"], copy.cycles["throughput"]) == (3_071_482, 3_059_076)
    assert all(copy.cycles[pm] >= swap.cycles[pm] for pm in ("vertex", "traversal", "intersection", "fragment"))
    fifth, last = ([t.to_dict()["frame_times"][i]["done"] for t in (swap, copy)] for i in (4, -1))
    assert fifth == [16_844_470, 16_887_986]  # (the stream runs 15 frames: a period of two, which 5 cannot show)
    assert last == [47_522_910, 47_427_061]
