"""Report sections: Tables I-III, the image sets (Figs. 15-17) and the peers' frame rates."""

from __future__ import annotations

import copy
import csv
import json
import re
import shutil

import numpy as np
import pytest
import yaml
from matplotlib.image import imread

from tlm.config import MODES, config_from_dict
from tlm.experiments.run import run as run_experiment
from tlm.experiments.thesis import CALIBRATED, PM_METRICS, THESIS, run_thesis
from tlm.report.collect import Inputs, Run, read
from tlm.report.images import images_section, run_panels
from tlm.report.peers import MAX_OURS_ROWS, peers_section
from tlm.report.tables import (
    MARK_CALIBRATED,
    MARK_SLOW_OURS,
    MARK_SLOW_THESIS,
    MAX_TABLES_PER_SCENE,
    fmt,
    fmt_thesis,
    tables_section,
)

TINY = {"seed": 0, "resolution": [32, 32], "photons": {"count": 2000}, "render": {"light_samples": 1},
        "arch": {"frames": 1}}


def _study(tmp_path_factory, name: str, scenes: list[str]):
    root = tmp_path_factory.mktemp(name)
    spec = root / "thesis.yaml"
    spec.write_text(yaml.safe_dump({"base": TINY, "scenes": scenes, "modes": ["rcast", "pmap"]}))
    run_thesis(spec, root / "thesis")
    return root / "thesis"


def _refract_run(tmp_path_factory, folder: str, scene: str):
    out = tmp_path_factory.mktemp("run") / folder
    run_experiment(config_from_dict({**TINY, "scene": scene, "mode": "refract"}, "test"), out)
    return out


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """A tiny `tlm thesis` folder: ring and cornell, RCast and PMap."""
    return _study(tmp_path_factory, "study", ["ring", "cornell"])


@pytest.fixture(scope="module")
def ring_run(tmp_path_factory):
    """A single `tlm run` of the ring scene in mode refract (the ring has no dielectric)."""
    return _refract_run(tmp_path_factory, "ring_refract", "ring")


@pytest.fixture(scope="module")
def thesis_study(tmp_path_factory):
    """A tiny `tlm thesis` folder of the thesis's scenes (Tables I and III): thesis/ring and cornell,
    RCast and PMap (the built-in ``ring`` is not Table I's scene, so its cells are not tabled)."""
    return _study(tmp_path_factory, "thesis_study", ["thesis/ring", "cornell"])


@pytest.fixture(scope="module")
def thesis_ring_run(tmp_path_factory):
    """A single `tlm run` of the thesis's ring scene (Table I's) in mode refract."""
    return _refract_run(tmp_path_factory, "thesis_ring_refract", "thesis/ring")


def _png_ok(path) -> None:
    assert path.is_file(), path
    pixels = imread(path)
    assert pixels.ndim == 3 and pixels.shape[0] > 100 and pixels.shape[1] > 100
    assert float(pixels[..., :3].std()) > 0.05, f"{path} looks blank"


def _csv(folder) -> dict[tuple[str, str, str], dict]:
    with open(folder / "thesis_comparison.csv", newline="") as f:
        return {(r["scene"], r["mode"], r["metric"]): r for r in csv.DictReader(f)}


def _cell(html_text: str, cell: str, source: str | None = None) -> str:
    """The inner HTML of the table cell ``data-cell=cell`` (in the table of ``source`` if given)."""
    if source is not None:
        start = html_text.index(f'data-source="{source}"')
        html_text = html_text[start:html_text.index("</table>", start)]
    m = re.search(rf'<td data-cell="{re.escape(cell)}"[^>]*>(.*?)</td>', html_text, re.S)
    assert m, f"no cell {cell}"
    return m.group(1)


def _spans(cell_html: str) -> dict[str, str]:
    return dict(re.findall(r'<span class="(ours|thesis|err)"[^>]*>([^<]*)</span>', cell_html))


