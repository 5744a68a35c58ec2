"""Report section: Tables I-III of the thesis reproduced, ours beside the thesis per cell.

Where the rows come from:

* a ``tlm thesis`` folder (a :class:`~tlm.report.collect.Study` of kind ``thesis``): its
  ``thesis_comparison.csv``, one source per (study, scene);
* otherwise every run folder and sweep point whose scene is a thesis table's scene (ring, room,
  cornell) by its file, not its name (:func:`thesis_table`: a user's ``room.yaml``, or the built-in
  ``room``, is not the thesis's ``thesis/room``, and gets the note a scene without a thesis table
  gets), through :func:`tlm.experiments.thesis.comparison_rows`. Runs of one
  scene file whose resolved configs agree except for ``mode`` fill the columns of one table
  (:func:`_config_key`); every other run (every sweep point) is a source of its own.

Each table is laid out like the thesis's (metrics as rows, modes as columns); a cell
shows ours, the thesis's value and the relative error (ours - thesis) / thesis. Marks:
``†`` a calibrated cell (its row's ``calibrated``: fitted by the table the run used, not a
prediction), ``▲`` the slowest PM of the scene-mode in the thesis, ``●`` the slowest PM
in ours. A source whose resolution, photon count, sampling
(eye rays per pixel, light samples), pipeline count or clock differs from the thesis's is
still shown, marked *not comparable* with the reason (the one rule,
:func:`tlm.experiments.thesis.mismatches`); neither its table's summary, nor its study's
line, nor the report's first screen gives a median relative error for it, nor does its
figure annotate its errors: they would measure the setting, not the model.
"""

from __future__ import annotations

import html
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import quote

from tlm.config import MODES
from tlm.errors import quoted
from tlm.experiments.provenance import scene_identity
from tlm.experiments.thesis import (
    METRICS,
    PM_METRICS,
    THESIS,
    THESIS_SCENES,
    THESIS_SIZES,
    _ours,
    comparison_rows,
    median_words,
    run_mismatches,
    slowest_words,
    summarize,
    table_of,
)
from tlm.report.collect import Inputs, Run, Study
from tlm.report.common import Section, line_style, new_figure, save, some, untangle
from tlm.report.names import same_file, shown_paths
from tlm.report.numbers import printed, sig
from tlm.report.sweep_lines import column_texts
from tlm.scenes.loader import scenes_dir

TABLE_NUMBER = {"ring": "I", "room": "II", "cornell": "III"}
SCENE_TITLE = {"ring": "Scene with ring", "room": "Room scene", "cornell": "Cornell Box scene"}
MODE_TITLE = {"rcast": "RCast", "reflect": "Reflect", "refract": "Refract", "pmap": "PMap"}
UNITS = dict.fromkeys(PM_METRICS, "M cycles") | {"TThru": "M cycles", "FPS": "frames/s"}

MARK_CALIBRATED = "†"
MARK_SLOW_THESIS = "▲"
MARK_SLOW_OURS = "●"

MAX_TABLES_PER_SCENE = 4  # sources shown as tables per scene; a note counts the rest and names a few
MAX_FIGURE_SOURCES = 4  # sources drawn in a scene's figure


def fmt(v: float | None) -> str:
    """Our value in a table: four significant digits, trailing zeros kept, from 1,000 up whole and
    thousands separated (:func:`~tlm.report.numbers.sig`: ``6.410``, ``93.60``, ``11,920``)."""
    return "–" if v is None else sig(v)


def fmt_thesis(v: float | None, scene: str = "", mode: str = "", metric: str = "") -> str:
    """The thesis's value in a table as the thesis prints it: :data:`THESIS`'s literal of the cell where
    ``v`` is it (``43.0``, ``110``, ``3.037``: its own digits, not padded to four), else ``v`` to four
    significant digits without trailing zeros."""
    if v is None:
        return "–"
    given = THESIS.get(scene, {}).get(metric)
    lit = given[MODES.index(mode)] if given and mode in MODES else None
    return printed(lit) if lit is not None and float(lit) == float(v) else sig(v, zeros=False)


def fmt_error(e: float | None) -> str:
    """A relative error as a signed percentage with one decimal."""
    return "–" if e is None else f"{e:+.1%}"


