"""The report of a sweep that crosses ``arch.pipelines`` with many other factors (the h195 probe's
216-point sweep: N x FIFO depth x packet size x cache pairs x block words).

1. §3 drew an idle figure per combination of the other factors (72 of 97 figures), and the scaling
   figure and the summary's a line per combination, a legend of 72 entries; "Does it scale" was a
   sentence per combination. Now combinations whose curves are the same are drawn once, at most
   a few distinct ones are drawn (the highest and lowest speed-ups; the notes name the rest and
   say that sweep.csv holds them), and the summary gives the range, the best and the worst.
2. A legend that leaves the axes no room leaked matplotlib's "constrained_layout not applied"
   warning to stderr.
3. A figure's file name cut off the last factor's value (``..._cache_pairs_1_cache_b.png``): the
   factors' names are shortened to their last dotted part before a value is cut.

The sweep folder here holds the rows only (``sweep.yaml``, ``sweep.jsonl``): all that the idle
figures read; the eq. 5.2 fits are given to the report as :func:`fit_sources` gives them.
"""

from __future__ import annotations

import itertools
import json
import re
import warnings
from pathlib import Path

import yaml

from tlm.experiments import scaling as eq52
from tlm.report import scaling as scaling_mod
from tlm.report.collect import read
from tlm.report.common import NAME_MAX, figure_name, new_figure, write_png
from tlm.report.scaling import scaling_section
from tlm.report.summary import summary_section

IDLE_FIGURES, CURVES = 6, 6  # (scaling.MAX_IDLE, MAX_CURVES: idle figures drawn, curves per panel)
NS, FIFOS, PACKETS, PAIRS = (1, 2, 4), (16, 64, 256, 4096), (16, 64, 256), (1, 2)
OTHERS = ("arch.fifo_depth", "arch.packet_size", "cache.pairs")


def _throughput(n, f, p, c) -> float:  # (distinct for every combination but the two FIFO depths 16 and 64)
    return 1e6 / n ** (0.3 + 0.01 * max(FIFOS.index(f), 1) + 0.03 * PACKETS.index(p) + 0.1 * PAIRS.index(c))


def sweep_folder(folder: Path) -> Path:
    """A 72-point sweep over N crossed with three other factors, its rows only."""
    folder.mkdir(parents=True)
    grid = {"arch.pipelines": list(NS), "arch.fifo_depth": list(FIFOS), "arch.packet_size": list(PACKETS),
            "cache.pairs": list(PAIRS)}
    points, rows = [], []
    for i, (n, f, p, c) in enumerate(itertools.product(NS, FIFOS, PACKETS, PAIRS)):
        factors = {"arch.pipelines": n, "arch.fifo_depth": f, "arch.packet_size": p, "cache.pairs": c}
        points.append({"point": i, "hash": f"h{i:03d}", "factors": factors})
        t = _throughput(n, f, p, c)
        rows.append({"point": i, "hash": f"h{i:03d}", "status": "ok", **factors, "arch.scheduler": "static",
                     "scene": "cornell", "mode": "rcast", "fps": 1e8 / t, "cycles.throughput": t,
                     **{f"idle.{pm}": round(1 - 1e5 / t, 6) for pm in ("vertex", "traversal", "intersection",
                                                                        "fragment")}})
    (folder / "sweep.yaml").write_text(yaml.safe_dump({"sweep": "many.yaml", "grid": grid, "points": points},
                                                      sort_keys=False))
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


def _fits() -> dict[tuple, dict]:
    """Eq. 5.2's fits of the sweep, a pair (latency, throughput) per combination of the other factors."""
    fits = {}
    for f, p, c in itertools.product(FIFOS, PACKETS, PAIRS):
        group = eq52.combination_text(dict(zip(OTHERS, (f, p, c), strict=True)))
        t1 = _throughput(1, f, p, c)
        rows = [{"pipelines": n, "simulated": _throughput(n, f, p, c), "analytical": _throughput(n, f, p, c),
                 "speedup": t1 / _throughput(n, f, p, c)} for n in NS]
        for target in eq52.TARGETS:
            fits[eq52.fit_key("cornell", "rcast", "static", target, group)] = {
                "rows": rows, "A": 1.0, "B": 2.0, "max_abs_rel_error": 0.01}
    return fits


def _inputs(tmp_path, monkeypatch):
    sw = sweep_folder(tmp_path / "many")
    inputs = read([sw])
    (tmp_path / "rep").mkdir()

    def sources(inputs_, notes, studies=True):  # (as fit_sources gives a sweep's fits: no results folders here)
        return [(sw.name, sw.name, _fits(), {"cornell": "cornell"}, sw, "")]

    monkeypatch.setattr(scaling_mod, "fit_sources", sources)
    return inputs


def _drawn(monkeypatch) -> list:
    figs, real = [], scaling_mod.write_png

    def keep(fig, path):
        figs.append(fig)
        return real(fig, path)

    monkeypatch.setattr(scaling_mod, "write_png", keep)
    return figs


