"""The report of a sweep of many points (the h22 probe's 200-point sweep, F3 and F2).

* FPS against a factor: the distinct lines are counted after identical ones are merged. A
  sweep whose 12 combinations of the other factors draw 2 lines was drawn as a median and a
  min-max band, the median a value no point has; now it is 2 lines, each named. Many
  distinct lines are still a median and a band, and the caption says what the band is.
* Where the cycles go: a sweep that does not vary ``arch.pipelines`` shows its first and last
  point (every point was its own group: the first 8 in point order were drawn), and a note
  of many left-out runs counts them and names a few, not hundreds.
* A sweep folder's ``points/`` holding folders of no point of the sweep (a rerun after a code
  edit leaves them): the sweep section counts them.

The sweep folders here hold the rows only (``sweep.yaml``, ``sweep.jsonl``): all that the
figures read.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import yaml

from tlm.report import sweeps as sweeps_mod
from tlm.report.collect import Inputs, Run, Sweep, read
from tlm.report.cycles import select_runs
from tlm.report.html import esc
from tlm.report.sweeps import _group_label, factor_figure, sweeps_section

LEVELS, PACKETS, FIFOS, MISSES = (6, 7), (1, 16, 64), (1, 4), (0, 6, 12, 24)


def sweep_folder(folder: Path, fps_of) -> Path:
    """A 48-point sweep (levels x packet x FIFO x miss cycles); point (l, p, f, m) ran at ``fps_of(l, p, f, m)``."""
    folder.mkdir(parents=True)
    grid = {"bsp.levels": list(LEVELS), "arch.packet_size": list(PACKETS), "arch.fifo_depth": list(FIFOS),
            "arch.page_miss_cycles": list(MISSES)}
    points, rows = [], []
    for i, (lv, p, f, m) in enumerate(itertools.product(LEVELS, PACKETS, FIFOS, MISSES)):
        factors = {"bsp.levels": lv, "arch.packet_size": p, "arch.fifo_depth": f, "arch.page_miss_cycles": m}
        points.append({"point": i, "hash": f"h{i:03d}", "factors": factors})
        rows.append({"point": i, "hash": f"h{i:03d}", "status": "ok", **factors, "scene": "cornell",
                     "mode": "rcast", "fps": fps_of(lv, p, f, m)})
    (folder / "sweep.yaml").write_text(yaml.safe_dump({"sweep": "s48.yaml", "description": "16x16 Cornell RCast",
                                                       "grid": grid, "points": points}, sort_keys=False))
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


def capture(monkeypatch) -> list:
    """Every matplotlib figure the sweeps section saves, in order (and still saved)."""
    figs, real = [], sweeps_mod.save

    def keep(fig, *a, **k):
        figs.append(fig)
        return real(fig, *a, **k)

    monkeypatch.setattr(sweeps_mod, "save", keep)
    return figs


def two_levels(lv, p, f, m):  # (as in the probe: the BSP depth and the miss cycles matter, nothing else)
    return (501.14 if lv == 6 else 414.41) - 0.008 * m


def test_combinations_that_draw_two_lines_are_two_lines_not_a_median(tmp_path, monkeypatch):
    figs = capture(monkeypatch)
    (sw,) = read([sweep_folder(tmp_path / "s48", two_levels)]).sweeps
    notes: list[str] = []
    fig = factor_figure(sw, "arch.page_miss_cycles", tmp_path, notes)
    (ax,) = figs[0].axes
    lines = {ln.get_label(): list(ln.get_ydata()) for ln in ax.get_lines()}
    assert lines == {
        f"levels={lv}; packet_size=1, 16 or 64; fifo_depth=1 or 4 (identical)": [two_levels(lv, 1, 1, m)
                                                                                 for m in MISSES]
        for lv in LEVELS}
    assert not ax.collections and notes == []  # no band, no "median and range" note
    assert ("The 12 combinations of bsp.levels, arch.packet_size, arch.fifo_depth draw 2 distinct lines: identical "
            "ones are drawn once, their label naming them all.") in fig.caption
    # every value drawn is a point's: nothing between the two levels (the median was 457.7 in the probe)
    fps = {r["fps"] for r in sw.rows}
    assert all(y in fps for ys in lines.values() for y in ys)


def test_many_distinct_lines_are_a_median_and_a_band_the_caption_says_what_the_band_is(tmp_path, monkeypatch):
    figs = capture(monkeypatch)
    (sw,) = read([sweep_folder(tmp_path / "s48", lambda lv, p, f, m: 100.0 * lv + p + 0.5 * f - 0.01 * m)]).sweeps
    notes: list[str] = []
    fig = factor_figure(sw, "arch.page_miss_cycles", tmp_path, notes)
    (ax,) = figs[0].axes
    assert [ln.get_label() for ln in ax.get_lines()] == ["median"] and len(ax.collections) == 1
    assert ("the band at each value of arch.page_miss_cycles spans the lowest to the highest FPS of those "
            "combinations there, the line is their median") in fig.caption
    assert notes == ["s48: FPS against arch.page_miss_cycles shows the median and the min-max range over the 12 "
                     "combinations of bsp.levels, arch.packet_size, arch.fifo_depth: they draw more than 8 distinct "
                     "lines"]


def test_a_label_of_many_irregular_identical_combinations_names_a_few_and_counts_the_rest():
    others = ["arch.packet_size", "arch.fifo_depth"]
    combos = [(p, f) for p in (1, 16, 64, 256) for f in (1, 4, 16)][:-1]  # 11 of 12: no product of values
    assert _group_label(others, combos) == ("packet_size=1, fifo_depth=1 | packet_size=1, fifo_depth=4 | "
                                            "packet_size=1, fifo_depth=16 and 8 more combinations (identical)")


def _point(i: int, factors: dict) -> Run:
    results = {"scene": {"name": "cornell"}, "cycles": {"throughput": 1000 + i}, "timing": {"units": {"xbar": {}}}}
    return Run(Path(f"h{i:03d}"), f"s48 #{i}", "sweep-point", results, {}, dict(factors))


def test_where_the_cycles_go_shows_a_sweeps_first_and_last_point(tmp_path):
    points = [_point(i, {"arch.packet_size": p, "arch.fifo_depth": f})
              for i, (p, f) in enumerate(itertools.product((1, 16, 64, 256), (1, 4, 16, 256, 1024)))]
    inputs = Inputs([], runs=points, sweeps=[Sweep(Path("s48"), {}, [], points)])
    chosen, notes = select_runs(inputs)
    assert [r.label for r in chosen] == ["s48 #0", "s48 #19"]
    assert notes == ["Sweep s48: 2 of 20 points are shown, its first and last point (s48 #0 [packet_size=1, "
                     "fifo_depth=1] and s48 #19 [packet_size=256, fifo_depth=1024])."]


def test_a_note_of_many_runs_left_out_counts_them_and_names_a_few(tmp_path):
    runs = [Run(Path(f"r{i}"), f"r{i}", "run", {"cycles": {"throughput": 1}, "timing": {"units": {"xbar": {}}}},
                {}, {}) for i in range(30)]
    untimed = [Run(Path(f"u{i}"), f"u{i}", "run", {"timing": None}, {}, {}) for i in range(12)]
    chosen, notes = select_runs(Inputs([], runs=[*runs, *untimed]))
    assert len(chosen) == 8
    assert notes == ["No timing results (not simulated), 12 left out: u0, u1, u2, u3 and 8 more.",
                     "At most 8 runs are drawn; 22 left out: r8, r9, r10, r11 and 18 more."]


def test_the_sweep_section_counts_point_folders_of_no_point_of_the_sweep(tmp_path):
    folder = sweep_folder(tmp_path / "s48", two_levels)
    for i in range(48):  # this sweep's points, and those a run of other code left
        (folder / "points" / f"h{i:03d}").mkdir(parents=True)
        (folder / "points" / f"old{i:03d}").mkdir()
    (folder / "points" / ".h000.tmp-h1-999999").mkdir()  # (a writer's temporary folder: not counted)
    sec = sweeps_section(read([folder]), tmp_path)
    said = ("48 point folders in s48/points are not this sweep's: left by an earlier run into the folder of other "
            "tlm code, another config or a different --set (an edit under tlm/ or to an input file changes every "
            "point's hash); nothing reads them, and removing them changes no result (sweep.yaml lists this sweep's "
            "hashes)")
    assert f"s48: {said}" in sec.notes
    assert f"sweep file s48.yaml. {esc(said)}.</p>" in sec.html