@dataclass
class Source:
    """One table: the rows of one scene from one study, one run or a group of runs."""

    label: str
    scene: str
    rows: dict[tuple[str, str], dict] = field(default_factory=dict)  # (mode, metric) -> comparison row
    runs: list[Run] = field(default_factory=list)  # the run folders behind the rows
    study: Study | None = None
    not_comparable: list[str] = field(default_factory=list)  # why ours is not the thesis's setting
    unknown: str | None = None  # why comparability cannot be told

    named: str = ""  # the scene as the report names it (its file), where no run tells it

    @property
    def modes(self) -> list[str]:
        return [m for m in MODES if any(k[0] == m for k in self.rows)]

    @property
    def scene_label(self) -> str:
        """Our scene as the report names scenes (by its file: ``thesis/room``, not ``room``):
        the scenes of its runs, else the name its study knew it by."""
        labels = list(dict.fromkeys(r.scene_label for r in self.runs))
        return ", ".join(labels) if labels else self.named or self.scene

    def slowest(self, mode: str) -> tuple[str | None, str | None]:
        """The slowest PM of ``mode`` in the thesis and in ours (None: no such cell)."""
        cells = {k: self.rows.get((mode, k)) for k in PM_METRICS}
        if any(c is None for c in cells.values()):
            return None, None
        theirs = None if any(c["thesis"] is None for c in cells.values()) else \
            max(PM_METRICS, key=lambda k: cells[k]["thesis"])
        ours = max(PM_METRICS, key=lambda k: cells[k]["ours"])
        return theirs, ours


def thesis_table(run: Run) -> str | None:
    """The thesis table (``ring``, ``room``, ``cornell``) whose scene ``run``'s scene is, judged by
    its file, not its name (a user's ``room.yaml``, named ``room`` by its stem, and the built-in
    ``room`` are not the thesis's ``thesis/room``): by the ``scene_digest`` its ``results.json``
    recorded, the file as the run read it: the thesis's scene where that is a built-in thesis
    scene's identity now (:func:`~tlm.experiments.provenance.scene_identity`) or where its
    ``scene.source`` is that built-in file itself (edited since the run); any other file is not,
    whatever it holds now or wherever it is (h391: a user's ``scenes/cornell.yaml``, edited, is not
    Table III's once its folder is moved off this machine, nor once the file is reverted). A
    results.json without one (a run or sweep point of an older tlm) is judged by its
    ``scene.source`` as :func:`tlm.experiments.thesis.table_of` judges it (the file's identity
    where it is on this machine, else its place under a ``scenes`` folder), one with neither
    (nothing to tell the file by) by the scene's name. None: not a thesis scene."""
    scene = run.results.get("scene") or {}
    name = str(scene.get("name"))
    if name not in THESIS_SCENES:
        return None
    digest, source = run.results.get("scene_digest"), scene.get("source")
    builtin = scenes_dir() / f"{THESIS_SCENES[name]}.yaml"
    if isinstance(digest, str) and digest:
        if digest == scene_identity(builtin) or (source and same_file(source) == same_file(builtin)):
            return name
        return None
    if source:
        return name if table_of(str(source)) == name else None
    return name


def not_thesis_words(scene: str, label: str) -> str:
    """What a scene named as a thesis table's but of another file is: `` (scenes/room.yaml is not the
    thesis's Room scene, thesis/room)`` (``label`` empty: `` (not the thesis's ...)``); empty for a scene
    of another name."""
    if scene not in THESIS_SCENES:
        return ""
    return f" ({f'{label} is ' if label else ''}not the thesis's {SCENE_TITLE[scene]}, {THESIS_SCENES[scene]})"


def _study_table(study: Study, scene: str, cells: list[Run]) -> bool:
    """Whether the scene ``scene`` of a thesis study is the thesis table's own scene (by its file): that
    of its cells (:func:`thesis_table`); where they are gone, what the study said when it ran (its
    ``not_comparable`` naming the scene file as not the thesis's), else it is taken to be."""
    if scene not in THESIS:
        return False
    if cells:
        return thesis_table(cells[0]) == scene
    judged = study.meta.get("not_comparable")
    why = judged.get(scene) if isinstance(judged, dict) else None
    return not (isinstance(why, list) and any(str(w).startswith("the scene ") for w in why))


def mismatches(run: Run, scene: str) -> list[str]:
    """How ``run`` differs from the setting of the thesis's table for ``scene`` (empty: none):
    :func:`tlm.experiments.thesis.mismatches`, the one rule, of its results and config; its scene
    file judged as :func:`thesis_table` judges it (h391: a copy of the thesis's file, by the digest the
    run recorded, is the thesis's scene though the copy is not on this machine or was edited since)."""
    results = run.results
    if thesis_table(run) == scene:  # (the file as the run read it: not judged again as it is now)
        results = {**results, "scene": {**(results.get("scene") or {}), "source": None}}
    return run_mismatches(scene, results, run.config)


