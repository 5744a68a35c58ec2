"""The report names scenes and sweep points so that one name means one thing.

* Two scene files may say the same ``name:`` (the built-in ``room`` and ``thesis/room``, the
  thesis's Table II scene with one light, both say ``name: room``): every section names a
  scene by its file (its path under ``scenes/`` without ``.yaml``), wherever the run was made.
* A sweep factor that is a category (a scene) is drawn as points, not joined by a line.
* The eq. 5.1 breakdown of a sweep point says which point (its factor values).
* A path the runs recorded on the machine that ran them (a bad-input case's error) is shown by
  its place in the repository or the study's folder, not as that machine's temporary path.

The folders here are made by hand: the files and keys the report reads, at 16x16.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import yaml
from matplotlib.collections import PolyCollection

from tlm.experiments.thesis import METRICS, THESIS
from tlm.report import cycles as cycles_mod
from tlm.report import sweeps as sweeps_mod
from tlm.report.collect import Inputs, Run, Study, Sweep, read
from tlm.report.extreme import extreme_section
from tlm.report.peers import peers_section
from tlm.report.scaling import scaling_section
from tlm.report.summary import summary_section
from tlm.report.tables import tables_section

ELSEWHERE = "/tmp/someone-elses-checkout"  # where the runs were made: not on this machine
PMS = ("vertex", "traversal", "intersection", "fragment")


def _timing(cycles: int = 1000) -> dict:
    unit = {"T_norm": cycles, "T_ms": 0, "T_ps": 0, "idle": 0, "elapsed": cycles, "stall": {},
            "fractions": {"busy": 1.0}}
    return {"frames": 1, "units": {f"pipe0.{pm}": dict(unit) for pm in PMS}}


def _results(name: str, file: str, mode: str = "rcast", fps: float = 10.0, factors: dict | None = None) -> dict:
    cycles = {"vertex": 10, "traversal": 1000, "intersection": 900, "fragment": 100, "throughput": 1000,
              "latency": 2000}
    out = {"scene": {"name": name, "source": f"{ELSEWHERE}/scenes/{file}.yaml", "resolution": [16, 16],
                     "triangles": 100},
           "mode": mode, "fps": fps, "cycles": cycles, "timing": _timing()}
    if factors:
        out["factors"] = factors
    return out


def _write_run(folder: Path, results: dict, config: dict) -> None:
    folder.mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps(results))
    (folder / "config.resolved.yaml").write_text(yaml.safe_dump(config))


def thesis_folder(root: Path) -> Path:
    """A thesis study of one cell, thesis/room in RCast, made elsewhere."""
    root.mkdir()
    _write_run(root / "room" / "rcast", _results("room", "thesis/room", fps=5.0),
               {"scene": "thesis/room", "mode": "rcast"})
    with open(root / "thesis_comparison.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["scene", "mode", "metric", "thesis", "ours", "rel_error", "calibrated"])
        for m in METRICS:
            t = THESIS["room"][m][0]
            w.writerow(["room", "rcast", m, t, 1.1 * t, 0.1, False])
    return root


def sweep_folder(root: Path, scenes: dict[str, tuple[str, str]], levels: list[int]) -> Path:
    """A sweep over ``scene`` (its config's name -> (name in the file, built-in file)) and
    ``bsp.levels``, made elsewhere; the frame rate falls with the level."""
    root.mkdir()
    (root / "sweep.yaml").write_text(yaml.safe_dump({"sweep": "s.yaml", "description": "16x16 RCast",
                                                     "grid": {"scene": list(scenes), "bsp.levels": levels}}))
    rows = []
    for i, (ref, lv) in enumerate((r, lv) for r in scenes for lv in levels):
        name, file = scenes[ref]
        fps = 20.0 - lv - list(scenes).index(ref)
        h = f"h{i:03d}"
        rows.append({"point": i, "hash": h, "status": "ok", "scene": ref, "bsp.levels": lv, "mode": "rcast",
                     "fps": fps, "cycles.throughput": 6e8 / fps, "cycles.traversal": 1000 + lv,
                     "cycles.intersection": 900})
        _write_run(root / "points" / h, _results(name, file, fps=fps, factors={"scene": ref, "bsp.levels": lv}),
                   {"scene": ref, "mode": "rcast", "bsp": {"levels": lv}})
    (root / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return root


def test_two_scenes_named_room_in_their_files_get_two_names_in_the_report(tmp_path):
    """The thesis's room (scenes/thesis/room.yaml) and the built-in room (scenes/room.yaml)
    both say ``name: room``: the report called both "room". Each is named by its file now."""
    inputs = read([thesis_folder(tmp_path / "thesis"), sweep_folder(tmp_path / "bsp", {"room": ("room", "room")},
                                                                     [3, 4])])
    cell = next(r for r in inputs.runs if r.kind == "thesis")
    assert cell.label == "thesis/room/rcast"  # (was "room/rcast", as if it were the built-in room)
    # Table II names our scene by its file
    assert "Ours: thesis study thesis, scene thesis/room" in tables_section(inputs, tmp_path).html
    # the peers' rows: the study's thesis/room and the sweep's room are two rows, each named by its file
    peers = peers_section(inputs, tmp_path).html
    assert "thesis/room scene, 16×16 pixels" in peers and "<td>room scene, 16×16 pixels" in peers
    # the first screen's frame rate names the thesis's room by its file, and so does why it has no median
    lead = summary_section(inputs, tmp_path).lead
    assert "13.8 FPS (thesis/room RCast)" in lead
    assert "not comparable with the thesis: thesis/room is 16×16 pixels" in lead
    # the image sets: the thesis's Fig. 16 is thesis/room; the built-in room says it is not that one
    from tlm.report.images import scene_title

    point = next(r for r in inputs.runs if r.kind == "sweep-point")
    assert scene_title(cell) == "thesis/room: Room scene (Fig. 16)"
    assert scene_title(point) == "room, not the thesis's Room scene (Fig. 16)"
    # and the report says why: both files say name: room
    from tlm.report import scenes_note

    assert "&#x27;room&#x27; is the name in the files of room and thesis/room" in scenes_note(inputs)


def test_the_scaling_fit_of_the_thesis_ring_is_named_by_its_file(tmp_path):
    """``tlm scaling`` labels a scene by its name ("ring") where its sweeps hold one file of
    that name; the report names it by the file it recorded (scenes/thesis/ring.yaml of the
    checkout that ran it): thesis/ring, not the built-in ring's name."""
    folder = tmp_path / "eq52"
    folder.mkdir()
    fits, rows = [], []
    for sched in ("static", "dynamic"):
        for target in ("latency", "throughput"):
            fits.append({"scene": "ring", "scene_file": f"{ELSEWHERE}/scenes/thesis/ring.yaml", "mode": "rcast",
                         "scheduler": sched, "target": target, "A": 1.0, "B": 1.0, "max_abs_rel_error": 0.01,
                         "pipelines": [1, 2]})
            for n in (1, 2):
                rows.append({"scene": "ring", "mode": "rcast", "scheduler": sched, "target": target,
                             "pipelines": n, "simulated": 1000 / n, "analytical": 1000 / n, "speedup": n})
    (folder / "eq52.json").write_text(json.dumps({"fits": fits}))
    with open(folder / "eq52.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    inputs = read([folder])
    sec = scaling_section(inputs, tmp_path)
    assert [f.title for f in sec.figures] == ["thesis/ring: scaling from eq52"]
    assert sec.figures[0].file == "scaling_eq52_ring.png"  # (the file keeps its name)
    text = " ".join(summary_section(inputs, tmp_path).lead.split())
    assert "thesis/ring 2.0x at N = 2" in text


def _capture(monkeypatch, module) -> list:
    """The matplotlib figures ``module`` saves, as it saves them."""
    figs = []
    real = module.save

    def save(fig, out, name, title, caption=""):
        figs.append(fig)
        return real(fig, out, name, title, caption)

    monkeypatch.setattr(module, "save", save)
    return figs


def _joined(ax) -> list:
    """The lines of ``ax`` that join two or more points."""
    return [ln for ln in ax.get_lines() if len(ln.get_xdata()) > 1 and ln.get_linestyle() not in ("None", "none", "")]


def test_a_scene_factor_is_drawn_as_points_not_a_line(tmp_path, monkeypatch):
    """FPS against the sweep's scene: categories, with no order or distance between them,
    were joined by a line (and, over more than 8 combinations, a band) across them."""
    scenes = {"cornell": ("cornell", "cornell"), "ring": ("ring", "ring"), "room": ("room", "room")}
    few = read([sweep_folder(tmp_path / "few", scenes, [3, 4])]).sweeps[0]
    many = read([sweep_folder(tmp_path / "many", scenes, list(range(3, 13)))]).sweeps[0]
    figs = _capture(monkeypatch, sweeps_mod)
    for sw in (few, many):
        rec = sweeps_mod.factor_figure(sw, "scene", tmp_path, [])
        ax = figs[-1].axes[0]
        assert not _joined(ax), f"{sw.path.name}: a line joins the scenes"
        assert not [c for c in ax.collections if isinstance(c, PolyCollection)], f"{sw.path.name}: a band"
        assert [t.get_text() for t in ax.get_xticklabels()] == ["cornell", "ring", "room"]
        assert "scene is a category" in rec.caption
        points = [ln for ln in ax.get_lines() if ln.get_marker() not in ("None", "none", "")]
        assert points, f"{sw.path.name}: no points"
    sweeps_mod.factor_figure(few, "bsp.levels", tmp_path, [])  # (a numeric factor keeps its lines)
    assert len(_joined(figs[-1].axes[0])) == 3


def test_the_breakdown_of_a_sweep_point_names_its_point(tmp_path, monkeypatch):
    """The eq. 5.1 breakdown of design_space #0 said "design_space #0" and no factor value."""
    run = Run(tmp_path / "p0", "design_space #0", "sweep-point", _results("cornell", "cornell"),
              {"scene": "cornell", "mode": "rcast"},
              {"bsp.levels": 5, "cache.pairs": 1, "arch.fifo_depth": 16, "arch.page_miss_cycles": 0})
    figs = _capture(monkeypatch, cycles_mod)
    rec = cycles_mod.breakdown_figure(run, tmp_path, "b.png")
    point = "bsp.levels = 5, cache.pairs = 1, arch.fifo_depth = 16, arch.page_miss_cycles = 0"
    assert point in rec.title and point in rec.caption
    assert point in figs[-1].axes[0].get_title()
    inputs = Inputs([], runs=[run], sweeps=[Sweep(tmp_path, {}, [], [run])])
    sec = cycles_mod.cycles_section(inputs, tmp_path)
    assert sec.figures and point in sec.figures[0].title


def test_a_recorded_path_of_the_machine_that_ran_it_is_not_shown(tmp_path):
    """A bad-input case's error names the scene file as it was where the study ran (a
    temporary checkout): the report shows the built-in file by its place in the repository,
    and a file of the study's folder relative to it."""
    folder = tmp_path / "extreme"
    rows = [{"case": "bad-scale-zero", "category": "bad input", "expect": "refused", "passed": True, "seconds": 0.1,
             "measured": f"input error: {ELSEWHERE}/scenes/extreme/bad_scale_zero.yaml: transform.scale: 0.0 "
                         "must be > 0.0"},
            {"case": "own-file", "category": "bad input", "expect": "refused", "passed": True, "seconds": 0.1,
             "measured": f"input error: {folder.resolve()}/cases/own-file/scene.yaml: extends itself"}]
    html = extreme_section(Inputs([], studies=[Study("extreme", folder, rows)]), tmp_path).html
    assert ELSEWHERE not in html and f"{folder.resolve()}/cases/own-file" not in html
    assert "input error: scenes/extreme/bad_scale_zero.yaml: transform.scale: 0.0 must be &gt; 0.0" in html
    assert "input error: cases/own-file/scene.yaml: extends itself" in html


def test_a_recorded_built_in_scene_path_is_shown_by_its_place_in_the_repository():
    from tlm.report.names import shown_paths
    from tlm.scenes.loader import scenes_dir

    bad = scenes_dir() / "extreme" / "bad_scale_zero.yaml"
    said = f"{bad}: geometry[0].transform.scale: 0 is not > 0."
    assert shown_paths(said) == "scenes/extreme/bad_scale_zero.yaml: geometry[0].transform.scale: 0 is not > 0."
