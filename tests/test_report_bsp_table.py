"""The BSP-levels balance of a sweep shows every point it measured.

A sweep over ``bsp.levels: [null, 3, 6]`` (the builder's floor(ln n) beside numbers) x another
factor: ``null`` asks for floor(ln n), 6 for the ring's 646 triangles, so each series (a
combination of the other factors) had two points at level 6 that measured the same. The report
left every such series out of the BSP-levels table and figure ("several points share a level
(they differ in a factor the report cannot tell apart)"): no row, no line, for a sweep whose
every point is usable. Such repeats are shown once now, a note counting them; and the points
table gives each point's Ttrav / Tisct, which the balance table (one row per series, a summary)
and a left-out figure did not.

The sweep folders are made by hand (the files and keys the report reads), with the cycles a real
16x12 sweep of the ring measured: ``bsp.levels`` null and 6 gave the same cycles there.
"""

from __future__ import annotations

import re
from pathlib import Path

from tests.sweep_folders import busy_units, start, write_point, write_rows
from tlm.report.collect import read
from tlm.report.sweeps import levels_balance, sweeps_section
from tlm.scenes.loader import scenes_dir

# (level, pipelines) -> cycles (vertex, traversal, intersection, fragment, throughput) and FPS
MEASURED = {(3, 1): (173190, 387529, 1172664, 60630, 1791797, 334.8593618585141),
            (3, 2): (173190, 195710, 587498, 30412, 984176, 609.647054998293),
            (6, 1): (392947, 398940, 522870, 60630, 1371896, 437.3509362225708),
            (6, 2): (392947, 201931, 273314, 30412, 893677, 671.3835088068731)}


def sweep_folder(root: Path, levels=(None, 3, 6), differ: bool = False) -> Path:
    """A sweep of the built-in ring over ``bsp.levels`` x ``arch.pipelines`` [1, 2]; ``None`` is
    ``bsp.levels: null`` (floor(ln 646) = 6). ``differ``: the null points measured other traversal
    cycles than those asking for 6 (a factor the report cannot tell apart)."""
    start(root, {"sweep": "s.yaml", "description": "16x12 RCast",
                 "grid": {"bsp.levels": list(levels), "arch.pipelines": [1, 2]}})
    rows = []
    for i, (lv, n) in enumerate((lv, n) for lv in levels for n in (1, 2)):
        level = 6 if lv is None else lv
        vert, trav, isct, frag, thru, fps = MEASURED[(level, n)]
        trav += 1000 if differ and lv is None else 0
        h = f"h{i:03d}"
        rows.append({"point": i, "hash": h, "status": "ok", "scene": "ring", "mode": "rcast", "bsp.levels": lv,
                     "arch.pipelines": n, "fps": fps, "cycles.vertex": vert, "cycles.traversal": trav,
                     "cycles.intersection": isct, "cycles.fragment": frag, "cycles.throughput": thru})
        results = {"scene": {"name": "ring", "source": str(scenes_dir() / "ring.yaml"), "resolution": [16, 12],
                             "triangles": 646, "bsp": {"levels": level, "requested_levels": level,
                                                       "truncated": False}},
                   "mode": "rcast", "fps": fps,
                   "cycles": {"vertex": vert, "traversal": trav, "intersection": isct, "fragment": frag,
                              "throughput": thru, "latency": thru},
                   "factors": {"bsp.levels": lv, "arch.pipelines": n},
                   "timing": {"frames": 1, "units": busy_units(n)}}
        write_point(root, h, results, {"scene": "ring", "mode": "rcast", "resolution": [16, 12],
                                       "bsp": {"levels": lv}, "arch": {"pipelines": n}})
    write_rows(root, rows)
    return root


def _rows(table_html: str) -> list[list[str]]:
    return [re.findall(r"<t[dh][^>]*>(.*?)</t[dh]>", tr) for tr in re.findall(r"<tr>(.*?)</tr>", table_html)]


def test_a_null_level_beside_its_number_keeps_every_series(tmp_path):
    notes: list[str] = []
    series, summary = levels_balance(read([sweep_folder(tmp_path / "N")]).sweeps[0], notes)
    # both series, each with its two levels: the point asking for 6 by number shown
    assert [s["label"] for s in summary] == ["ring (pipelines=1)", "ring (pipelines=2)"]
    assert {k: [(p["point"], p["level"]) for p in pts] for k, pts in series.items()} == {
        ("ring", 1): [(2, 3), (4, 6)], ("ring", 2): [(3, 3), (5, 6)]}
    s1 = summary[0]
    assert (s1["floor_ln"], s1["closest_level"], s1["best_level"]) == (6, 6, 6)
    assert s1["ratio_at_floor"] == 398940 / 522870 and s1["fps_at_floor"] == MEASURED[(6, 1)][5]
    # the repeats left out are counted, and why
    assert notes == ["N: points 0 and 1 left out of the BSP-levels balance as repeats: each measured the same Ttrav, "
                     "Tisct, FPS and TThru as the point of its series at its level, bsp.levels null being the "
                     "builder's floor(ln n) (that point is shown)"]


def test_the_section_tables_every_series_and_every_points_ratio(tmp_path):
    section = sweeps_section(read([sweep_folder(tmp_path / "N")]), tmp_path)
    tables = re.findall(r"<table>.*?</table>", section.html, re.S)
    points, balance = _rows(tables[0]), _rows(tables[1])
    # the balance table: one row per series, none left out
    assert [r[0] for r in balance[1:]] == ["ring (pipelines=1)", "ring (pipelines=2)"]
    assert balance[1][2:5] == ["6", "0.7630", "437.4"]
    assert any(f.file == "bsp_balance_N.png" for f in section.figures)
    # the points table: every point's Ttrav / Tisct
    col = points[0].index("Ttrav / Tisct")
    ratios = {int(r[0]): r[col] for r in points[1:]}
    assert ratios == {0: "0.7630", 1: "0.7388", 2: "0.3305", 3: "0.3331", 4: "0.7630", 5: "0.7388"}


def test_points_of_one_level_that_differ_still_leave_their_series_out(tmp_path):
    """Two points at one level that measured differently cannot both be one curve's point: the
    series is left out of the balance, and the note says that they differ."""
    notes: list[str] = []
    series, summary = levels_balance(read([sweep_folder(tmp_path / "D", differ=True)]).sweeps[0], notes)
    assert series == {} and summary == []
    assert notes == ["D: 2 series (ring (pipelines=1) and ring (pipelines=2)): no balance curve, several points share "
                     "a level with different cycles or FPS (they differ in a factor the report cannot tell apart)"]