def _config_key(run: Run) -> str:
    """What runs of one table share: their resolved configs but ``mode``, and their scene file
    as the report names it (:attr:`~tlm.report.collect.Run.scene_label`, one name for one file).
    The config's ``scene`` is the path its config file gave, relative to that file: two configs
    in two folders that both say ``scene: room.yaml`` name two files."""
    if not run.config:
        return f"path:{run.path.resolve()}"
    return json.dumps({"scene file": run.scene_label, **{k: v for k, v in run.config.items() if k != "mode"}},
                      sort_keys=True, default=str)


def collect_sources(inputs: Inputs, notes: list[str]) -> dict[str, list[Source]]:
    """Sources per thesis scene, in input order; what cannot be tabled goes to ``notes``.

    Worked out once per ``inputs`` (the tables and the report's first screen both judge
    the same sources, and judging a run reads its scene files): a later call returns the
    same sources and adds the same notes."""
    memo = inputs.memo.get("tables.sources")
    if memo is None:
        said: list[str] = []
        memo = inputs.memo["tables.sources"] = (_collect_sources(inputs, said), said)
    notes.extend(memo[1])
    return memo[0]


def _fitted(run) -> frozenset[tuple[str, str]] | None:
    """The cells a run's instruction table was fitted to (:func:`~tlm.experiments.thesis_tables.fitted_cells` of
    its ``arch.programs``; None: the packaged table's); where that table can no longer be read, every cell a
    calibration may fit (:data:`~tlm.experiments.thesis_tables.CALIBRATED`): unknown, so no fitted cell passes
    for a prediction."""
    from tlm.arch.costs import load_programs
    from tlm.experiments.thesis_tables import CALIBRATED, fitted_cells

    table = (run.config.get("arch") or {}).get("programs") if isinstance(run.config, dict) else None
    if table is None:
        return None
    try:
        return fitted_cells(load_programs(table).calibration)
    except (OSError, ValueError):  # (an InputError is a ValueError: a table moved or changed since the run)
        return frozenset((scene, m) for scene in THESIS for _, m in CALIBRATED)


def _collect_sources(inputs: Inputs, notes: list[str]) -> dict[str, list[Source]]:
    by_scene: dict[str, list[Source]] = {s: [] for s in THESIS}
    in_study: set[Path] = set()
    for study in inputs.of_kind("thesis"):
        in_study.update(r.path.resolve() for r in inputs.study_cells(study))
        scenes: dict[str, list[dict]] = {}
        for row in study.rows:
            scenes.setdefault(str(row["scene"]), []).append(row)
        for scene, rows in scenes.items():
            # (its cells by their folder, DIR/<scene>/<mode>, not by the name in their file: the built-in ring,
            # its rows ring-2, is named ring as thesis/ring is)
            runs = inputs.study_cells(study, scene)
            if not _study_table(study, scene, runs):
                # (named in its file as a table's scene but not its file: 'not the thesis's ...'; an older study's
                # copy of thesis/ring, rows 'myring' of no table, is not said to be another file)
                named = runs[0].scene if runs and thesis_table(runs[0]) is None else scene
                notes.append(f"{study.path.name}: scene {quoted(inputs.study_scene(study, scene))} has no table in "
                             f"the thesis{not_thesis_words(named, '')}, left out of the tables")
                continue
            src = Source(f"thesis study {study.path.name}", scene, study=study, runs=runs,
                         named=_study_scene(study, scene))
            for row in rows:
                src.rows[(str(row["mode"]), str(row["metric"]))] = row
            _judge(src)
            by_scene[scene].append(src)
    groups: dict[tuple[str, str], list[Source]] = {}
    skipped = [r for r in inputs.runs if r.kind == "sweep-point" and inputs.of_kind("thesis") and thesis_table(r)]
    if skipped:
        notes.append(f"{len(skipped)} sweep points of thesis scenes are not tabled: a thesis study is among the "
                     "inputs (sweep points are tabled only without one)")
    no_table: dict[tuple[str, str], list[str]] = {}  # a scene with no thesis table (its words): the runs left out
    no_cycles: list[str] = []
    for run in inputs.runs:
        if run.path.resolve() in in_study or (skipped and run.kind == "sweep-point"):
            continue
        if thesis_table(run) is None:
            no_table.setdefault((run.scene, not_thesis_words(run.scene, shown_paths(run.scene_label))),
                                []).append(run.label)
            continue
        if not run.results.get("cycles") or run.results.get("fps") is None:
            no_cycles.append(run.label)
            continue
        rows = comparison_rows(run.scene, run.mode, _ours(run.results["cycles"], run.results["fps"]), _fitted(run))
        key = (run.scene, _config_key(run))
        src = next((s for s in groups.get(key, []) if run.mode not in s.modes), None)
        if src is None:
            src = Source(run.label, run.scene)
            groups.setdefault(key, []).append(src)
            by_scene[run.scene].append(src)
        else:
            src.label += f", {run.label}"
        src.runs.append(run)
        for row in rows:
            src.rows[(run.mode, row["metric"])] = row
    for (scene, why), labels in no_table.items():  # (a sweep of hundreds of points: one note, its count, a few labels)
        notes.append(f"{labels[0]}: scene {quoted(scene)} has no table in the thesis{why}, left out of the tables"
                     if len(labels) == 1 else f"scene {quoted(scene)} has no table in the thesis{why}: {len(labels)} "
                     f"runs of it left out of the tables ({some(labels)})")
    if no_cycles:
        notes.append(f"{no_cycles[0]}: no simulated cycles in results.json, left out of the tables"
                     if len(no_cycles) == 1 else f"{len(no_cycles)} runs with no simulated cycles in results.json "
                     f"left out of the tables ({some(no_cycles)})")
    for sources in by_scene.values():
        for src in sources:
            if src.study is None:
                _judge(src)
    return {s: v for s, v in by_scene.items() if v}