def _as_run(run: Run, kind: str, label: str, **results) -> Run:
    """A copy of ``run`` with another kind, label and some results fields replaced."""
    res = copy.deepcopy(run.results)
    for key, value in results.items():
        target = res
        *path, last = key.split(".")
        for p in path:
            target = target[p]
        target[last] = value
    return Run(run.path, label, kind, res, copy.deepcopy(run.config))


# -- Tables I-III ----------------------------------------------------------------------------------

@pytest.mark.slow
def test_tables_from_study_show_the_csv_values_and_marks(thesis_study, tmp_path):
    study = thesis_study
    section = tables_section(read([study]), tmp_path)
    assert section.absent is None and section.key == "tables"
    assert [f.file for f in section.figures] == ["tables_ring.png", "tables_cornell.png"]
    for f in section.figures:
        _png_ok(tmp_path / f.file)
    rows = _csv(study)
    html_text = section.html
    # every cell of the study is in the HTML with the CSV's values
    for (scene, mode, metric), row in rows.items():
        spans = _spans(_cell(html_text, f"{scene}/{mode}/{metric}"))
        assert spans["ours"] == fmt(float(row["ours"]))
        assert spans["thesis"] == fmt_thesis(float(row["thesis"]), scene, mode, metric)
        # the study's 32x32 frames are not the thesis's setting (below): the CSV keeps the error, the cell
        # shows none
        assert float(row["rel_error"]) == pytest.approx(float(row["ours"]) / float(row["thesis"]) - 1.0, abs=1e-5)
        assert spans["err"] == "n/c"
    spans = _spans(_cell(html_text, "cornell/pmap/TFrag"))
    assert spans["thesis"] == "210"
    assert float(spans["ours"]) == pytest.approx(float(rows[("cornell", "pmap", "TFrag")]["ours"]), rel=1e-3)
    # modes the study did not run are empty cells, not invented numbers
    assert "–" in _cell(html_text, "ring/reflect/TVert") and "ours" not in _cell(html_text, "ring/reflect/TVert")
    # calibrated cells carry the dagger, and only they
    for (scene, mode, metric) in rows:
        has = MARK_CALIBRATED in _cell(html_text, f"{scene}/{mode}/{metric}")
        assert has == ((mode, metric) in CALIBRATED), (scene, mode, metric)
    # the slowest PM of each scene-mode, in the thesis and in ours
    for scene in ("ring", "cornell"):
        for mode in ("rcast", "pmap"):
            theirs = max(PM_METRICS, key=lambda k: float(rows[(scene, mode, k)]["thesis"]))
            ours = max(PM_METRICS, key=lambda k: float(rows[(scene, mode, k)]["ours"]))
            for metric in (*PM_METRICS, "TThru", "FPS"):
                cell = _cell(html_text, f"{scene}/{mode}/{metric}")
                assert (MARK_SLOW_THESIS in cell) == (metric == theirs), (scene, mode, metric)
                assert (MARK_SLOW_OURS in cell) == (metric == ours), (scene, mode, metric)
    assert theirs == "TFrag"  # cornell PMap: Table III's fragment PM, 210 M cycles
    # the study's summary, and the 32x32 frames are flagged as not comparable
    summary = json.loads((study / "thesis_summary.json").read_text())
    assert summary["median_abs_rel_error_held_out"] is None  # not comparable: no median, and the line says why
    assert ("Thesis study thesis: no median |relative error| (not comparable with the thesis: thesis/ring is "
            in html_text)
    assert f"in {summary['slowest_pm_matches']} of {summary['scene_modes']} scene-modes" in html_text
    assert html_text.count('data-comparable="no"') == 2
    assert any("32×32 pixels (thesis 320×240)" in n and "2,000 photons (thesis 20,000)" in n for n in section.notes)
    assert MARK_CALIBRATED in html_text and "calibrated cell" in html_text  # the legend
    # the study's per-item table: every cell of thesis_summary.json's per_item (keyed by table), ours
    # (thesis), each row named by its scene as the study ran it
    start = html_text.index('class="thesis-table per-item"')
    table = html_text[start:html_text.index("</table>", start)]
    assert set(summary["per_item"]) == {f"{s}/{m}" for s in ("ring", "cornell") for m in ("rcast", "pmap")}
    assert set(re.findall(r"<tr><th>([a-z/]+)</th>", table)) == \
        {f"{s}/{m}" for s in ("thesis/ring", "cornell") for m in ("rcast", "pmap")}
    it = summary["per_item"]["cornell/pmap"]
    row = re.search(r"<tr><th>cornell/pmap</th>(.*?)</tr>", table).group(1)
    assert f"<td>{it['rays']:,}</td>" in row
    assert f"<td>{fmt(it['ours']['trav_cycles_per_ray'])} ({fmt(it['thesis']['trav_cycles_per_ray'])})</td>" in row


