"""`tlm report` as a probe found it wanting, mended.

* A damaged file among the inputs (a results.json or eq52.json not JSON or cut off, a cut-off
  extreme.jsonl, a damaged sweep point) is named, with what to do and what is left out, in the
  page's warnings and on stderr; the report is written from the rest. Every input damaged: one
  error listing them all, exit 2.
* Two ``tlm report`` into one folder at once: the second is refused (exit 2), as a second run is.
* The first screen says a tie of bottleneck PMs as a tie, draws the thesis's ticks where they can
  be seen on every bar, names in its captions and legend only what is drawn, and reads the sweep
  points, the granularity study and the runs' photon-map error where no run, thesis or
  error-vs-cost study is there to draw; an extreme-only report says its cases were simulated.
* Provenance: a sweep point's render is part of its host seconds ("of which"), and thesis cells
  say the render they share.
* An extreme case refused for a huge resolution names its case; a sweep's category factor is
  drawn in its grid's order.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError
from tlm.report.collect import Inputs, Run, Study, Sweep, read
from tlm.report.cycles import cycles_section
from tlm.report.html import section_html
from tlm.report.provenance import provenance_section
from tlm.report.summary import PMS, summary_section
from tlm.report.warnings import warnings_html

REPO = Path(__file__).resolve().parents[1]
RESULTS = {"tlm": "results/1", "scene": {"name": "cornell"}, "mode": "rcast", "timing": {}, "seed": 0}


def _run_folder(folder: Path, results: dict | None = None) -> Path:
    folder.mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps(results or RESULTS, indent=2) + "\n")
    return folder


def _cut(path: Path) -> Path:
    text = path.read_text()
    path.write_text(text[:len(text) // 2])
    return path


def _damaged_study_folders(root: Path) -> list[Path]:
    """An extreme study whose table is cut off and a scaling study whose eq52.json is cut off: their files."""
    (root / "ext").mkdir(parents=True)
    row = {"case": "a", "category": "geometry", "expect": "x", "measured": "y", "passed": True, "seconds": 1.0}
    (root / "ext" / "extreme.jsonl").write_text(json.dumps(row) + "\n" + json.dumps(row)[:20])
    (root / "sc").mkdir()
    (root / "sc" / "eq52.json").write_text(json.dumps({"fits": [], "sweeps": []}, indent=2)[:12])
    return [root / "ext" / "extreme.jsonl", root / "sc" / "eq52.json"]


def test_every_damaged_file_is_named_and_the_rest_is_read(tmp_path):
    _run_folder(tmp_path / "in" / "ok")
    bad_run = _cut(_run_folder(tmp_path / "in" / "cut") / "results.json")
    files = [bad_run, *_damaged_study_folders(tmp_path / "in")]
    inputs = read([tmp_path / "in"])
    assert [r.path.name for r in inputs.runs] == ["ok"] and inputs.studies == []
    assert len(inputs.damaged) == 3
    for f in files:
        line = next(d for d in inputs.damaged if d.startswith(f"{f}: "))
        assert "a damaged copy" in line and "copy it again or run" in line and "left out of this report" in line
    assert "is cut off (" in next(d for d in inputs.damaged if d.startswith(str(bad_run)))  # (not a raw parser error)
    page = warnings_html(inputs)
    assert "Damaged inputs" in page and all(str(f) in page for f in files)


def test_every_input_damaged_is_one_error_naming_each(tmp_path):
    files = _damaged_study_folders(tmp_path / "in")
    with pytest.raises(InputError) as e:
        read([tmp_path / "in"])
    text = str(e.value)
    assert "every tlm output given is damaged (2 folders)" in text and all(str(f) in text for f in files)
    assert "\n" not in text


def test_a_damaged_sweep_point_is_left_out_and_said(tmp_path):
    sw = tmp_path / "sw"
    (sw / "points").mkdir(parents=True)
    (sw / "sweep.yaml").write_text(yaml.safe_dump({"grid": {"arch.pipelines": [1, 2]},
                                                   "points": [{"hash": "a"}, {"hash": "b"}]}))
    rows = [{"point": i, "hash": h, "status": "ok", "fps": 1.0, "arch.pipelines": i + 1} for i, h in enumerate("ab")]
    (sw / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    _run_folder(sw / "points" / "a")
    bad = _cut(_run_folder(sw / "points" / "b") / "results.json")
    inputs = read([sw])
    assert [r.path.name for r in inputs.runs] == ["a"]
    assert [r["status"] for r in inputs.sweeps[0].rows] == ["ok", "damaged"]
    assert len(inputs.damaged) == 1 and inputs.damaged[0].startswith(f"{bad}: is cut off (cannot read it as JSON: ")


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("mends")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--out", str(root / "runs" / "good"), "--set",
                     "resolution=[16,16]", "--set", "arch.frames=1", "--set", "render.light_samples=1", "--set",
                     "mode=rcast", "--no-report", "--no-progress", "--no-reference"]) == 0
    return root / "runs" / "good"


@pytest.mark.slow  # (a render, and a process holding the folder)
def test_the_report_of_the_rest_says_the_damaged_file(tiny_run, tmp_path, capsys, cache):
    runs = tmp_path / "runs"
    runs.mkdir()
    good = runs / "good"
    bad = runs / "bad"
    for f in (good, bad):
        f.mkdir()
        for name in ("results.json", "config.resolved.yaml"):
            (f / name).write_bytes((tiny_run / name).read_bytes())
    _cut(bad / "results.json")
    capsys.readouterr()
    assert main(["report", str(runs), "--out", str(tmp_path / "rep")]) == 0
    err = capsys.readouterr().err
    assert f"tlm: note: {bad / 'results.json'}: is cut off" in err and "internal error" not in err
    page = (tmp_path / "rep" / "report.html").read_text(encoding="utf-8")
    assert "Damaged inputs" in page and "1 damaged file left out" in page
    assert main(["report", str(bad), "--out", str(tmp_path / "rep2")]) == 2
    assert capsys.readouterr().err.startswith(f"tlm: error: {bad / 'results.json'}: is cut off")
    assert not (tmp_path / "rep2").exists()


@pytest.mark.slow  # (a render, and a process holding the folder)
def test_a_second_report_into_one_folder_is_refused(tiny_run, tmp_path, capsys, cache):
    out = tmp_path / "rep"
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from pathlib import Path; from tlm import claims\n"
         f"with claims.claimed(Path({str(out)!r}), 'report'):\n    print('held', flush=True); time.sleep(60)"],
        stdout=subprocess.PIPE, text=True, cwd=REPO)
    try:
        assert holder.stdout.readline().strip() == "held"
        capsys.readouterr()
        assert main(["report", str(tiny_run), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert f"another report is writing into {str(out)!r} (process {holder.pid}" in err, err
        assert not (out / "report.html").exists()
    finally:
        holder.kill()
        holder.wait()
    assert main(["report", str(tiny_run), "--out", str(out)]) == 0  # (its process ended: the folder is free)


# -- the first screen -----------------------------------------------------------------------------------------

def _run(scene: str, mode: str, fps: float, busy: dict[str, float], kind: str = "run", path: str = "") -> Run:
    units = {f"pipe0.{pm}": {"fractions": {"busy": b}} for pm, b in busy.items()}
    return Run(Path(path or f"runs/{scene}-{mode}"), f"{scene}/{mode}", kind,
               {"scene": {"name": scene}, "mode": mode, "fps": fps, "timing": {"units": units}}, {})


def _busy(top: str) -> dict[str, float]:
    return {pm: 0.9 if pm == top else 0.2 for pm in PMS}


def _figures(monkeypatch) -> dict:
    """The matplotlib figures the summary saves, by file name."""
    import tlm.report.summary as summary

    drawn = {}
    real = summary.save

    def keep(fig, out, name, *a, **k):
        drawn[name] = fig
        return real(fig, out, name, *a, **k)

    monkeypatch.setattr(summary, "save", keep)
    return drawn


def test_a_tie_of_bottlenecks_is_said_as_one(tmp_path):
    runs = [_run(s, "rcast", 1.0, _busy(pm)) for s, pm in zip(("a", "b", "c", "d"), PMS[::-1], strict=True)]
    lead = summary_section(Inputs([], runs=runs), tmp_path).lead
    assert "each of TVert, TTrav, Tisct and TFrag is the bottleneck in 1 of 4 scene-modes" in lead


def test_captions_and_legend_name_only_what_is_drawn(tmp_path, monkeypatch):
    drawn = _figures(monkeypatch)
    sec = summary_section(Inputs([], runs=[_run("ring", "rcast", 2.0, _busy("traversal"))]), tmp_path)
    captions = {f.file: f.caption for f in sec.figures}
    assert "ticks" not in captions["summary_fps.png"] and "▲" not in captions["summary_bottleneck.png"]
    legend = drawn["summary_fps.png"].axes[0].get_legend()
    assert [t.get_text() for t in legend.get_texts()] == ["RCast"]


def test_the_thesis_ticks_show_on_a_black_bar(tmp_path, monkeypatch):
    drawn = _figures(monkeypatch)
    rows = [{"scene": "ring", "mode": "rcast", "metric": "FPS", "ours": 9.0, "thesis": 3.0, "rel_error": 2.0,
             "calibrated": False}]
    inputs = Inputs([], studies=[Study("thesis", tmp_path / "th", rows)])
    sec = summary_section(inputs, tmp_path)
    assert "black ticks edged in white" in next(f.caption for f in sec.figures if f.file == "summary_fps.png")
    lines = drawn["summary_fps.png"].axes[0].get_lines()
    white = [ln for ln in lines if ln.get_marker() == "_" and ln.get_color() == "white"]
    black = [ln for ln in lines if ln.get_marker() == "_" and ln.get_color() in ("k", "black")]
    assert white and black and lines.index(white[0]) < lines.index(black[0])  # (the black tick over a white one)
    assert white[0].get_markeredgewidth() > black[0].get_markeredgewidth()


def test_sweep_points_alone_are_read_for_speed_and_bottleneck(tmp_path):
    points = [_run("cornell", "rcast", fps, _busy("traversal"), kind="sweep-point", path=f"sw/points/{i}")
              for i, fps in enumerate((2.0, 8.0))]
    lead = summary_section(Inputs([], runs=points), tmp_path).lead
    assert "no frame rate to show" not in lead and "no bottleneck to show" not in lead
    assert "the 2 sweep points run from 2 FPS" in lead
    assert "the bottleneck PM of the 2 sweep points: TTrav in 2, busy 90%" in lead


def test_the_error_the_page_shows_elsewhere_is_said(tmp_path):
    inputs = Inputs([], studies=[Study("granularity", tmp_path / "gran", [])])
    lead = summary_section(inputs, tmp_path).lead
    assert "no error to show" not in lead and "§6 shows the TLM cycle error of the granularity study" in lead


def test_an_extreme_only_report_says_its_cases_were_simulated(tmp_path):
    rows = [{"case": f"c{i}", "category": "geometry", "expect": "", "measured": "", "passed": True, "seconds": 1.0}
            for i in range(3)]
    inputs = Inputs([], studies=[Study("extreme", tmp_path / "ext", rows)])
    absent = cycles_section(inputs, tmp_path).absent
    assert "nothing was simulated" not in absent and "the 3 cases of the extreme study" in absent
    prov = provenance_section(inputs, tmp_path).html
    assert "<table>" not in prov and "No run among the inputs; the 3 cases" in prov


def test_host_seconds_say_what_is_part_of_what(tmp_path):
    point = Run(Path("sw/points/a"), "sw #0", "sweep-point",
                {"scene": {"name": "x"}, "host_seconds": {"functional": 1.267, "simulate": 0.1},
                 "functional": {"cached": False, "render_host_seconds": {"load_scene": 0.5, "cast": 0.378}}}, {})
    cells = [Run(tmp_path / "th" / "ring" / mode, f"ring/{mode}", "thesis",
                 {"scene": {"name": "ring"}, "host_seconds": {"load_scene": 0.25, "build_bsp": 1.5, "simulate": s,
                                                              **extra}}, {})
             for mode, s, extra in (("rcast", 0.5, {}), ("pmap", 0.75, {"photon_trace": 3.0}))]
    sec = provenance_section(Inputs([], runs=[point, *cells]), tmp_path)
    assert "1.367 (of which 0.878 render)" in sec.html and "(+ 0.878" not in sec.html
    assert "2.25 (of which 1.75 shared with its scene" in sec.html
    assert any("renders each scene once for all its modes" in n for n in sec.notes)


def test_the_shared_render_note_points_where_the_studys_line_is(tmp_path):
    """The notes come after the section's table and its study lines (html.section): the
    study's line is above them; without the study among the inputs, its provenance.json."""
    cells = [Run(tmp_path / "th" / "ring" / mode, f"ring/{mode}", "thesis",
                 {"scene": {"name": "ring"}, "host_seconds": {"load_scene": 0.25, "build_bsp": 1.5, "simulate": 0.5}},
                 {}) for mode in ("rcast", "pmap")]
    study = Study("thesis", tmp_path / "th", [], {"provenance": {"study": "t.yaml", "host_seconds": 2.5}})
    for studies, where in (([study], "(its line above)"), ([], "(its folder's provenance.json)")):
        sec = provenance_section(Inputs([], runs=cells, studies=studies), tmp_path)
        (note,) = [n for n in sec.notes if "renders each scene once" in n]
        assert f"the study's host seconds {where}, which count" in note and "below" not in note
        if studies:  # (on the page: the study's line, then the note)
            page = section_html(1, sec, tmp_path)
            assert page.index("thesis folder") < page.index("renders each scene once")