def _study_scene(study: Study, scene: str) -> str:
    """A thesis study's scene named by its file when the study's cells are gone: the entry of
    the study's config (``scenes:``) whose built-in file is the one the thesis table's scene is."""
    scenes = (study.meta.get("config") or {}).get("scenes") if isinstance(study.meta.get("config"), dict) else None
    if isinstance(scenes, list) and THESIS_SCENES.get(scene) in scenes:
        return THESIS_SCENES[scene]
    return ""


def _judge(src: Source) -> None:
    if not src.runs:
        judged = src.study.meta.get("not_comparable") if src.study is not None else None
        if isinstance(judged, dict):  # (judged by the same rule when the study ran)
            why = judged.get(src.scene)
            src.not_comparable = [shown_paths(str(w)) for w in why] if isinstance(why, list) else []
        else:
            src.unknown = "its run folders are missing, so its resolution and photon count are unknown"
        return
    seen: list[str] = []
    for run in src.runs:
        for m in mismatches(run, src.scene):
            m = shown_paths(m)  # (a scene file of the machine that ran it: by its place in the repository)
            if m not in seen:
                seen.append(m)
    src.not_comparable = seen


def study_summaries(inputs: Inputs, sources: dict[str, list[Source]] | None = None) -> list[tuple[Study, dict]]:
    """Each thesis study's :func:`~tlm.experiments.thesis.summarize` over its rows of the
    thesis's tables, its scenes judged as their tables are (:func:`collect_sources`): a
    scene not comparable with the thesis counts in no median. The study lines of this
    section and the report's first screen both quote it."""
    if not inputs.of_kind("thesis"):
        return []
    if sources is None:
        sources = collect_sources(inputs, [])
    out = []
    for study in inputs.of_kind("thesis"):
        named = {s: inputs.study_scene(study, s) for s in {str(r["scene"]) for r in study.rows}}
        tabled = {src.scene for srcs in sources.values() for src in srcs if src.study is study}  # (by its file)
        rows = [{**r, "scene": named[str(r["scene"])]} for r in study.rows if str(r["scene"]) in tabled]
        if rows:  # (the scenes by their files, as the tables name them: its words name them so)
            differ = {named[src.scene]: src.not_comparable for srcs in sources.values() for src in srcs
                      if src.study is study and src.not_comparable}
            out.append((study, summarize(rows, differ)))
    return out


# -- HTML ---------------------------------------------------------------------------------------

# (the tables' style, .tlm-tables, is in the page's head: tlm.report.html.CSS; a <style> in the body is not HTML)


def _cell_html(src: Source, mode: str, metric: str, slow: tuple[str | None, str | None]) -> str:
    e = html.escape
    cell_id = e(f"{src.scene}/{mode}/{metric}")
    row = src.rows.get((mode, metric))
    if row is None:
        return f'<td data-cell="{cell_id}" class="missing" title="not run">–</td>'
    cal = bool(row.get("calibrated"))  # (the row's own word: the cells its table was fitted to, not CALIBRATED's)
    ours_mark = f' <span class="mark-slow-ours" title="slowest PM in ours">{MARK_SLOW_OURS}</span>' \
        if slow[1] == metric else ""
    thesis_mark = f' <span class="mark-slow-thesis" title="slowest PM in the thesis">{MARK_SLOW_THESIS}</span>' \
        if slow[0] == metric else ""
    cal_mark = f' <span class="mark-calibrated" title="calibrated (fitted) cell">{MARK_CALIBRATED}</span>' \
        if cal else ""
    cls = ' class="calibrated"' if cal else ""
    return (f'<td data-cell="{cell_id}"{cls}><span class="ours">{e(fmt(row["ours"]))}</span>{ours_mark}<br>'
            f'<span class="thesis">{e(fmt_thesis(row["thesis"], src.scene, mode, metric))}</span>{thesis_mark}<br>'
            f'{_error_html(src, row)}{cal_mark}</td>')