@pytest.mark.slow
def test_tables_from_runs_group_by_config_and_mark_comparability(thesis_study, thesis_ring_run, tmp_path):
    inputs = read([thesis_study])
    cells = {r.label: r for r in inputs.runs}
    # two cells of one study, posing as separate runs: one table with both columns
    runs = [_as_run(cells["thesis/ring/rcast"], "run", "a"), _as_run(cells["thesis/ring/pmap"], "run", "b")]
    # a run at the thesis's sizes (faked) is comparable
    big = _as_run(cells["cornell/rcast"], "run", "big", **{"scene.resolution": [320, 320]})
    big.config.setdefault("render", {}).update(spp=1, light_samples=1)  # and at the thesis's sampling
    big.config.setdefault("arch", {}).update(frames=5)  # and stream (configs/thesis.yaml's)
    section = tables_section(Inputs([], runs=[*runs, big]), tmp_path)
    assert section.absent is None
    tables = re.findall(r'<table class="thesis-table" data-scene="(\w+)" data-source="([^"]*)" '
                        r'data-comparable="(\w+)"', section.html)
    assert tables == [("ring", "a, b", "no"), ("cornell", "big", "yes")]
    pmap = cells["thesis/ring/pmap"].results
    spans = _spans(_cell(section.html, "ring/pmap/TTrav", "a, b"))
    assert spans["ours"] == fmt(pmap["cycles"]["traversal"] / 1e6)
    assert spans["thesis"] == fmt_thesis(THESIS["ring"]["TTrav"][MODES.index("pmap")], "ring", "pmap", "TTrav")
    assert spans["err"] == "n/c"  # no relative error against another setting than the thesis's
    assert _spans(_cell(section.html, "cornell/rcast/TTrav", "big"))["err"].endswith("%")
    spans = _spans(_cell(section.html, "ring/rcast/FPS", "a, b"))
    assert spans["ours"] == fmt(cells["thesis/ring/rcast"].results["fps"])
    assert not any("big" in n for n in section.notes)
    assert any(n.startswith("thesis/ring (a, b) is not comparable") for n in section.notes)
    # the single run of a smaller mode: its column only
    section = tables_section(read([thesis_ring_run]), tmp_path)
    assert "ours" in _cell(section.html, "ring/refract/TVert") and "ours" not in _cell(section.html, "ring/pmap/TVert")


@pytest.mark.slow
def test_tables_are_bounded_and_say_what_they_leave_out(thesis_study, tmp_path):
    cell = next(r for r in read([thesis_study]).runs if r.label == "thesis/ring/pmap")
    points = [_as_run(cell, "sweep-point", f"sweep #{i}") for i in range(MAX_TABLES_PER_SCENE + 2)]
    section = tables_section(Inputs([], runs=points), tmp_path)
    assert section.html.count('<table class="thesis-table"') == MAX_TABLES_PER_SCENE
    left = [n for n in section.notes if "left out of the tables" in n]
    assert len(left) == 1 and f"sweep #{MAX_TABLES_PER_SCENE}" in left[0] and "sweep #0" not in left[0]


