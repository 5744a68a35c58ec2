"""A report over N pipelines and the scaling sweeps (h234): the bottleneck is the busiest pipeline's PM (as
``cycles.<pm>`` and ``slowest_pm`` are the most over the pipelines); ``tlm plots --only`` with a scaling sweep
and without the eq52 folder, or with eq52 and some scaling folders missing, reports what ran; a factor that keeps
the frame rate but moves a PM's cycles does not "change nothing"; the summary sees the scaling sweeps §3 draws;
one short name for a scene file in ``tlm scaling``; the sweep's own ``tlm reference`` command in the summary."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tlm.errors import InputError
from tlm.experiments.scaling import groups, scene_name
from tlm.report.collect import Inputs, Run, Sweep
from tlm.report.regenerate import SCALING, regenerate
from tlm.report.summary import summary_section, sweep_findings
from tlm.report.summary_points import PMS, bottleneck_of_points, points_error


def _units(busy: dict[str, float]) -> dict:
    return {name: {"fractions": {"busy": b}} for name, b in busy.items()}


# the probe's Cornell refract 96x96, 4 pipelines: pipe0's PMs (TVert the busiest of them), pipe2's Intersection
# PM busy 87% (cycles.intersection and slowest_pm are its)
N4 = {"pipe0.vertex": 0.296574, "pipe0.traversal": 0.202707, "pipe0.intersection": 0.257564,
      "pipe0.fragment": 0.036188, "pipe1.traversal": 0.208202, "pipe1.intersection": 0.203906,
      "pipe1.fragment": 0.036552, "pipe2.traversal": 0.500565, "pipe2.intersection": 0.872838,
      "pipe2.fragment": 0.058691}


def _n4_run(kind: str = "run", path: str = "runs/n4") -> Run:
    return Run(Path(path), "n4", kind, {"scene": {"name": "cornell"}, "mode": "refract", "fps": 43.9,
                                        "timing": {"units": _units(N4),
                                                   "throughput_estimate": {"slowest_pm": "intersection"}}}, {})


def test_the_bottleneck_is_the_busiest_pipelines_pm(tmp_path):
    sec = summary_section(Inputs([], runs=[_n4_run()]), tmp_path)
    assert "the Tisct PM is the bottleneck in the only scene-mode, busy 87% of the time" in sec.lead
    assert "TVert PM is the bottleneck" not in sec.lead
    points = bottleneck_of_points(Inputs([], runs=[_n4_run("sweep-point")]))
    assert "Tisct in 1, busy 87%" in points

    from tlm.report.summary_points import busy_shares

    assert busy_shares(_n4_run().results) == {"vertex": 0.296574, "traversal": 0.500565,
                                              "intersection": 0.872838, "fragment": 0.058691}


def test_a_pipeline_without_a_number_is_no_busy_share():
    from tlm.report.summary_points import busy_shares

    assert busy_shares({"timing": {"units": _units({**N4, "pipe3.traversal": None})}}) is None
    assert busy_shares({"timing": {"units": _units({k: v for k, v in N4.items() if "vertex" not in k})}}) is None


# ---------------------------------------------------------------- tlm plots --only with the scaling sweeps

def _scaling_rows() -> list[dict]:
    return [{"point": i, "hash": f"h{i}", "status": "ok", "arch.scheduler": s, "arch.pipelines": n,
             "scene": "cornell", "mode": "rcast", "cycles.throughput": 1000 // n + (s == "static") * 50,
             "fps": 1e8 / (1000 // n + (s == "static") * 50),
             **{f"idle.{pm}": round(0.1 * k + 0.01 * n, 6) for k, pm in enumerate(PMS)}}
            for i, (s, n) in enumerate((s, n) for s in ("static", "dynamic") for n in (1, 2, 4))]


SPEC = {"sweep": "x.yaml", "grid": {"arch.scheduler": ["static", "dynamic"], "arch.pipelines": [1, 2, 4]}}


def _write_sweep(folder: Path) -> None:
    """A sweep folder of rows alone (sweep.yaml, sweep.jsonl), as a stub step writes it."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "sweep.yaml").write_text(yaml.safe_dump(SPEC))
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in _scaling_rows()))


def _stub(runs: Path, called: list):
    def run_command(argv: list[str]) -> int:
        called.append(argv)
        if argv[0] == "sweep":
            _write_sweep(Path(argv[argv.index("--out") + 1]))
        return 0
    return run_command


def test_only_a_scaling_sweep_is_reported_as_a_sweep(tmp_path):
    """No eq52 folder: the scaling sweep that ran is the report's input (the old report found no folder)."""
    (tmp_path / "configs").mkdir()
    called: list = []
    page = regenerate(tmp_path / "configs", tmp_path / "runs", tmp_path / "plots", ["scaling_cornell"],
                      run_command=_stub(tmp_path / "runs", called), say=lambda _: None)
    assert [a[0] for a in called] == ["sweep"]
    text = page.read_text(encoding="utf-8")
    assert "<b>Does it scale:</b> cornell" in text
    assert "no scaling to show" not in text


def test_eq52_fits_the_scaling_folders_there_and_says_which_are_missing(tmp_path):
    (tmp_path / "configs").mkdir()
    runs, called, said = tmp_path / "runs", [], []
    regenerate(tmp_path / "configs", runs, tmp_path / "plots", ["scaling_cornell", "eq52"],
               run_command=_stub(runs, called), say=said.append)
    eq52 = next(a for a in called if a[0] == "scaling")
    assert eq52[1:eq52.index("--out")] == [str(runs / "scaling_cornell")]
    assert any("eq52: fits scaling_cornell alone: no folder scaling_ring, scaling_room" in s for s in said)