def _error_html(src: Source, row: dict) -> str:
    """The cell's relative error, or ``n/c`` where ours is another setting than the thesis's
    (an error against it would measure the setting, not the model)."""
    if src.not_comparable:
        why = html.escape("not comparable: ours is " + "; ".join(src.not_comparable), quote=True)
        return f'<span class="err" title="{why}">n/c</span>'
    return f'<span class="err">{html.escape(fmt_error(row["rel_error"]))}</span>'


def _summary_line(rows: list[dict]) -> str:
    return _line(summarize(rows))


def _line(s: dict) -> str:
    """A :func:`~tlm.experiments.thesis.summarize` in words: the medians (of the comparable
    scenes' cells; where there is none, why) and the slowest-PM count."""
    only_calibrated = s["median_abs_rel_error_held_out"] is None and s["median_abs_rel_error_calibrated"] is not None
    parts = [] if only_calibrated else [median_words(s)]  # (cells all calibrated: no held-out median to deny)
    if s["median_abs_rel_error_calibrated"] is not None:
        parts.append(f"{'median |relative error| ' if only_calibrated else ''}over the "
                     f"{s['calibrated_cells_compared']} calibrated cells "
                     f"{s['median_abs_rel_error_calibrated']:.1%}")
    if s["scene_modes"]:
        parts.append(slowest_words(s))  # (qualified as the median is, where scenes are not comparable)
    return "; ".join(parts) if parts else "no cell with a thesis value"


def table_html(src: Source) -> str:
    """One thesis-style table of ``src`` (metrics as rows, modes as columns)."""
    e = html.escape
    w, h, n, tris = THESIS_SIZES[src.scene]
    slow = {m: src.slowest(m) for m in MODES}
    head = (f"Table {TABLE_NUMBER[src.scene]}. {SCENE_TITLE[src.scene]} (thesis: {tris:,} triangles, "
            f"{w}×{h} pixels, {n:,} photons). Ours: {src.label}, scene {src.scene_label}")
    flag = ""
    if src.not_comparable:
        flag = (f' <span class="not-comparable">Not comparable: ours is '
                f'{e("; ".join(src.not_comparable))}.</span>')
    elif src.unknown:
        flag = f' <span class="not-comparable">Comparability unknown: {e(src.unknown)}.</span>'
    lines = [f'<table class="thesis-table" data-scene="{e(src.scene)}" data-source="{e(src.label)}" '
             f'data-comparable="{"no" if src.not_comparable else "unknown" if src.unknown else "yes"}">',
             f"<caption>{e(head)}{flag}</caption>",
             "<thead><tr><th>metric</th>" + "".join(f"<th>{MODE_TITLE[m]}</th>" for m in MODES) + "</tr></thead>",
             "<tbody>"]
    for metric in METRICS:
        cells = "".join(_cell_html(src, m, metric, slow[m]) for m in MODES)
        lines.append(f"<tr><th>{e(metric)} ({e(UNITS[metric])})</th>{cells}</tr>")
    lines.append("</tbody></table>")
    if src.not_comparable:  # an error against another setting measures the setting, not the model
        summary = ("no relative error against the thesis: ours is " + "; ".join(src.not_comparable)
                   + " (n/c: not comparable; a run at the thesis's setting is, e.g. the built-in experiment's: "
                   "'tlm thesis thesis')")
    else:
        summary = _summary_line(list(src.rows.values()))
    lines.append(f'<p class="table-summary">{e(summary)}.</p>')
    return "\n".join(lines)


PER_ITEM = (("trav_cycles_per_ray", "TTrav per ray"), ("tests_per_ray", "triangle tests per ray"),
            ("frag_cycles_per_pixel", "TFrag per pixel"), ("vert_cycles_per_triangle", "TVert per triangle"))


