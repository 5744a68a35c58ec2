"""The report on a sweep of many points: notes that count and name a few, not walls of labels.

* Tables I-III listed every source left out of a scene's tables inline ("196 more sources
  left out ...: A1 #4, A1 #5, ..." and 996 labels on a 1,000-point sweep), and gave every
  run of a scene with no thesis table a note of its own; they count them and name a few now.
* The BSP-levels figure counted its series before merging identical ones: 100 combinations
  of the other factors that draw 5 curves were "100 curves ..., more than 8", and no figure.
  It counts them after the merge, as the FPS figures do.
* The BSP-levels notes listed the point numbers of unusable or truncated points inline.

The sweep folders are made by hand (the files and keys the report reads, at 16x16).
"""

from __future__ import annotations

import re
from pathlib import Path

from tests.sweep_folders import busy_units, start, write_point, write_rows
from tlm.report.collect import read
from tlm.report.common import some
from tlm.report.sweeps import levels_balance, sweeps_section
from tlm.report.tables import tables_section
from tlm.scenes.loader import scenes_dir

FIFOS = [1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048]  # 12 values: 12 combinations with the levels


def sweep_folder(root: Path, name: str = "cornell", levels=(6, 7), cycles_rows: bool = True,
                 truncated: bool = False, distinct: bool = False) -> Path:
    """A sweep over ``bsp.levels`` x ``arch.fifo_depth`` (12 depths) of the scene ``name``
    (the built-in cornell's file). The cycles and the FPS depend on the level only (the FIFO
    never fills), unless ``distinct``: then each depth draws its own curve. ``cycles_rows``:
    the rows have the traversal and intersection cycles; ``truncated``: every point's tree
    was built shallower than asked."""
    start(root, {"sweep": "s.yaml", "description": "16x16 RCast",
                 "grid": {"bsp.levels": list(levels), "arch.fifo_depth": FIFOS}})
    rows = []
    for i, (lv, fifo) in enumerate((lv, f) for lv in levels for f in FIFOS):
        fps = 20.0 - lv + (FIFOS.index(fifo) / 100 if distinct else 0.0)
        trav = 1000 + 100 * lv
        h = f"h{i:03d}"
        row = {"point": i, "hash": h, "status": "ok", "scene": "cornell", "mode": "rcast", "bsp.levels": lv,
               "arch.fifo_depth": fifo, "fps": fps, "cycles.throughput": 6e8 / fps}
        if cycles_rows:
            row.update({"cycles.traversal": trav, "cycles.intersection": 900})
        rows.append(row)
        cycles = {"vertex": 10, "traversal": trav, "intersection": 900, "fragment": 100, "throughput": 6e8 / fps,
                  "latency": 2000}
        results = {"scene": {"name": name, "source": str(scenes_dir() / "cornell.yaml"), "resolution": [16, 16],
                             "triangles": 2604, "bsp": {"levels": lv - truncated, "requested_levels": lv,
                                                        "truncated": truncated}},
                   "mode": "rcast", "fps": fps, "cycles": cycles,
                   "factors": {"bsp.levels": lv, "arch.fifo_depth": fifo},
                   "timing": {"frames": 1, "units": busy_units()}}
        write_point(root, h, results, {"scene": "cornell", "mode": "rcast", "resolution": [16, 16],
                                       "bsp": {"levels": lv}, "arch": {"fifo_depth": fifo}})
    write_rows(root, rows)
    return root


def test_some_counts_many_and_names_few():
    assert some([f"#{i}" for i in range(3)]) == "#0, #1 and #2"  # (h413: listed, the last after "and")
    assert some([f"#{i}" for i in range(8)]) == "#0, #1, #2, #3, #4, #5, #6 and #7"
    assert some([f"#{i}" for i in range(996)]) == "#0, #1, #2, #3 and 992 more"


def test_the_tables_count_the_sources_they_leave_out(tmp_path):
    inputs = read([sweep_folder(tmp_path / "S")])
    section = tables_section(inputs, tmp_path)
    left = [n for n in section.notes if "more sources left out" in n]
    assert left == ["Table III: 20 more sources left out of the tables and the figure (at most 4 per table): "
                    "S #4, S #5, S #6, S #7 and 16 more"]  # (listed all 20)


def test_the_runs_of_a_scene_with_no_thesis_table_are_one_note(tmp_path):
    """24 points of a scene named ``bunny``: one note, not 24."""
    inputs = read([sweep_folder(tmp_path / "B", name="bunny")])
    section = tables_section(inputs, tmp_path)
    assert section.absent and section.notes == [
        "scene 'bunny' has no table in the thesis: 24 runs of it left out of the tables "
        "(B #0, B #1, B #2, B #3 and 20 more)"]


def test_the_levels_figure_counts_its_lines_after_merging_identical_ones(tmp_path):
    """12 combinations of the other factors that draw one curve: a figure of one line, not
    "no BSP-levels figure: 12 curves ..., more than 8"."""
    inputs = read([sweep_folder(tmp_path / "S")])
    section = sweeps_section(inputs, tmp_path)
    assert not [n for n in section.notes if "no BSP-levels figure" in n]
    fig = next(f for f in section.figures if f.file == "bsp_balance_S.png")
    assert (tmp_path / "bsp_balance_S.png").is_file()
    assert "The 12 series (scenes times the other factors' values) draw 1 distinct line" in fig.caption
    # the table still lists every series
    assert section.html.count("<td class=\"l\">cornell (fifo_depth=") == 12


def test_the_levels_figure_is_left_out_for_more_than_8_distinct_lines(tmp_path):
    inputs = read([sweep_folder(tmp_path / "D", distinct=True)])
    section = sweeps_section(inputs, tmp_path)
    assert not [f for f in section.figures if f.file.startswith("bsp_balance")]
    assert "D: no BSP-levels figure: 12 curves (scenes times the other factors' values) draw more than 8 distinct " \
           "lines; the table lists them" in section.notes


def test_the_levels_notes_count_the_points_they_name(tmp_path):
    notes: list[str] = []
    levels_balance(read([sweep_folder(tmp_path / "U", cycles_rows=False)]).sweeps[0], notes)
    assert notes[0] == ("U: 24 points (0, 1, 2, 3 and 20 more) left out of the BSP-levels balance: no level, or "
                        "no traversal and intersection cycles")
    notes = []
    levels_balance(read([sweep_folder(tmp_path / "T", truncated=True)]).sweeps[0], notes)
    assert notes == ["T: 24 points (0, 1, 2, 3 and 20 more) built a shallower BSP tree than their level asks "
                     "(results.json scene.bsp.truncated); they are drawn at the level asked"]
    notes = []
    levels_balance(read([sweep_folder(tmp_path / "O", levels=(7,))]).sweeps[0], notes)
    assert notes == ["O: 12 series (cornell (fifo_depth=1), cornell (fifo_depth=2), cornell (fifo_depth=4), "
                     "cornell (fifo_depth=8) and 8 more): one level only, no balance curve"]
    assert not [n for n in notes if re.search(r"(\d+, ){8}", n)]