@pytest.mark.slow
def test_sweep_points_are_not_tabled_beside_a_thesis_study(thesis_study, tmp_path):
    inputs = read([thesis_study])
    cell = next(r for r in inputs.runs if r.label == "thesis/ring/pmap")
    points = [_as_run(cell, "sweep-point", f"sweep #{i}") for i in range(2)]
    (tmp_path / "a").mkdir()
    alone = tables_section(Inputs([], runs=points), tmp_path / "a")
    assert 'data-source="sweep #0"' in alone.html
    inputs.runs.extend(points)
    both = tables_section(inputs, tmp_path)
    assert "sweep #" not in both.html
    assert any(n.startswith("2 sweep points of thesis scenes are not tabled") for n in both.notes)


def test_tables_absent_without_thesis_scenes(study, tmp_path):
    section = tables_section(Inputs([]), tmp_path)
    assert section.absent and "thesis" in section.absent and not section.figures
    cell = next(r for r in read([study]).runs if r.label == "ring/pmap")
    other = _as_run(cell, "run", "mine", **{"scene.name": "bunny"})
    section = tables_section(Inputs([], runs=[other]), tmp_path)
    assert section.absent and any("'bunny' has no table in the thesis" in n for n in section.notes)
    assert not list(tmp_path.glob("*.png"))


# -- image sets ------------------------------------------------------------------------------------

@pytest.mark.slow
def test_images_of_a_study_show_left_out_passes(study, tmp_path):
    section = images_section(read([study]), tmp_path)
    assert section.absent is None and section.key == "images"
    assert len(section.figures) == 1
    _png_ok(tmp_path / section.figures[0].file)
    # the study ran RCast and PMap; Reflect and Refract are rebuilt from the PMap cell, and the
    # ring's Refract pass was left out by the planner, with its reason
    assert any("Scene with ring" in n and "Refract" in n and "the scene has no dielectric material" in n
               for n in section.notes)
    assert any("no reflect cell" in n and "rebuilt from the pmap cell" in n for n in section.notes)
    assert not any("Cornell" in n and "left out" in n for n in section.notes)


@pytest.mark.slow
def test_images_of_a_run_are_cumulative_composites(ring_run, tmp_path):
    inputs = read([ring_run])
    section = images_section(inputs, tmp_path)
    assert section.absent is None
    _png_ok(tmp_path / section.figures[0].file)
    assert any("Refract" in n and "the scene has no dielectric material" in n for n in section.notes)
    assert any("PMap" in n and "not run" in n and "does not include the pmap" in n for n in section.notes)
    panels = run_panels(inputs.runs[0])
    assert [p.image is not None for p in panels] == [True, True, True, False]
    # the run's own mode is its written composite; Refract (left out) equals Reflect
    written = np.asarray(imread(ring_run / "images" / "composite.png")[..., :3] * 255).round()
    assert np.abs(panels[2].image.astype(float) - written).max() <= 1
    assert np.array_equal(panels[1].image, panels[2].image)
    assert not np.array_equal(panels[0].image, panels[1].image)  # the ring's mirror adds light


def test_images_absent_for_sweep_points_and_empty_inputs(ring_run, tmp_path):
    section = images_section(Inputs([]), tmp_path)
    assert section.absent and not section.figures
    bare = tmp_path / "point"
    bare.mkdir()
    shutil.copy(ring_run / "results.json", bare / "results.json")
    point = Run(bare, "sweep #0", "sweep-point", json.loads((bare / "results.json").read_text()), {})
    section = images_section(Inputs([], runs=[point]), tmp_path)
    assert section.absent and "sweep points" in section.absent
    assert any("1 sweep points have no images" in n for n in section.notes)


# -- peers -----------------------------------------------------------------------------------------