def test_idle_figures_of_many_combinations_are_bounded_and_the_notes_say_where_the_rest_are(tmp_path, monkeypatch):
    inputs = _inputs(tmp_path, monkeypatch)
    sec = scaling_section(inputs, tmp_path / "rep")
    idle = [f for f in sec.figures if f.file.startswith("idle_")]
    # 24 combinations, 18 distinct (FIFO depths 16 and 64 draw one figure): was a figure each
    assert len(idle) == IDLE_FIGURES, [f.title for f in idle]
    assert all("The 24 combinations of the other factors draw 18 distinct idle figures" in f.caption for f in idle)
    said = [n for n in sec.notes if "distinct idle figures not drawn" in n]
    assert len(said) == 1 and "sweep.csv" in said[0] and said[0].startswith("many: cornell: 12 of 18 "), said
    assert sec.html.count("<details>") == IDLE_FIGURES  # (a table per figure drawn)


def test_the_scaling_figure_draws_a_few_curves_of_many_combinations(tmp_path, monkeypatch):
    inputs = _inputs(tmp_path, monkeypatch)
    figs = _drawn(monkeypatch)
    sec = scaling_section(inputs, tmp_path / "rep")
    scaling = [f for f in sec.figures if f.file.startswith("scaling_")]
    assert len(scaling) == 1
    assert "not drawn" in scaling[0].caption and "sweep.csv holds every point" in scaling[0].caption
    fig = figs[[f.file for f in sec.figures].index(scaling[0].file)]
    for ax in fig.axes:  # (latency and throughput: simulated, eq. 5.2 and no slowest variant per curve)
        assert len(ax.get_lines()) <= 2 * CURVES + 1, len(ax.get_lines())
        assert len(ax.get_legend().get_texts()) <= 2 * CURVES + 1


def test_the_summary_says_the_range_of_many_speedups_in_one_bounded_sentence(tmp_path, monkeypatch):
    inputs = _inputs(tmp_path, monkeypatch)
    lead = " ".join(re.sub(r"<[^>]+>", " ", summary_section(inputs, tmp_path / "rep").lead).split())
    said = re.search(r"Does it scale: (.*?) \(static tiles", lead)
    assert said, lead
    assert len(said.group(1)) < 400, said.group(1)  # (was a clause per combination: 24 of them)
    assert said.group(1).startswith("from ") and " over 24 curves; best cornell [" in said.group(1)
    assert " worst cornell [" in said.group(1)


def test_a_legend_that_leaves_the_axes_no_room_leaks_no_warning(tmp_path):
    fig = new_figure(4, 2)
    ax = fig.subplots()
    for i in range(60):
        ax.plot([0, 1], [i, i], label=f"a long label of a line, number {i}")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        write_png(fig, tmp_path / "f.png")
    assert (tmp_path / "f.png").is_file()


def test_a_long_combination_keeps_every_value_in_the_file_name(tmp_path):
    combination = "arch.fifo_depth = 4096, arch.packet_size = 256, cache.pairs = 1, cache.block_words = 1024"
    name = figure_name(tmp_path, "idle", "outT", "cornell", combination, key="a")
    assert name == "idle_outT_cornell_fifo_depth_4096_packet_size_256_pairs_1_block_words_1024.png"
    assert len(name) <= NAME_MAX
    # (names that fit are as they were: the committed plots/ among them)
    assert figure_name(tmp_path, "idle", "scaling_cornell", "cornell") == "idle_scaling_cornell_cornell.png"
    assert figure_name(tmp_path, "sweep", "design_space", "arch.page_miss_cycles") == \
        "sweep_design_space_arch_page_miss_cycles.png"
    assert figure_name(tmp_path, "idle", "cross", "cornell", "bsp.levels = 5") == "idle_cross_cornell_bsp_levels_5.png"


def test_combinations_merge_only_where_every_number_drawn_is_the_same():
    """Two combinations of the same simulated cycles but another eq. 5.2 fit (A, its curve, its error) are two
    curves: merged, the figure drew one fit's A and the caption's largest error left the other's out (a review)."""
    rows = [{"pipelines": n, "simulated": 100.0 / n, "analytical": 100.0 / n, "speedup": float(n)} for n in (1, 2, 4)]
    other = [{**r, "analytical": r["analytical"] * 1.5} for r in rows]
    fits = {}
    for group, (a, drawn) in {"fifo_depth = 8": (1.0, rows), "fifo_depth = 16": (9.0, other)}.items():
        for target in eq52.TARGETS:
            fits[eq52.fit_key("cornell", "rcast", "static", target, group)] = {
                "rows": drawn, "A": a, "B": 2.0, "max_abs_rel_error": 0.5 if a > 1 else 0.01}
    out, note = scaling_mod.bounded_fits(fits, "sweep.csv")
    assert sorted({f["A"] for f in out.values()}) == [1.0, 9.0], (out.keys(), note)
    assert "identical" not in " ".join(str(k) for k in out)
    same = {k: {**v, "A": 1.0, "rows": rows, "max_abs_rel_error": 0.01} for k, v in fits.items()}
    merged, _ = scaling_mod.bounded_fits(same, "sweep.csv")  # (every number the same: one curve, both named)
    assert len(merged) == len(eq52.TARGETS) and "identical" in " ".join(str(k) for k in merged), merged.keys()