def _column(values: list) -> list[str]:
    """A column of the per-item table: its numbers as :func:`fmt` writes a table's (``273.9``, ``1,112``), or,
    where :func:`~tlm.report.sweep_lines.column_texts` writes the column in scientific notation (numbers
    spanning 0.001 to 10 million), all of them so: one notation a column."""
    texts = column_texts(values, fmt)
    if any("e" in t for v, t in zip(values, texts) if isinstance(v, int | float) and not isinstance(v, bool)):
        return texts
    return [fmt(v) if isinstance(v, int | float) and not isinstance(v, bool) else t for v, t in zip(values, texts)]


def per_item_html(label: str, per_item: dict, names: dict[str, str] | None = None) -> str:
    """A thesis study's PM times per work item (``thesis_summary.json`` ``per_item``): ours
    and, in brackets, the thesis's time over our count of the same item. ``names``: each
    scene's name in the study (``room``) as the report names it (``thesis/room``)."""
    e = html.escape
    lines = [f'<table class="thesis-table per-item" data-source="{e(label)}">',
             f"<caption>Per work item, thesis study {e(label)}: ours (the thesis's time over our count)</caption>",
             "<thead><tr><th>scene / mode</th><th>rays traced</th>" + "".join(f"<th>{e(h)}</th>" for _, h in PER_ITEM)
             + "<th>tests per leaf</th></tr></thead>", "<tbody>"]
    items = list(per_item.values())
    n = len(items)
    # each column's numbers, ours and the thesis's, in one notation (_column: not 1381 beside 3.453e+04)
    texts = {k: _column([it["ours"].get(k) for it in items] + [it["thesis"].get(k) for it in items])
             for k, _ in PER_ITEM}
    leaf = _column([it.get("tests_per_leaf") for it in items])
    for i, (cell, it) in enumerate(per_item.items()):
        scene, _, mode = str(cell).rpartition("/")
        cell = f"{(names or {}).get(scene, scene)}/{mode}" if scene else cell
        tds = [f"<td>{it['rays']:,}</td>"]
        tds += [f"<td>{texts[k][i]} ({texts[k][n + i]})</td>" for k, _ in PER_ITEM]
        tds.append(f"<td>{leaf[i]}</td>")
        lines.append(f"<tr><th>{e(cell)}</th>{''.join(tds)}</tr>")
    lines.append("</tbody></table>")
    lines.append('<p class="legend">Both sides divide by our count of the item, so a row\'s ours / thesis is its '
                 "cell's ratio; read down a column to see whether the thesis's cost per item is the same in every "
                 "scene. The thesis's triangle tests per ray are implied by its Tisct at 2 cycles a ray and 3 a "
                 "triangle (§IV.A.3); ours are counted. In PMap, TVert per triangle includes the photon work.</p>")
    return "\n".join(lines)


LEGEND = (f"Each cell: ours (simulated), the thesis's value, the relative error (ours − thesis) / thesis. "
          f"{MARK_CALIBRATED} calibrated cell (fitted to the thesis, not a prediction); "
          f"{MARK_SLOW_THESIS} slowest PM of the scene-mode in the thesis; {MARK_SLOW_OURS} slowest PM in ours. "
          "Cycles in millions per frame, FPS in frames per second at the simulated clock.")
# where each kind of cell's error against the thesis is explained (how far ours is, and the measured cause)
FIDELITY_DOC, FIDELITY_PART = Path(__file__).resolve().parents[2] / "docs" / "fidelity.md", "by-cell"


def fidelity_html(out: Path) -> str:
    """Why cells differ from the thesis, pointing to docs/fidelity.md's "By cell": a link relative to the report
    folder ``out`` where ``out`` is inside the source checkout that holds the page (the committed ``plots/``:
    ``../docs/fidelity.md#by-cell``, which moves with the checkout); its name alone elsewhere: in an installed
    copy, which ships no docs, and for a report outside the checkout (``/tmp/r``), whose link would climb to the
    checkout's place on this machine and lead nowhere once the folder is copied or moved (h302). Either way the
    page names the file in words, "in tlm's source", so that a page mailed without the checkout still says where."""
    words = "docs/fidelity.md, “By cell”"
    if FIDELITY_DOC.is_file() and Path(out).resolve().is_relative_to(FIDELITY_DOC.parents[1]):
        href = quote(os.path.relpath(FIDELITY_DOC, Path(out).resolve()).replace(os.sep, "/")) + "#" + FIDELITY_PART
        words = f'<a href="{html.escape(href)}">{html.escape(words)}</a> in tlm\'s source'  # (named: a mailed page)
    else:
        words = f"{html.escape(words)} in tlm's source"
    return (f'<p class="legend">Why a cell is far from the thesis: each kind of cell, how far ours is and the '
            f"measured cause, in {words}.</p>")


# -- figure -------------------------------------------------------------------------------------