def test_a_huge_resolution_case_names_its_case(tmp_path, cache):
    from tlm.experiments.extreme import run_extreme

    cases = tmp_path / "extreme.yaml"
    cases.write_text(yaml.safe_dump({"base": {"scene": "cornell", "mode": "rcast"}, "cases": [{
        "name": "bad-huge-resolution", "category": "bad input", "expect": "refused",
        "config": {"resolution": [200000, 200000]}, "checks": [{"error": "more than this machine's"}]}]}))
    rows = run_extreme(cases, tmp_path / "out")
    assert rows[0]["passed"] and f"{cases} (bad-huge-resolution): resolution:" in rows[0]["measured"]


def test_a_category_factor_keeps_its_grid_order(tmp_path, monkeypatch):
    import tlm.report.sweeps as sweeps

    drawn = {}
    real = sweeps.save

    def keep(fig, out, name, *a, **k):
        drawn["fig"] = fig
        return real(fig, out, name, *a, **k)

    monkeypatch.setattr(sweeps, "save", keep)
    rows = [{"point": i, "hash": str(i), "status": "ok", "fps": 1.0 + i, "arch.scheduler": s}
            for i, s in enumerate(("static", "dynamic"))]
    sw = Sweep(tmp_path / "sw", {"grid": {"arch.scheduler": ["static", "dynamic"]}}, rows, [])
    assert sweeps.factor_figure(sw, "arch.scheduler", tmp_path, []) is not None
    ticks = [t.get_text() for t in drawn["fig"].axes[0].get_xticklabels()]
    assert [t for t in ticks if t] == ["static", "dynamic"], ticks