def test_eq52_with_no_scaling_folder_is_refused_before_any_step(tmp_path):
    (tmp_path / "configs").mkdir()
    called: list = []
    with pytest.raises(InputError, match="add scaling_ring or scaling_room or scaling_cornell to --only"):
        regenerate(tmp_path / "configs", tmp_path / "runs", tmp_path / "plots", ["thesis", "eq52"],
                   run_command=_stub(tmp_path / "runs", called), say=lambda _: None)
    assert called == []
    assert len(SCALING) == 3


def test_the_summary_says_the_scaling_sweeps_section_3_draws(tmp_path):
    sw = Sweep(tmp_path / "scaling_cornell", SPEC, _scaling_rows(), [])
    sec = summary_section(Inputs([], scaling_sweeps=[sw]), tmp_path)
    assert "no scaling to show" not in sec.lead
    assert "<b>Does it scale:</b> cornell" in sec.lead and "3.5x at N = 4" in sec.lead  # (1050 / 300 static)


# ---------------------------------------------------------------- "change nothing" only where no cycle moves

def test_a_factor_that_keeps_the_frame_rate_but_moves_cycles_does_not_change_nothing():
    rows = []
    for i, (n, words) in enumerate((n, w) for n in (1, 4) for w in (64, 1024)):
        rows.append({"point": i, "hash": f"h{i}", "status": "ok", "arch.pipelines": n, "cache.block_words": words,
                     "arch.page_miss_cycles": 0, "fps": 414.4, "cycles.vertex": 1447829,
                     "cycles.traversal": 436535 if words == 64 else 480189, "cycles.intersection": 507241,
                     "cycles.fragment": 75844, "cycles.throughput": 1447829, "cycles.latency": 2895658})
    spec = {"grid": {"arch.pipelines": [1, 4], "cache.block_words": [64, 1024]}}
    (text,) = sweep_findings(Inputs([], sweeps=[Sweep(Path("sw"), spec, rows, [])]))
    assert text.startswith("<b>Sweep sw</b> (4 of 4 points ok): no factor changes the frame rate: every point runs "
                           "at 414 FPS; cache.block_words keeps the frame rate")
    slower = [{**r, "point": r["point"] + 4, "hash": f"s{r['point']}", "arch.page_miss_cycles": 48, "fps": 400.0,
               "cycles.throughput": 1500000} for r in rows]
    spec = {"grid": {**spec["grid"], "arch.page_miss_cycles": [0, 48]}}
    (text,) = sweep_findings(Inputs([], sweeps=[Sweep(Path("sw"), spec, rows + slower, [])]))
    assert "arch.page_miss_cycles moves the frame rate most" in text
    assert "arch.pipelines changes nothing between points that differ only in it" in text
    assert ("cache.block_words keeps the frame rate between points that differ only in it, but moves TTrav (by up "
            "to 10.0%)") in text
    assert "cache.block_words change" not in text and "cache.block_words changes nothing" not in text


# ---------------------------------------------------------------- one name for a scene file in tlm scaling

def test_a_scene_file_has_one_short_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    mine = tmp_path / "work" / "myroom.yaml"
    rec = {"scene": "myroom", "scene_file": str(mine), "scene_ref": str(mine)}
    assert scene_name(rec) == "work/myroom.yaml"  # (under the working folder: from it, as the report names it)
    monkeypatch.chdir(tmp_path / "..")
    assert scene_name(rec) == f"{tmp_path.name}/work/myroom.yaml"
    other = {"scene": "myroom", "scene_file": "/elsewhere/b/myroom.yaml", "scene_ref": "/elsewhere/b/myroom.yaml"}
    monkeypatch.chdir(tmp_path)
    assert scene_name(other) == "myroom.yaml"  # (not under the working folder: its file's name)
    recs = [{**rec, "scene_file": f, "scene_ref": f, "scene_id": i, "mode": "rcast", "scheduler": "static"}
            for f, i in (("/x/a/myroom.yaml", "id-a"), ("/x/b/myroom.yaml", "id-b"))]
    names = sorted(k[0] for k in groups(recs))
    assert names == ["/x/a/myroom.yaml", "/x/b/myroom.yaml"]  # (two files, one name: told apart by their paths)


# ---------------------------------------------------------------- the sweep's tlm reference command

def test_the_reference_command_is_the_sweeps(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "room.yaml").write_text("scene: myroom.yaml\nmode: pmap\n")
    out = tmp_path / "runs" / "sw"
    run = Run(out / "points" / "h0", "sw #0", "sweep-point",
              {"scene": {"name": "myroom"}, "mode": "pmap", "error": {"available": False, "reference": "ref0"}},
              {"scene": str(tmp_path / "myroom.yaml"), "mode": "pmap", "resolution": [32, 32]},
              factors={"arch.pipelines": 1})
    rows = [{"point": 0, "hash": "h0", "status": "ok", "arch.pipelines": 1}]
    spec = {"sweep": "sw.yaml", "base_file": "room.yaml", "set": {}, "grid": {"arch.pipelines": [1]}}
    said = points_error(Inputs([], runs=[run], sweeps=[Sweep(out, spec, rows, [run])]))
    assert "<code>tlm reference room.yaml</code>" in said and "config.resolved.yaml" not in said
    spec = {**spec, "set": {"resolution": [32, 32]}}
    said = points_error(Inputs([], runs=[run], sweeps=[Sweep(out, spec, rows, [run])]))
    assert "tlm reference room.yaml --set &#x27;resolution=[32, 32]&#x27;" in said
    said = points_error(Inputs([], runs=[run], sweeps=[Sweep(out, {**spec, "base_file": None}, rows, [run])]))
    assert f"tlm reference {out / 'points' / 'h0' / 'config.resolved.yaml'}" in said  # (a mapping: the point's)