def _scene_figure(scene: str, sources: list[Source], out: Path, notes: list[str]):
    cyc = [m for m in METRICS if m != "FPS"]
    fig = new_figure(11.5, 4.8)
    gs = fig.add_gridspec(1, 2, width_ratios=[5, 1.4])
    ax, axf = fig.add_subplot(gs[0]), fig.add_subplot(gs[1])
    group = len(cyc) + 1
    step = 0.7 / (len(sources) + 1)
    dropped = []

    def draw(axis, x0, mode, metric, first):
        t = THESIS[scene][metric][MODES.index(mode)]
        cal = any(bool((src.rows.get((mode, metric)) or {}).get("calibrated")) for src in sources)
        axis.plot([x0], [t], linestyle="none", marker="D" if cal else "o", markersize=6, markerfacecolor="white",
                  markeredgecolor="black", label=("thesis, calibrated cell" if cal else "thesis (Tables I–III)")
                  if first.setdefault(("t", cal), True) else None)
        first[("t", cal)] = False
        for i, src in enumerate(sources):
            row = src.rows.get((mode, metric))
            if row is None:
                continue
            o = row["ours"]
            x = x0 + step * (i + 1)
            if o is None or o <= 0:
                dropped.append(f"{src.label} {mode} {metric} = {o}")
                continue
            style = line_style(i + 1)
            axis.plot([x0, x], [t, o], color=style["color"], linewidth=0.6, linestyle=":")
            axis.plot([x], [o], linestyle="none", marker=style["marker"], color=style["color"], markersize=5,
                      markeredgecolor="black", markeredgewidth=0.4,
                      label=f"ours: {src.label} ({src.scene_label})" if first.setdefault(("o", i), True) else None)
            first[("o", i)] = False
            if row["rel_error"] is not None and not src.not_comparable:  # (n/c: no error, as in its table)
                notes_drawn.append(axis.annotate(f"{row['rel_error']:+.0%}", (x, o), xytext=(0, 4),
                                                 textcoords="offset points", fontsize=6.5, va="bottom",
                                                 ha="center", color="#333"))

    first: dict = {}
    notes_drawn: list = []  # the relative-error labels
    ticks, labels = [], []
    for mi, mode in enumerate(MODES):
        base = mi * group
        if mi % 2:
            ax.axvspan(base - 0.5, base + len(cyc) - 0.3, color="#f0f0f0", zorder=0)
        ax.text(base + (len(cyc) - 1) / 2, 1.01, MODE_TITLE[mode], transform=ax.get_xaxis_transform(),
                ha="center", va="bottom", fontsize=9)
        if not any((mode, metric) in src.rows for src in sources for metric in METRICS):
            ax.text(base + (len(cyc) - 1) / 2, 0.02, "ours: not run", transform=ax.get_xaxis_transform(),
                    ha="center", va="bottom", fontsize=8, color="#444")
        for k, metric in enumerate(cyc):
            draw(ax, base + k, mode, metric, first)
            ticks.append(base + k + step * len(sources) / 2)
            labels.append(metric)
        draw(axf, mi, mode, "FPS", first)
    ax.set_yscale("log")
    ax.set_xticks(ticks, labels=labels, rotation=90, fontsize=7)
    ax.set_ylabel("millions of cycles per frame (log)")
    ax.set_xlabel("metric, grouped by mode")
    ax.grid(axis="y", which="major", linewidth=0.4, color="#bbb")
    axf.set_yscale("log")
    axf.set_xticks([i + step * len(sources) / 2 for i in range(len(MODES))],
                   labels=[MODE_TITLE[m] for m in MODES], rotation=90, fontsize=7)
    axf.set_ylabel("frames per second (log)")
    axf.set_xlabel("mode")
    axf.set_title("FPS", fontsize=9)
    axf.grid(axis="y", which="major", linewidth=0.4, color="#bbb")
    for a in (ax, axf):
        lo, hi = a.get_ylim()
        a.set_ylim(lo / 1.6, hi * 3.0)  # room for the error labels above the highest marker and below the lowest
    ax.set_xlim(-0.7, len(MODES) * group - 1.3)
    axf.set_xlim(-0.5, len(MODES) - 0.5 + step * (len(sources) + 1))  # (the labels stay inside the panel)
    handles, names = [], []
    for a in (ax, axf):
        for hnd, name in zip(*a.get_legend_handles_labels()):
            if name not in names:
                handles.append(hnd)
                names.append(name)
    order = sorted(range(len(names)), key=lambda i: not names[i].startswith("thesis"))
    handles, names = [handles[i] for i in order], [names[i] for i in order]
    fig.legend(handles, names, loc="outside lower center", ncol=min(3, len(names)), fontsize=7, frameon=False)
    flag = ""
    if any(s.not_comparable for s in sources):
        flag = (" (not comparable: another setting, no errors shown)" if all(s.not_comparable for s in sources)
                else " (some sources not comparable: no errors on them)")
    fig.suptitle(f"Table {TABLE_NUMBER[scene]}, {SCENE_TITLE[scene]}: ours ({_our_scenes(sources)}) against the "
                 f"thesis{flag}", fontsize=11)
    for t in notes_drawn:  # (the y limits leave them room: the layout ignores them)
        t.set_in_layout(False)
    untangle(fig, notes_drawn, ((0, 4), (0, -4)))
    if dropped:
        notes.append(f"Table {TABLE_NUMBER[scene]} figure: values that cannot go on a log axis left out: "
                     f"{', '.join(dropped)}")
    caption = (f"Simulated cycles per PM and throughput (left, millions of cycles per frame) and frame rate (right) "
               f"per mode, ours of {_our_scenes(sources)}: hollow circles the thesis's Table {TABLE_NUMBER[scene]} "
               "(diamonds: calibrated cells), filled markers ours, annotated with the relative error, above the "
               "marker or, where that would cover another, below it (none on a source "
               "not comparable with the thesis: it would measure the setting, not the model).")
    return save(fig, out, f"tables_{scene}.png",
                f"Table {TABLE_NUMBER[scene]} ({SCENE_TITLE[scene]}): ours ({_our_scenes(sources)}) against the thesis",
                caption)