def test_peers_show_quoted_figures_the_thesis_row_and_ours(study, ring_run, tmp_path):
    inputs = read([study, ring_run])
    section = peers_section(inputs, tmp_path)
    assert section.absent is None and section.key == "peers"
    _png_ok(tmp_path / "peers.png")
    assert "other hardware" in section.figures[0].caption and "order-of-magnitude" in section.figures[0].caption
    text = section.html
    for quoted in ("7.52 fps to 28.88 fps", "1.8 fps to 10.5 fps", "8.1 s per frame", "64.3 s per frame",
                   "PMap 3.037", "RCast 24.2"):
        assert quoted in text, quoted
    assert "Schmittler" in text and "Purcell" in text
    ours = [line for line in text.splitlines() if line.startswith('<tr class="ours">')]
    assert len(ours) == 3  # study ring, study cornell, the run
    cell = next(r for r in inputs.runs if r.label == "cornell/pmap")
    line = next(x for x in ours if "cornell scene" in x)
    assert f"PMap {cell.results['fps']:.3g}" in line and "32×32 pixels" in line
    run_line = next(x for x in ours if "ring_refract" in x)
    assert f"Refract {inputs.runs[-1].results['fps']:.3g}" in run_line


@pytest.mark.slow
def test_peers_absent_or_bounded(study, tmp_path):
    section = peers_section(Inputs([]), tmp_path)
    assert section.absent and "frame rate" in section.absent and not section.figures
    cell = next(r for r in read([study]).runs if r.label == "ring/rcast")
    no_fps = _as_run(cell, "run", "broken", fps=None)
    many = [_as_run(cell, "run", f"r{i}") for i in range(MAX_OURS_ROWS + 2)]
    section = peers_section(Inputs([], runs=[no_fps, *many]), tmp_path)
    assert any("broken: no simulated FPS" in n for n in section.notes)
    left = [n for n in section.notes if "left out of the figure" in n]
    assert len(left) == 1 and f"r{MAX_OURS_ROWS}," in left[0] and "ours: r0," not in left[0]
    assert section.html.count('<tr class="ours">') == MAX_OURS_ROWS


def test_a_study_of_calibrated_cells_only_denies_no_median():
    """Only calibrated cells: their median, not 'no median (no cell with a thesis value)' too."""
    from tlm.report.tables import _line

    s = {"median_abs_rel_error_held_out": None, "median_abs_rel_error_calibrated": 0.04, "median_withheld": None,
         "held_out_cells_compared": 0, "calibrated_cells_compared": 4, "scene_modes": 1, "slowest_pm_matches": 1}
    assert _line(s) == ("median |relative error| over the 4 calibrated cells 4.0%; slowest PM as in the thesis in 1 "
                        "of 1 scene-modes")


def test_a_report_judges_each_thesis_cell_once(tmp_path, monkeypatch):
    """The tables and the report's first screen quote one judgement of a thesis study's cells
    (judging a cell reads its scene files): each cell is judged once, and both say why the
    study is not comparable."""
    import tlm.report.tables as tables_mod
    from tlm.report.collect import Study
    from tlm.report.summary import summary_section
    from tlm.scenes.loader import scenes_dir

    judged = []
    judge = tables_mod.run_mismatches
    monkeypatch.setattr(tables_mod, "run_mismatches", lambda table, *rest: judged.append(table) or judge(table, *rest))
    root = tmp_path / "study"
    scene = {"name": "cornell", "source": str(scenes_dir() / "cornell.yaml"), "resolution": [16, 16]}
    cell = Run(root / "cornell" / "rcast", "cornell/rcast", "thesis", {"scene": scene, "mode": "rcast"}, {})
    rows = [{"scene": "cornell", "mode": "rcast", "metric": m, "thesis": 10.0, "ours": 11.0, "rel_error": 0.1,
             "calibrated": False} for m in (*PM_METRICS, "TThru", "FPS")]
    inputs = Inputs([], runs=[cell], studies=[Study("thesis", root, rows)])
    tables = tables_section(inputs, tmp_path)
    summary = summary_section(inputs, tmp_path)
    assert judged == ["cornell"]
    said = "no median |relative error| (not comparable with the thesis: cornell is 16×16 pixels (thesis 320×320))"
    assert said in tables.html and said in summary.lead
    assert [f.file for f in tables.figures] == ["tables_cornell.png"]
