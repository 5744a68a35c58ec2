"""Reproduce Tables I-III of the thesis, and calibrate the PM programs on their RCast column.

An experiment file (``configs/thesis.yaml``)::

    base: {render: {light_samples: 1, spp: 1}}   # a run config applied to every cell
    scenes: [thesis/ring, thesis/room, cornell]   # the thesis's three scenes
    modes: [rcast, reflect, refract, pmap]

Every key is optional, as in every study file (:func:`tlm.experiments.study.read_study`):
without ``base`` each cell runs at the default settings (``tlm params``: the scene's own
resolution, 4 eye rays and 4 light samples per pixel, not the thesis's 1 and 1), without
``scenes`` the thesis's three, without ``modes`` all four. A scene or a mode may be listed
once, and so may a thesis table's scene (a copy of its file beside it is refused).

Which table a scene is set beside is its file, not its name (:func:`scene_keys`: an unchanged
copy ``myring.yaml`` of ``thesis/ring`` is Table I's, named ``ring`` in the rows and the folder
``DIR/ring``; a user's ``room.yaml``, or ``bunny.yaml``, has no table: its rows no thesis value,
``DIR/<stem>``, a number added where two share a stem, ``room-2``). Whether a table's scene is
comparable, at the thesis's setting, is the one rule of
comparability, :func:`~tlm.experiments.thesis_setting.mismatches` (its names are
re-exported here): the summary's medians, the report's tables and ``tlm calibrate``'s
refusal to overwrite the packaged table all follow it. A scene that is not comparable keeps
its cells in the CSV, each saying so (``comparable`` false, ``not_comparable`` why), but gives
no median: it would measure the setting, not the model.

``tlm thesis FILE --out DIR`` renders every scene once in the last (largest) mode; the
modes are cumulative, so each smaller mode's frames are a subset of that render and
its run folder is written from it without rendering again (``DIR/<scene>/<mode>``,
each with its own simulation). Then ``DIR/thesis_comparison.csv`` has one row per
(scene, mode, metric) with the columns ``scene, mode, metric, thesis, ours,
rel_error, calibrated, comparable, not_comparable`` (cycles in millions as in the tables,
FPS in frames per second; ``comparable`` false where the cell's scene is not the thesis's
at its setting, ``not_comparable`` then how, in the summary's words; both empty where the
thesis has no value), and ``DIR/thesis_summary.json`` the median absolute relative error
over the held-out cells of the comparable scenes that are predictions of their own
(``median_abs_rel_error_predicted``; ``not_predictions``: the held-out cells left out of it and why,
:data:`NOT_PREDICTIONS`: TVert in Reflect and Refract, the fitted RCast TVert again, and FPS, the clock
over TThru; ``median_abs_rel_error_held_out``: the median over every held-out cell, those
included), (``not_comparable``: why the others are
left out, keyed by the scene as the CSV's ``scene`` column names it; ``median_withheld``:
the same in words, naming the scene as the printout does; ``scenes``: the one name -> the
other, ``ring`` -> ``thesis/ring``; ``no_table``: a scene without a table -> a line saying so, which
``tlm thesis`` prints) and, per scene-mode, whether our slowest PM is the thesis's. A scene named as
a table's but of another file (:func:`judged_table`) is judged as that table's: its rows say
``comparable`` false, ``the scene room.yaml (the thesis's is thesis/room)``, and it counts in no median.

``tlm calibrate FILE`` fits the free parameters of the instruction table (the ``scale``
of each programmable PM, and the ``record_cycles`` of the Traversal and Fragment PMs)
by least squares on the relative error of the RCast column's TVert, TTrav and TFrag
cells of the three tables (9 cells, 5 parameters) and writes the table (by default the one
the study uses: its ``base.arch.programs``, else the packaged ``tlm/arch/programs.yaml``).
Every other cell is a prediction. It needs at least two of the tables' scenes (one gives
one cell per PM, fewer than the Traversal and Fragment PMs' two parameters each) and the
``rcast`` mode among the study's modes (the others are not fitted). Its report's
``not_comparable`` says how the study's setting is not the thesis's: such a fit is never
written over the packaged table (:func:`tlm.api.write_calibration`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from tlm.arch.costs import PROGRAMMABLE, Programs
from tlm.config import MODES, RunConfig, config_from_dict, file_folder, to_dict
from tlm.config_words import with_overrides
from tlm.errors import InputError, quoted
from tlm.experiments.calibrate_fit import fit as _fit
from tlm.experiments.calibrate_fit import (  # noqa: F401  (those this module does not use: re-exported)
    fit_scale,
    fit_scale_and_records,
    fit_statistics,
    fitted_parameters,
    held_out,
    norm_per_frame,
    write_calibrated,
)
from tlm.experiments.provenance import identities_remembered, scene_label
from tlm.experiments.run import RenderResult, programs_for, render, simulate_render, write_run
from tlm.experiments.run_warnings import unread_overrides
from tlm.experiments.study import read_study, refuse_own_keys, refuse_set, run_study, with_set
from tlm.experiments.thesis_setting import (  # noqa: F401  (those this module does not use: re-exported)
    NOT_SETTING,
    THESIS_CLOCK_HZ,
    THESIS_SAMPLING,
    THESIS_SCENES,
    THESIS_SIZES,
    judged_table,
    mismatches,
    no_table,
    photons_of,
    run_mismatches,
    scene_keys,
    setting_mismatches,
    table_of,
    thesis_setting,
)
from tlm.experiments.thesis_tables import (  # noqa: F401  (re-exported: their home until now)
    CALIBRATED,
    COLUMNS,
    FIT_PMS,
    FIT_RECORDS,
    METRICS,
    NOT_PREDICTIONS,
    OURS_CYCLES,
    PM_METRICS,
    THESIS,
    comparison_rows,
    describe_rows,
    fitted_cells,
    not_prediction,
    thesis_value,
    with_comparable,
)
from tlm.experiments.thesis_tables import ours as _ours
from tlm.experiments.thesis_text import (  # noqa: F401  (all but fixed: re-exported, their home until now)
    describe_items,
    fixed,
    median_words,
    slowest_words,
)
from tlm.progress import Timer, progress_bar
from tlm.render.planner import plan
from tlm.scenes.loader import resolve_scene_path
from tlm.storage import SAID
from tlm.storage import warn as _warn


def load_study(path: Path, overrides: tuple[str, ...] = ()) -> tuple[dict, list[str], list[str], Path]:
    """``(base, scenes, modes, folder)`` of the study file ``path``, every cell's config checked. ``overrides``:
    ``tlm thesis --set`` strings, applied to ``base`` as ``tlm run --set`` applies them; one of ``scene`` or ``mode``
    (each cell's, from ``scenes`` and ``modes``) is refused, and a bad key or value (named: FILE ``with --set``)."""
    return _study(path, overrides)[:4]


def _study(path: Path, overrides: tuple[str, ...] = ()) -> tuple[dict, list[str], list[str], Path, dict]:
    """:func:`load_study` and each scene's ``(key, table)``: :func:`scene_keys` once a study (it reads every file)."""
    raw, base, src = read_study(path, ("scenes", "modes"))
    for key in ("scene", "mode"):
        if key in base:
            raise InputError(f"is set by '{key}s', not in base", source=src, key=f"base.{key}")
    folder = file_folder(path)  # (a pipe's, <(...): the working folder's, as its paths were typed)
    label = src  # (what a cell's config is named by in its errors)
    if overrides:
        base = with_set(base, overrides, [folder], warn=False)  # (a --set scene, refused below: not warned of, h455)
        refuse_own_keys(overrides, ("scenes", "modes"), src)
        refuse_set(overrides, {k: f"set by the study's {k}s, one cell each: list them under {k}s in the study "
                                  "file, not by --set" for k in ("scene", "mode")}, src)
        label = with_overrides(src)
        config_from_dict(base, label)  # (the base alone first: a bad --set named as tlm run names it)
    scenes = raw.get("scenes", list(THESIS_SCENES.values()))
    modes = raw.get("modes", list(MODES))
    if not isinstance(scenes, list) or not scenes or not all(isinstance(s, str) for s in scenes):
        raise InputError(f"{quoted(scenes)} must be a non-empty list of scene names or paths", source=src, key="scenes")
    if not isinstance(modes, list) or not modes or any(m not in MODES for m in modes):
        raise InputError(f"{quoted(modes)} must be a non-empty list of {', '.join(MODES)}", source=src, key="modes")
    twice = sorted({m for m in modes if modes.count(m) > 1}, key=MODES.index)
    if twice:  # (each mode writes DIR/<scene>/<mode> and its rows once: a second one would be dropped)
        raise InputError(f"{', '.join(repr(m) for m in twice)} {'is' if len(twice) == 1 else 'are'} listed twice "
                         "(list each mode once)", source=src, key="modes")
    for s in scenes:
        for m in modes:
            config_from_dict({**base, "scene": s, "mode": m}, f"{label} (scene {s}, mode {m})")
    files: dict[Path, str] = {}
    for s in scenes:  # each scene writes DIR/<key> and its rows: one file, one scene (scene_keys: one key each)
        file = resolve_scene_path(s, folder, src, "scenes").resolve()
        if file in files:
            raise InputError(f"{quoted(files[file])} and {quoted(s)} are the same scene (list it once)"
                             if files[file] != s else f"{quoted(s)} is listed twice (list it once)", source=src,
                             key="scenes")
        files[file] = s
    keys = scene_keys(scenes, folder, src)  # (two scenes of one table, by their files' bytes: refused)
    return base, scenes, sorted(set(modes), key=MODES.index), folder, keys


def restrict(res: RenderResult, cfg: RunConfig) -> RenderResult:
    """The render of a smaller mode, cut out of a render of a larger one (same settings); its
    host seconds are the shared stages' and its own passes' (not the passes it leaves out)."""
    p = plan(res.scene, cfg)
    missing = [n for n in p.run_names if n not in res.work]
    if missing:
        raise ValueError(f"the render lacks the passes {missing}")
    keep = p.run_names
    pm = "pmap" in keep
    seconds = {k: v for k, v in res.timer.seconds.items()
               if not (k.startswith("pass_") and k[len("pass_"):] not in keep) and (pm or k != "photon_trace")}
    return replace(res, cfg=cfg, plan=p, timer=Timer(seconds),
                   radiance={k: res.radiance[k] for k in keep if k in res.radiance},  # (fgather: work only)
                   work={k: res.work[k] for k in keep}, photons=res.photons if pm else None,
                   error=res.error if pm else None, timing=None)


# -- per work item: where the cycles of a cell go -------------------------------------------------

RAY_KEYS = ("primary_rays", "secondary_rays", "shadow_rays", "rays")
TEST_KEYS = ("tri_tests", "shadow_tri_tests")


def _sum_keys(work: dict, keys: tuple[str, ...]) -> int:
    return int(sum(v for k, v in work.items() if k in keys))


def per_item(scene: str | None, mode: str, results: dict) -> dict[str, Any]:
    """A cell's PM times per work item, ours beside what the thesis's time implies (``scene``: the
    cell's table, :func:`scene_keys`; None: no thesis column).

    The thesis gives times, not counts, so its per-item figures divide its time by *our*
    count of the item (the same pixels, triangles and photons; rays as our scene traces
    them): ``TTrav`` per traced ray, ``TFrag`` per pixel, ``TVert`` per triangle (in PMap
    the Vertex PM's photon work too), and triangle tests per ray implied by ``Tisct``,
    ``(Tisct - 2 rays) / 3 / rays`` (the Intersection PM loads a ray in two cycles and a
    triangle in three, §IV.A.3; pipeline drains and page misses are left out). Ours are
    our times over the same counts, and our counted triangle tests per ray. Both sides
    divide by our count, so a row's ``ours / thesis`` is its cell's ratio; what the table
    shows is how the thesis's cost per item compares across scenes and modes (a cost that
    is the same per item in every scene is a per-item cost). ``tests_per_leaf`` is ours
    only: triangles tested per leaf visited, the BSP's leaf size as the rays see it.
    """
    work: dict[str, int] = {}
    for counts in results["work"].values():
        for k, v in counts.items():
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                work[k] = work.get(k, 0) + v
    for k, v in ((results.get("photons") or {}).get("work") or {}).items():
        work[k] = work.get(k, 0) + v
    rays = _sum_keys(work, RAY_KEYS)
    tests = _sum_keys(work, TEST_KEYS)
    leaves = _sum_keys(work, ("leaf_visits", "shadow_leaf_visits"))
    pixels = int(results["primary"]["pixels"])
    triangles = int(results["scene"]["triangles"])
    cyc = results["cycles"]
    ours = {"TTrav": cyc["traversal"], "Tisct": cyc["intersection"], "TFrag": cyc["fragment"],
            "TVert": cyc["vertex"]}
    theirs = {m: (None if thesis_value(scene, mode, m) is None else thesis_value(scene, mode, m) * 1e6)
              for m in ours}

    def quotients(t: dict, tests_per_ray: float | None) -> dict[str, float | None]:
        if any(v is None for v in t.values()):
            return dict.fromkeys(("trav_cycles_per_ray", "tests_per_ray", "frag_cycles_per_pixel",
                                  "vert_cycles_per_triangle"))
        return {
            "trav_cycles_per_ray": round(t["TTrav"] / rays, 3) if rays else None,
            "tests_per_ray": tests_per_ray,
            "frag_cycles_per_pixel": round(t["TFrag"] / pixels, 3),
            "vert_cycles_per_triangle": round(t["TVert"] / triangles, 3),
        }

    implied = None
    if rays and theirs["Tisct"] is not None:
        implied = round((theirs["Tisct"] - 2 * rays) / 3 / rays, 3)
    return {
        "rays": rays, "tri_tests": tests, "pixels": pixels, "triangles": triangles,
        "eye_hits": int(results["primary"]["hits"]),
        "tests_per_leaf": round(tests / leaves, 3) if leaves else None,
        "ours": quotients(ours, round(tests / rays, 3) if rays else None), "thesis": quotients(theirs, implied),
    }


def summarize(rows: list[dict], not_comparable: dict[str, list[str]] | None = None,
              names: dict[str, str] | None = None) -> dict:
    """The medians of |relative error| and the slowest PMs of comparison rows.

    ``not_comparable``: scene -> how ours differs from the thesis's setting
    (:func:`mismatches`); those scenes' cells count in no median (an error against another
    setting measures the setting, not the model). ``held_out_cells`` and
    ``calibrated_cells`` count every cell with a thesis value, ``*_compared`` those the
    medians are over; ``predicted_cells`` and ``median_abs_rel_error_predicted`` (the headline,
    :func:`median_words`) the held-out cells but those of :data:`NOT_PREDICTIONS` (another cell
    again: ``not_predictions``, the kinds left out -> why; ``not_predictions_compared``, how many);
    ``median_withheld`` says in words what was left out and why (None:
    nothing), each scene by its name in ``names`` (its rows' name -> the printout's:
    :func:`scene_names`, ``ring`` -> ``thesis/ring``), as the tables name it."""
    nc = {s: list(w) for s, w in (not_comparable or {}).items() if w}
    known = [r for r in rows if r["rel_error"] is not None]
    compared = [r for r in known if str(r["scene"]) not in nc]
    held = [abs(r["rel_error"]) for r in compared if not r["calibrated"]]
    # (the headline: the held-out cells that are predictions of their own, not another cell again)
    kinds = {(str(r["mode"]), str(r["metric"])): not_prediction(str(r["mode"]), str(r["metric"]))
             for r in known if not r["calibrated"]}
    predicted = [abs(r["rel_error"]) for r in compared
                 if not r["calibrated"] and kinds[(str(r["mode"]), str(r["metric"]))] is None]
    left_kinds = [k for k in NOT_PREDICTIONS if k in kinds.values()]
    fitted = [abs(r["rel_error"]) for r in compared if r["calibrated"]]
    withheld = None
    # (a scene of the study's: one without a table, named as one's, :func:`judged_table`, is said too)
    left = {s: w for s, w in nc.items() if any(str(r["scene"]) == s for r in rows)}
    if left:
        shown = {s: (names or {}).get(s, s) for s in left}
        what = "; ".join(f"{shown[s]} is {', '.join(w)}" for s, w in left.items())
        withheld = (f"{', '.join(shown.values())} left out, not comparable with the thesis: {what}" if compared
                    else f"not comparable with the thesis: {what}")
    slowest = {}
    cells: dict[tuple[str, str], dict[str, dict]] = {}
    for r in rows:
        cells.setdefault((r["scene"], r["mode"]), {})[r["metric"]] = r
    for (scene, mode), m in cells.items():  # (a cell without every PM's two values has no slowest PM to name)
        if any(k not in m or m[k]["thesis"] is None or m[k]["ours"] is None for k in PM_METRICS):
            continue
        theirs = max(PM_METRICS, key=lambda k: m[k]["thesis"])
        ours = max(PM_METRICS, key=lambda k: m[k]["ours"])
        slowest[f"{scene}/{mode}"] = {"thesis": theirs, "ours": ours, "match": theirs == ours}
    ok = [v for c, v in slowest.items() if c.rsplit("/", 1)[0] not in nc]
    return {
        "held_out_cells": sum(not r["calibrated"] for r in known),
        "median_abs_rel_error_held_out": float(np.median(held)) if held else None,
        "calibrated_cells": sum(bool(r["calibrated"]) for r in known),
        "median_abs_rel_error_calibrated": float(np.median(fitted)) if fitted else None,
        "held_out_cells_compared": len(held),
        # the headline (median_words): the held-out cells but those of not_predictions, over the comparable scenes
        "predicted_cells": sum(not r["calibrated"] and kinds[(str(r["mode"]), str(r["metric"]))] is None
                               for r in known),
        "median_abs_rel_error_predicted": float(np.median(predicted)) if predicted else None,
        "predicted_cells_compared": len(predicted),
        "not_predictions": {k: NOT_PREDICTIONS[k] for k in left_kinds},
        "not_predictions_compared": len(held) - len(predicted),
        "calibrated_cells_compared": len(fitted),
        "not_comparable": nc,
        "median_withheld": withheld,
        "slowest_pm": slowest,
        "slowest_pm_matches": sum(v["match"] for v in slowest.values()),
        "scene_modes": len(slowest),
        "slowest_pm_comparable": len(ok),  # (the same over the comparable scenes', as the medians: slowest_words)
        "slowest_pm_matches_comparable": sum(v["match"] for v in ok),
    }


def run_thesis(path: Path, out: Path, progress=None, bar: bool = False, overrides: tuple[str, ...] = (),
               warn: Callable[[str], None] | None = None) -> dict:
    """Every (scene, mode) of the study: run folders, the comparison CSV and its summary.

    progress : called ``(scene, mode, results)`` after each cell; bar : progress bars of
    the cells, each scene's render and each simulation on stderr (only on a terminal);
    overrides : ``tlm thesis --set`` strings, applied to the study's base (:func:`load_study`),
    which each cell's ``results.json`` (``overrides``) and ``provenance.json`` record;
    warn : gets each of the study's warning lines once the cells ran: a ``--set`` some cells never
    read (:func:`unread_lines`, the summary's ``warnings``), then each distinct warning of the cells'
    ``results.json`` once, with how many cells and which (:func:`cell_warning_lines`). The returned
    ``warnings`` are those lines. None: the first kind said on stderr (``tlm: warning: ...``), the
    cells' own only returned (a library caller's cells keep theirs; ``tlm thesis`` prints them all).
    """
    quiet_cells = warn is None
    warn = _warn if warn is None else warn
    overrides = tuple(str(o) for o in overrides)
    base, scenes, modes, folder, keys = _study(Path(path), overrides)  # (keys: each scene's rows, folder, entries)
    wall: dict[str, float] = {}
    summary: dict = {}
    items: dict[str, dict] = {}
    differ: dict[str, list[str]] = {}  # scene -> how its cells differ from the thesis's setting
    names = scene_names(scenes, folder, str(path), keys)  # (each scene as the tables name it, the summary's words too)

    unread: dict[str, dict[tuple[str, str], str]] = {}  # a --set some cell never reads -> its cells -> why
    said: dict[str, list[str]] = {}  # a cell's own warning -> the cells that gave it ("thesis/ring pmap")
    before = set(SAID)  # (a line said on stderr during the study, a cache's, is not said again after it)

    def names_of(scene: str) -> str:
        return names.get(keys[scene][0], scene)

    def summary_file(rows: list[dict]) -> dict:
        summary.update(summarize(rows, differ, names), scenes=dict(names), no_table=no_table(keys, names),
                       per_item=items, host_seconds=wall, warnings=unread_lines(unread, len(scenes), len(modes)))
        return {"thesis_summary.json": summary}

    # (each cell is judged by its scene file: the identities of that file and of the built-in ones, once)
    with identities_remembered(), progress_bar(bar, desc="thesis", total=len(scenes) * len(modes),
                                               unit="cell") as cells:
        def one_scene(scene: str, tmp: Path) -> list[dict]:
            """A scene's render, then each mode's simulation and run folder: its comparison rows."""
            t0 = time.perf_counter()
            key, table = keys[scene]
            judged = judged_table(scene, table)
            cells.set_postfix_str(f"{scene}: render")
            big = config_from_dict({**base, "scene": scene, "mode": modes[-1]}, str(path))
            programs = programs_for(big, folder)
            res = render(big, folder, str(path), progress=bar)
            rows = []
            for mode in modes:
                cells.set_postfix_str(f"{scene} {mode}")
                cfg = config_from_dict({**base, "scene": scene, "mode": mode}, str(path))
                sub = restrict(res, cfg)
                sub = simulate_render(sub, programs, progress=bar)
                # (its overrides the --set strings alone, as a case of tlm extreme records them; its scene and
                # mode are its results' own. A --set this cell never reads is said once, for every cell: unread)
                results = write_run(sub, tmp / key / mode, str(path), list(overrides), say_unread=False)
                for line in unread_overrides(sub, overrides):
                    item, _, why = line.partition(" has no effect in this run: ")
                    unread.setdefault(item, {})[(names_of(scene), mode)] = why.replace(f"mode {mode!r}", "its mode")
                for line in results["warnings"]:  # (its own: the --set it never read are not among them)
                    said.setdefault(" ".join(line.split()), []).append(f"{names_of(scene)} {mode}")
                rows.extend(table_rows(key, table, mode, _ours(results["cycles"], results["fps"]),
                                       fitted_cells(programs.calibration)))
                items[f"{key}/{mode}"] = per_item(table, mode, results)
                if judged is not None:  # (one named as a table's but of another file: 'the scene ...' first)
                    seen = differ.setdefault(key, [])
                    seen.extend(m for m in run_mismatches(judged, results, to_dict(cfg)) if m not in seen)
                cells.update()
                if progress is not None:
                    progress(scene, mode, results)
            wall[scene] = round(time.perf_counter() - t0, 3)
            return rows

        # (each row says whether its cell is compared: its scene judged by every mode's cell, as the summary judges it)
        rows = run_study(str(path), out, "thesis_comparison", scenes, one_scene, columns=COLUMNS,
                         marker="thesis_comparison.csv", finish=lambda rows, _: marked(rows, differ),
                         files=summary_file, overrides=overrides)
    unread_said = list(summary.get("warnings") or [])
    lines = [*unread_said, *cell_warning_lines(said, len(scenes) * len(modes), SAID - before)]
    for line in unread_said if quiet_cells else lines:
        warn(line)
    return {"rows": rows, "summary": summary, "names": names, "warnings": lines}


def cell_warning_lines(said: dict[str, list[str]], cells: int, already: set[str] = frozenset()) -> list[str]:
    """Each distinct warning of a study's cells (``said``: the line, as a cell's ``results.json``
    ``warnings`` has it, -> the cells that gave it, ``"thesis/ring pmap"``; ``cells``: how many the
    study has) once, led by the cells it is of: ``cell cornell pmap: ...``, ``2 of 12 cells
    (thesis/ring pmap, cornell pmap): ...``, ``all 12 cells: ...``; but for those of ``already``,
    the lines said on stderr while the cells ran (a cache that could not be written:
    :data:`tlm.storage.SAID`), which are not said again."""
    lines = []
    for line, where in said.items():
        if line in already:
            continue
        where = list(dict.fromkeys(where))
        if len(where) == 1:
            who = f"cell {where[0]}"
        elif len(where) == cells:
            who = f"all {cells} cells"
        else:
            who = f"{len(where)} of {cells} cells ({', '.join(where)})"
        lines.append(f"{who}: {line}")
    return lines


def unread_lines(unread: dict[str, dict[tuple[str, str], str]], scenes: int, modes: int) -> list[str]:
    """One line per ``--set`` of the study that some of its cells never read (``unread``: the
    override as given, ``--set KEY=VALUE``, -> the cells, ``(scene, mode)``, -> why; ``scenes``
    and ``modes``: how many the study has): how many cells, which (by mode: ``rcast`` of every
    scene, or of those named) and why, once for the study rather than in each cell's
    ``results.json``."""
    lines = []
    for item, where in unread.items():
        by_mode: dict[str, list[str]] = {}
        for scene, mode in where:
            by_mode.setdefault(mode, []).append(scene)
        every = all(len(names) == scenes for names in by_mode.values())
        said = ", ".join(by_mode) + " of every scene" if every else "; ".join(
            f"{mode} of {', '.join(names)}" for mode, names in by_mode.items())
        lines.append(f"{item} changes nothing in {len(where)} of {scenes * modes} cells (mode {said}): "
                     f"{'; '.join(dict.fromkeys(where.values()))}")
    return lines


def _name(scene: str) -> str:
    return Path(scene).stem


def table_rows(key: str, table: str | None, mode: str, ours: dict[str, float],
               fitted: frozenset[tuple[str, str]] | None = None) -> list[dict]:
    """:func:`comparison_rows` of a study's scene named ``key`` whose table is ``table`` (by its file), ``fitted``
    the cells its instruction table was fitted to (:func:`fitted_cells`; None: the packaged table's): without
    a table (None), no thesis value and no cell calibrated, whatever its name (a user's ``room.yaml`` is
    not Table II's: nothing was fitted to it)."""
    rows = comparison_rows(key, mode, ours, fitted)
    return rows if table is not None else [{**r, "thesis": None, "rel_error": None, "calibrated": False} for r in rows]


def marked(rows: list[dict], differ: dict[str, list[str]]) -> list[dict]:
    """:func:`with_comparable`, and a scene of no table that is judged as one's (:func:`judged_table`: not the
    thesis's scene by its file) marked not comparable in every row, saying why, though it has no thesis value."""
    return [{**r, "comparable": False, "not_comparable": "; ".join(differ[str(r["scene"])])}
            if r["thesis"] is None and differ.get(str(r["scene"])) else r for r in with_comparable(rows, differ)]


def scene_names(scenes: list[str], folder: Path, source: str, keys: dict | None = None) -> dict[str, str]:
    """Each scene of a study by the name its rows give it (:func:`scene_keys`, or ``keys`` where given: its table,
    ``ring``, else its file's stem) -> the scene as the report names it: a built-in one by its name under
    ``scenes/`` (``thesis/ring``, not the built-in ``ring``), another as the study lists it (its path)."""
    names = {}
    for s, (key, _) in (keys or scene_keys(scenes, folder, source)).items():
        file = resolve_scene_path(s, folder, source, "scenes").resolve()
        label = scene_label(file)
        names[key] = label if label != str(file) else s
    return names


# -- calibration --------------------------------------------------------------------------------

def calibrate(path: Path, iterations: int = 4, progress=None) -> tuple[Programs, dict]:
    """Fit the programs' free parameters to the RCast column.

    ``vertex.scale``, and for the PMs of ``FIT_RECORDS`` their ``scale`` and
    ``record_cycles`` together. The cycles of a PM are ``scale x instructions +
    record_cycles x records + (page misses, flushes, swaps, copies, preemption)``; the
    last part barely depends on the parameters, so the fit alternates a closed-form
    weighted least-squares step with a re-simulation until it settles. The report's ``fit``:
    per PM, how well the fit is determined (:func:`~tlm.experiments.calibrate_fit.fit_statistics`).

    Refused (:class:`~tlm.errors.InputError`, before any render): a study without the
    ``rcast`` mode (the only column fitted), a scene without a thesis table (by its file,
    :func:`scene_keys`: a user's ``room.yaml`` is fitted to no table, a copy of ``thesis/ring``
    under another name is Table I's, its ``cells`` named ``ring``), and fewer
    than two scenes (one cell per PM cannot fix a scale and a record cost: the fit would
    be one of infinitely many exact ones). The report's ``not_comparable`` (scene -> how
    ours differs, :func:`mismatches`; empty: the thesis's setting) says whether the fit
    is one to the thesis's setting.
    """
    inputs = _calibration_inputs(Path(path))
    programs, history, sims, stats = _fit(inputs, inputs["scenes"], iterations, progress)
    tables = inputs["tables"]
    cells = {}
    for s in inputs["scenes"]:
        ours = _ours(sims[s].cycles, sims[s].fps)
        cells[tables[s]] = {m: {"thesis": thesis_value(tables[s], "rcast", m), "ours": round(ours[m], 4)}
                           for m in FIT_PMS.values()}
    report = {"scales": programs.scale, "record_cycles": programs.record_cycles, "fitted": fitted_parameters(),
              "cells": cells, "fit": stats, "iterations": len(history), "history": history,
              "not_comparable": {s: w for s, w in inputs["differ"].items() if w}}
    return programs, report


def leave_one_out(path: Path, iterations: int = 4, progress=None) -> dict:
    """A held-out check of :func:`calibrate` (``tlm calibrate --leave-one-out``), writing no table: for each
    scene, the fit to the others (each a dry run, on the same renders) and the left-out scene's fitted RCast
    cells under it (``scenes``: scene -> ``parameters``, ``cells``: metric -> ``thesis``, ``ours``,
    ``rel_error``, ``in_sample``, the fit to every scene's); ``held_out`` and ``in_sample``: the median and
    max |relative error| of those cells, and of the fit to every scene. It needs three scenes at least (a fit
    to one is refused, :func:`calibrate`). ``progress``: called ``(scene left out, iteration, parameters)``,
    the scene by its table's name, as ``scenes`` keys it (``ring``, not ``thesis/ring``)."""
    return held_out(_calibration_inputs(Path(path), leave_one_out=True), iterations, progress)


def _calibration_inputs(path: Path, leave_one_out: bool = False) -> dict[str, Any]:
    """:func:`calibrate`'s study checked and rendered: each scene's ``tables`` and ``fns`` (functional run,
    config), the table it starts from, each PM's instructions and records per frame, ``differ``."""
    base, scenes, modes, folder, keys = _study(Path(path))
    if "rcast" not in modes:
        raise InputError(f"{quoted(modes)} has no rcast: calibrate fits the RCast column only (the other modes' cells "
                         "are predictions)", source=str(path), key="modes")
    tables = {s: table for s, (_, table) in keys.items()}  # (by its file: scene_keys)
    unknown = [s for s in scenes if tables[s] is None]
    if unknown:  # (a scene whose name is a table's but not its file, judged_table: fitted to no table)
        named = [f"{quoted(s)} is not the thesis's {_name(s)} scene, {THESIS_SCENES[_name(s)]}" for s in unknown
                 if judged_table(s, None)]
        raise InputError(f"{quoted(unknown)} have no thesis table to calibrate against"
                         + (f" (a scene is a table's by its file, not its name: {'; '.join(named)})" if named else ""),
                         source=str(path), key="scenes")
    if len(scenes) < 2 + leave_one_out:
        raise InputError(f"{quoted(scenes)}: {'--leave-one-out fits all scenes but one, and ' if leave_one_out else ''}"
                         "one scene gives one RCast cell per PM, too few for the Traversal and "
                         "Fragment PMs' two parameters each (scale, record_cycles): list at least "
                         f"{'three' if leave_one_out else 'two'} of the thesis's scenes "
                         f"({', '.join(THESIS_SCENES.values())})", source=str(path), key="scenes")
    cfgs = {s: config_from_dict({**base, "scene": s, "mode": "rcast"}, str(path)) for s in scenes}
    programs = programs_for(cfgs[scenes[0]], folder)  # a bad instruction table fails before the renders
    fns = {}
    differ: dict[str, list[str]] = {}
    for scene in scenes:
        cfg = cfgs[scene]
        res = render(cfg, folder, str(path))
        fns[scene] = (res.functional(), cfg)
        cam = res.scene.camera
        differ[tables[scene]] = mismatches(tables[scene], source=res.scene.source,
                                           resolution=[cam.width, cam.height], spp=cfg.render.spp,
                                           light_samples=cfg.render.light_samples, pipelines=cfg.arch.pipelines,
                                           clock_hz=cfg.arch.clock_hz, config=to_dict(cfg))
    ones, zeros = dict.fromkeys(PROGRAMMABLE, 1.0), dict.fromkeys(PROGRAMMABLE, 0.0)
    # T_norm is linear in the parameters: instructions and records per frame, once
    return {"scenes": scenes, "tables": tables, "fns": fns, "programs": programs, "differ": differ,
            "instructions": norm_per_frame(fns, programs.with_scales(ones, zeros)),
            "records": norm_per_frame(fns, programs.with_scales(zeros, ones))}