def _our_scenes(sources: list[Source]) -> str:
    """The scenes of ``sources``, as the report names them (their files)."""
    return ", ".join(dict.fromkeys(s.scene_label for s in sources))


# -- section ------------------------------------------------------------------------------------

def tables_section(inputs: Inputs, out: Path) -> Section:
    """Tables I-III reproduced: one HTML table per (scene, source) and one figure per scene."""
    out = Path(out)
    section = Section("tables", "Tables I–III: ours against the thesis")
    sources = collect_sources(inputs, section.notes)
    if not sources:
        files = list(THESIS_SCENES.values())
        section.absent = ("no run or thesis study among the inputs has simulated cycles of a thesis scene file "
                          f"({', '.join(files[:-1])} or {files[-1]}, or a byte copy of one; a scene of any other "
                          "file is not one, even one "
                          f"named {', '.join(list(THESIS_SCENES)[:-1])} or {list(THESIS_SCENES)[-1]})")
        return section
    parts = ['<div class="tlm-tables">']
    for study, summary in study_summaries(inputs, sources):
        parts.append(f'<p class="study-summary">Thesis study {html.escape(study.path.name)}: '
                     f"{html.escape(_line(summary))}.</p>")
    parts.append(f'<p class="legend">{html.escape(LEGEND)}</p>')
    parts.append(fidelity_html(out))
    for scene, srcs in sources.items():
        shown = srcs[:MAX_TABLES_PER_SCENE]
        if len(srcs) > len(shown):
            rest = some([s.label for s in srcs[len(shown):]])
            section.notes.append(f"Table {TABLE_NUMBER[scene]}: {len(srcs) - len(shown)} more sources left out of the "
                                 f"tables and the figure (at most {MAX_TABLES_PER_SCENE} per table): {rest}")
        for src in shown:
            parts.append(table_html(src))
            if src.not_comparable:
                section.notes.append(f"{src.scene_label} ({src.label}) is not comparable with the thesis's Table "
                                     f"{TABLE_NUMBER[scene]}: ours is {'; '.join(src.not_comparable)}")
            elif src.unknown:
                section.notes.append(f"{src.scene_label} ({src.label}), beside the thesis's Table "
                                     f"{TABLE_NUMBER[scene]}: comparability unknown, {src.unknown}")
        drawn = shown[:MAX_FIGURE_SOURCES]
        if len(shown) > len(drawn):
            section.notes.append(f"Table {TABLE_NUMBER[scene]} figure: drawn for the first {len(drawn)} sources only; "
                                 f"{', '.join(s.label for s in shown[len(drawn):])} are in the tables")
        section.figures.append(_scene_figure(scene, drawn, out, section.notes))
    for study in inputs.of_kind("thesis"):
        if study.meta.get("per_item"):
            names = {str(c).rpartition("/")[0]: inputs.study_scene(study, str(c).rpartition("/")[0])
                     for c in study.meta["per_item"]}
            parts.append(per_item_html(study.path.name, study.meta["per_item"], names))
    parts.append("</div>")
    section.html = "\n".join(parts)
    return section

