"""A sweep factor's null value is written ``null``, as its YAML writes it, not Python's ``None``.

``bsp.levels: [null, 6, 8]`` (null: the thesis's depth, floor(ln n)) was shown as ``None`` in the
sweep's points table, in the legend of the FPS-against-``arch.fifo_depth`` figure
(``levels=None``), in a sweep point's factors (the title of its figures) and in the findings.
Each now says ``null`` and, where the key's help (``tlm params``) says what null asks, that in
short: ``null (floor(ln n))``; the same rule that names the null points on a factor's own axis
(``bsp.levels null (floor(ln n), the thesis's depth)``), whose parentheses are now kept whole.

The sweep folders hold the rows only (``sweep.yaml``, ``sweep.jsonl``): all the figures read.
"""

from __future__ import annotations

import json
from pathlib import Path

import yaml

import tlm.report.sweeps as sweeps
from tlm.report.collect import Inputs, Run, Sweep, read
from tlm.report.cycles import select_runs
from tlm.report.summary import sweep_findings
from tlm.report.sweep_lines import NULL_STYLE
from tlm.report.sweeps import _group_label, factor_figure, sweeps_section

NULL_LEVELS = "null (floor(ln n))"


def rows_sweep(folder: Path, key: str, values: list, fifos=(1, 16), fps_of=None) -> Path:
    """A sweep over ``key`` (``values``) x ``arch.fifo_depth``, rows only; a point of ``key`` null ran at 30
    FPS, another at ``20 - value + fifo / 100``."""
    folder.mkdir(parents=True)
    (folder / "sweep.yaml").write_text(yaml.safe_dump({"sweep": "s.yaml", "description": "16x16 RCast",
                                                       "grid": {key: values, "arch.fifo_depth": list(fifos)}},
                                                      sort_keys=False))
    rows = []
    for i, (v, fifo) in enumerate((v, f) for v in values for f in fifos):
        fps = 30.0 + fifo / 100 if v is None else 20.0 - v + fifo / 100
        rows.append({"point": i, "hash": f"h{i:03d}", "status": "ok", "scene": "cornell", "mode": "rcast", key: v,
                     "arch.fifo_depth": fifo, "fps": fps, "cycles.throughput": 6e8 / fps})
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


def drawn(monkeypatch, sw, factor: str, out: Path):
    """The matplotlib figure of FPS against ``factor`` and its record."""
    figs = []
    save = sweeps.save
    monkeypatch.setattr(sweeps, "save", lambda fig, *a, **k: figs.append(fig) or save(fig, *a, **k))
    record = factor_figure(sw, factor, out, [])
    (fig,) = figs
    return fig, record


def legend(fig) -> list[str]:
    return [t.get_text().replace("\n", " ") for t in fig.legends[0].get_texts()]


def test_the_points_table_says_null_and_what_it_asks(tmp_path):
    folder = rows_sweep(tmp_path / "L", "bsp.levels", [None, 6, 8])
    (out := tmp_path / "rep").mkdir()
    html = sweeps_section(read([folder]), out).html
    assert html.count(f"<td>{NULL_LEVELS}</td>") == 2, html  # (the two points of bsp.levels null)
    assert "<td>None</td>" not in html


def test_the_legend_against_another_factor_says_null(tmp_path, monkeypatch):
    (sw,) = read([rows_sweep(tmp_path / "L", "bsp.levels", [None, 6, 8])]).sweeps
    fig, _ = drawn(monkeypatch, sw, "arch.fifo_depth", tmp_path)
    assert legend(fig) == [f"levels={NULL_LEVELS}", "levels=6", "levels=8"]


def test_a_label_of_identical_combinations_says_null():
    combos = [(None, 1), (None, 16), (6, 1), (6, 16)]
    assert _group_label(["bsp.levels", "arch.fifo_depth"], combos) == \
        f"levels={NULL_LEVELS} or 6; fifo_depth=1 or 16 (identical)"


def test_a_sweep_points_factors_say_null():
    """A point's factors, the title of its cycle figures and of its images."""
    point = Run(Path("sw/points/h0"), "sw #0", "sweep-point", {"scene": {"name": "cornell"}}, {},
                {"bsp.levels": None, "arch.fifo_depth": 16, "estimate.final_gather": True})
    assert point.factors_text == f"bsp.levels = {NULL_LEVELS}, arch.fifo_depth = 16, estimate.final_gather = true"


def test_the_note_of_the_points_where_the_cycles_go_says_null():
    points = [Run(Path(f"h{i}"), f"sw #{i}", "sweep-point", {"scene": {"name": "cornell"}, "cycles": {"throughput": 1},
                  "timing": {"units": {"xbar": {}}}}, {}, {"bsp.levels": lv}) for i, lv in enumerate((None, 6, 8))]
    _, notes = select_runs(Inputs([], runs=points, sweeps=[Sweep(Path("sw"), {}, [], points)]))
    assert notes == [f"Sweep sw: 2 of 3 points are shown, its first and last point (sw #0 [levels={NULL_LEVELS}] "
                     "and sw #2 [levels=8])."], notes


def test_the_findings_say_null(tmp_path):
    (sw,) = read([rows_sweep(tmp_path / "L", "bsp.levels", [None, 6, 8])]).sweeps
    (text,) = sweep_findings(Inputs([], sweeps=[Sweep(sw.path, sw.spec, sw.rows, [])]))
    assert f"between its best value ({NULL_LEVELS}) and its worst (8)" in text, text
    # (30.01 and 30.16 FPS, 0.5% apart: a tie within 1%, h509)
    assert (f"2 points tie within 1% as the best, at 30.0 to 30.2 FPS: bsp.levels = {NULL_LEVELS}, any "
            "arch.fifo_depth.") in text, text
    assert "None" not in text


def test_a_null_whose_help_has_an_aside_in_parentheses(tmp_path, monkeypatch):
    """render.threads' help: ``null = the CPUs available to the process (its affinity, ...; ...)``: the
    legend of the null points on its own axis cut that in the parenthesis (at its ``;``), which was
    left open; a label of the other factor's figure says the first clause, ``null (the CPUs available
    to the process)``."""
    (sw,) = read([rows_sweep(tmp_path / "T", "render.threads", [None, 2, 4])]).sweeps
    fig, _ = drawn(monkeypatch, sw, "render.threads", tmp_path)
    (star,) = [t for t, h in zip(legend(fig), fig.legends[0].legend_handles, strict=True)
               if h.get_marker() == NULL_STYLE["marker"]]
    assert star.startswith("render.threads null (the CPUs available to the process (its affinity, "), star
    assert star.count("(") == star.count(")"), star
    fig, _ = drawn(monkeypatch, sw, "arch.fifo_depth", tmp_path)
    assert legend(fig) == ["threads=null (the CPUs available to the process)", "threads=2", "threads=4"]
