"""Report section: image sets in the style of the thesis's Figs. 15-17.

Per scene a row of four panels, RCast, Reflect, Refract and PMap, each the image of
that mode, i.e. the *cumulative* composite (the modes add passes: Refract is ray cast
+ reflection + refraction), as in the thesis.

* A ``tlm thesis`` folder: each cell ``<scene>/<mode>`` is one panel, its
  ``images/composite.png`` (each cell tone-mapped with its own exposure, as written).
  A mode the study did not run but a larger cell of the scene contains (the cells are
  cuts of one render) is rebuilt from that cell's radiance, as for a single run.
* A single run: the composites of its own mode and of every smaller mode are rebuilt
  from ``radiance/<pass>.npy`` (sums of the passes the planner ran up to that mode),
  all tone-mapped with the run's one exposure (``results.json`` ``image.exposure``), so
  the four panels are directly comparable. A run folder without ``radiance/`` shows
  its ``images/composite.png`` for its own mode only.

A run whose photon-map frame was measured against its reference (``results.json`` ``error``,
:mod:`tlm.experiments.reference`; one that did not converge, ``reference_converged`` false, is said
"NOT converged" in the figure's title, caption and the lead) also gets a figure of
that frame beside its difference from the reference (ours minus the reference in
luminance), titled with the relative MSE and RMSE, which the section's lead repeats with the reference in one
line, its key, photons a round, k_nearest, rounds and resolution (:func:`reference_line`), as the caption does. The
difference is read back from the run's ``images/pmap_error.png`` (the blue and red of a
run written before 2026-11-29 too) and drawn in
:data:`tlm.experiments.reference.DIFFERENCE_COLOURS`, with its colour bar: dark blue
where ours is darker, neutral grey where equal, light yellow where brighter. Its grey
rises from one end to the other, so a greyscale print still tells the two signs apart
(darker than the grey of zero: ours darker).

A mode whose pass the planner left out for lack of what it needs (no mirror, no
dielectric, ...) still has an image (the same as the previous mode's) and its panel
gives the planner's reason; a mode beyond the run's is an empty panel saying it was
not run and why. Sweep points keep no images; they are listed in a note.

Each file is read where the run wrote it alone (:meth:`~tlm.report.collect.Run.wrote`: its ``.tlm-written``
lists it), never one a rerun into the folder kept from an earlier output (:mod:`tlm.report.written`); a panel
or note that finds such a file says so.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tlm.config import MODES
from tlm.experiments.thesis import THESIS_SCENES
from tlm.render.image import to_srgb8
from tlm.render.planner import PASSES
from tlm.report.collect import Inputs, Run
from tlm.report.common import FigureName, Section, new_figure, save
from tlm.report.tables import thesis_table
from tlm.report.written import kept

MODE_TITLE = {"rcast": "RCast", "reflect": "Reflect", "refract": "Refract", "pmap": "PMap"}
SCENE_TITLE = {"ring": "Scene with ring (Fig. 15)", "room": "Room scene (Fig. 16)",
               "cornell": "Cornell Box scene (Fig. 17)"}
MAX_ROWS = 4  # rows (scenes or runs) per figure
MAX_FIGURES = 6  # image figures in the report; what is beyond is named in a note
MAX_ERROR_FIGURES = 4  # figures of a run's photon-map frame against its reference
WRAP = 34
ON_MAP = 2.0  # a difference image's pixel lies on its map's colours within this (0-255 units; rounding: 0.87)


@dataclass
class Panel:
    mode: str
    image: np.ndarray | None = None  # (H, W, 3) uint8 or float in [0, 1]
    remark: str = ""  # the planner's reason, or why there is no image


@dataclass
class Row:
    label: str
    resolution: str
    panels: list[Panel] = field(default_factory=list)


def scene_title(run: Run) -> str:
    """The run's scene as the report names it (its file: ``thesis/room``), with the thesis's
    title and figure where it is the thesis's scene (``thesis/room: Room scene (Fig. 16)``); a
    scene that only shares the name of one (the built-in ``room``) says that it is not that one.
    The thesis's scene is judged as Tables I-III judge it (:func:`~tlm.report.tables.thesis_table`, by
    its file: a byte copy of ``thesis/room`` under another name is it, a user's ``room.yaml`` is not;
    h452: a label compared here put a run in Table III whose caption said it was not that scene)."""
    label = run.scene_label
    if run.scene not in SCENE_TITLE:
        return label
    if thesis_table(run) == run.scene:
        return f"{label}: {SCENE_TITLE[run.scene]}"
    return f"{label}, not the thesis's {SCENE_TITLE[run.scene]}"


def _read_png(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def _plan(run: Run) -> tuple[list[str], dict[str, str]]:
    plan = run.results.get("plan") or {}
    return list(plan.get("run") or []), dict(plan.get("left_out") or {})


def _resolution(run: Run) -> str:
    res = run.results["scene"].get("resolution")
    return f"{res[0]}×{res[1]}" if res else "?"


def cell_panel(run: Run, mode: str) -> Panel:
    """The panel of one thesis cell: its composite, and the reason if its pass was left out."""
    _, left = _plan(run)
    png = run.wrote("images/composite.png")  # (a file the cell wrote: its listing's)
    if png is None:
        other = kept(run, "images/composite.png")  # (one there that is not the cell's: "wrote no", not "has no")
        return Panel(mode, remark=f"no image: {run.label} {'wrote' if other else 'has'} no images/composite.png"
                     f"{other}")
    remark = f"{mode} pass left out: {left[mode]} (image = previous mode's)" if mode in left else ""
    return Panel(mode, _read_png(png), remark)


def study_panels(cells: dict[str, Run], study_name: str) -> list[Panel]:
    """One scene of a thesis study: each cell's composite; a mode the study did not run is
    rebuilt from the radiance of a larger mode's cell (the cells are cuts of one render)."""
    largest = max(cells.values(), key=lambda r: MODES.index(r.mode))
    rebuilt: list[Panel] | None = None
    panels = []
    for i, mode in enumerate(MODES):
        if mode in cells:
            panels.append(cell_panel(cells[mode], mode))
        elif i < MODES.index(largest.mode) and largest.radiance is not None:
            rebuilt = rebuilt or run_panels(largest)
            p = rebuilt[i]
            why = (f"study {study_name} has no {mode} cell: rebuilt from the {largest.mode} cell's radiance "
                   "and exposure")
            panels.append(Panel(mode, p.image, f"{p.remark}; {why}" if p.remark else why))
        else:
            panels.append(Panel(mode, remark=f"not run: study {study_name} has no {mode} cell"))
    return panels


def run_panels(run: Run) -> list[Panel]:
    """The four cumulative mode images of one run, rebuilt from its radiance."""
    ran, left = _plan(run)
    top = MODES.index(run.mode) if run.mode in MODES else len(MODES) - 1
    exposure = float((run.results.get("image") or {}).get("exposure") or 1.0)
    rad_dir = run.radiance
    panels = []
    total = None
    for i, mode in enumerate(MODES):
        if i > top:
            panels.append(Panel(mode, remark=f"not run: {left.get(mode, f'the run is in mode {run.mode!r}')}"))
            continue
        if rad_dir is None:
            composite = run.wrote("images/composite.png") if i == top else None
            if composite is not None:
                panels.append(Panel(mode, _read_png(composite)))
            else:
                other = kept(run, "radiance")
                panels.append(Panel(mode, remark=f"cannot rebuild: the run {'wrote' if other else 'folder has'} no "
                                    f"radiance/{other}"))
            continue
        name = PASSES[i]
        remark = ""
        if name in ran:
            path = run.wrote(f"radiance/{name}.npy")  # (one the run wrote: not an earlier run's, kept by a rerun)
            if path is None:
                other = kept(run, f"radiance/{name}.npy")
                panels.append(Panel(mode, remark=f"the run wrote no radiance/{name}.npy{other}" if other else
                                    f"no radiance/{name}.npy in the run folder"))
                total = None
                continue
            rad = np.load(path).astype(np.float64)
            total = rad if total is None else total + rad
        else:
            remark = f"{name} pass left out: {left.get(name, 'not planned')} (image = previous mode's)"
        panels.append(Panel(mode, None if total is None else to_srgb8(total, exposure), remark))
    return panels


def _draw(rows: list[Row], title: str, out: Path, name: FigureName, caption: str):
    ncols = len(MODES)
    fig = new_figure(2.3 * ncols + 0.4, 2.55 * len(rows) + 0.5)
    axes = fig.subplots(len(rows), ncols, squeeze=False)
    for r, row in enumerate(rows):
        for c, panel in enumerate(row.panels):
            ax = axes[r][c]
            ax.set_xticks([])
            ax.set_yticks([])
            for spine in ax.spines.values():
                spine.set_visible(panel.image is not None)
            ax.set_title(MODE_TITLE[panel.mode], fontsize=9)
            if panel.image is not None:
                ax.imshow(panel.image, interpolation="none")
                if panel.remark:
                    ax.set_xlabel(textwrap.fill(panel.remark, WRAP, expand_tabs=False), fontsize=6.5)
            else:
                ax.set_xlim(0, 1)
                ax.set_ylim(0, 1)
                ax.set_facecolor("#f2f2f2")
                for spine in ax.spines.values():
                    spine.set_visible(True)
                    spine.set_linestyle(":")
                ax.text(0.5, 0.5, textwrap.fill(panel.remark, 26, expand_tabs=False), ha="center", va="center",
                        fontsize=7, transform=ax.transAxes, wrap=True)
            if c == 0:
                ax.set_ylabel(textwrap.fill(f"{row.label} ({row.resolution})", 28, expand_tabs=False), fontsize=8)
    fig.suptitle(title, fontsize=11)
    return save(fig, out, name, title, caption)


def _error_words(error: dict) -> str:
    rel = "n/a" if error.get("rel_mse") is None else f"{error['rel_mse']:.3g}"
    return f"relative MSE {rel}, RMSE {error['rmse']:.3g}"


def reference_line(error: dict) -> str:
    """The reference a run's ``results.json`` ``error`` is against, in one line (h507): its key, photons a round,
    k_nearest, rounds, relative standard error and resolution
    (:func:`~tlm.experiments.reference.reference_named`; a run written before these were kept names fewer)."""
    from tlm.experiments.reference import reference_named

    return reference_named(error.get("reference"), error.get("reference_photons"), error.get("reference_k_nearest"),
                           error.get("reference_rounds"), error.get("reference_resolution"),
                           error.get("reference_standard_error"))


def _reference_words(error: dict) -> str:
    """The reference a run's photon-map error is against: ``its converged reference``, or where
    it did not converge (``reference_converged`` not true) ``its reference (NOT converged)``."""
    return "its converged reference" if error.get("reference_converged") else "its reference (NOT converged)"


def signed_difference(rgb: np.ndarray, colours: tuple[str, ...]) -> np.ndarray | None:
    """(H, W) in [-1, 1]: the difference (over its scale) that each pixel of ``rgb`` ((H, W, 3)
    uint8) stands for in the piecewise-linear map of ``colours`` (evenly spaced from -1 to +1, as
    :func:`~tlm.experiments.reference.difference_image` draws them): the nearest point of the map.
    None where a pixel lies further than :data:`ON_MAP` from the map (an image drawn in other colours)."""
    stops = np.array([[int(c[i:i + 2], 16) for i in (1, 3, 5)] for c in colours], dtype=np.float64)
    px = np.asarray(rgb, dtype=np.float64).reshape(-1, 3)
    n = len(stops) - 1
    best, where = np.full(len(px), np.inf), np.zeros(len(px))
    for k in range(n):
        step = stops[k + 1] - stops[k]
        s = np.clip((px - stops[k]) @ step / (step @ step), 0.0, 1.0)
        gap = np.linalg.norm(px - stops[k] - s[:, None] * step, axis=1)
        closer = gap < best
        best[closer], where[closer] = gap[closer], -1.0 + 2.0 * (k + s[closer]) / n
    if not len(px) or best.max() > ON_MAP:
        return None
    return where.reshape(np.shape(rgb)[:2])


def error_figure(run: Run, out: Path):
    """The run's photon-map frame beside its difference from the reference, or None when
    the run measured no error or its folder lacks either image. The difference is read back
    from the run's difference image (:func:`signed_difference`) and drawn in
    :data:`~tlm.experiments.reference.DIFFERENCE_COLOURS` (a run's of before 2026-11-29, in
    blue and red, too), whose grey rises from -scale to +scale, with its colour bar; an
    image not in the run's difference colours is shown as written, without a bar, and the
    caption says so."""
    from matplotlib.colors import LinearSegmentedColormap, Normalize

    from tlm.experiments.reference import DIFFERENCE_COLOURS, DIFFERENCE_COLOURS_BEFORE

    error = run.results.get("error") or {}
    if not error.get("available"):
        return None
    diff_name = str(error.get("difference_image") or "images/pmap_error.png")
    diff_png, frame_png = run.wrote(diff_name), run.wrote("images/pmap.png")  # (the run's own: its listing's)
    if diff_png is None or frame_png is None:
        return None
    scale = float(error.get("difference_scale") or 1.0)
    written = _read_png(diff_png)
    signed = signed_difference(written, DIFFERENCE_COLOURS)
    if signed is None:  # (a run written before the colours changed)
        signed = signed_difference(written, DIFFERENCE_COLOURS_BEFORE)
    fig = new_figure(7.0, 3.4)
    axes = fig.subplots(1, 2)
    axes[0].imshow(_read_png(frame_png), interpolation="none")
    if signed is None:
        axes[1].imshow(written, interpolation="none")
    else:
        cmap = LinearSegmentedColormap.from_list("tlm_difference", DIFFERENCE_COLOURS)
        shown = axes[1].imshow(signed * scale, cmap=cmap, norm=Normalize(-scale, scale), interpolation="none")
        bar = fig.colorbar(shown, ax=axes[1], shrink=0.85)
        bar.set_label("radiance difference", fontsize=8)
        bar.ax.tick_params(labelsize=7)
    for ax, title in ((axes[0], "PMap frame (ours)"), (axes[1], "ours − reference (luminance)")):
        ax.set_title(title, fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    title = f"{run.label}: PMap frame against {_reference_words(error)}, {_error_words(error)}"
    state = "converged" if error.get("reference_converged") else "NOT converged"
    drawn = (f"{diff_name} as the run wrote it: its colours are not those of "
             "tlm's difference image, so they are not read back and no colour bar is drawn"
             if signed is None else
             f"read back from {diff_name} and drawn dark blue where ours is "
             f"darker, neutral grey where equal, light yellow where brighter, full colour at ±{scale:.3g} (the "
             "99th percentile of |difference|); the grey rises from one end to the other, so a greyscale print "
             "keeps the sign")
    caption = (f"Left: the run's photon-mapped term (images/pmap.png, the run's exposure). Right: its luminance "
               f"minus that of the {state} {reference_line(error)}, {drawn}. The reference is "
               "the pixel's box-filter integral: a run of render.spp 1 samples the pixel's centre, so edges "
               "show aliasing too.")
    fig.suptitle(f"{run.label}\nPMap frame against {_reference_words(error)}: {_error_words(error)}", fontsize=9)
    return save(fig, out, FigureName(("pmap_error", run.label), f"pmap_error\n{run.label}"), title, caption)


def images_section(inputs: Inputs, out: Path) -> Section:
    """Figs. 15-17 style image sets: per thesis study one figure, per run one row."""
    out = Path(out)
    section = Section("images", "Image sets (Figs. 15–17): RCast, Reflect, Refract, PMap")
    jobs: list[tuple[list[Row], str, FigureName, str]] = []  # rows, title, file name, caption
    in_study: set[Path] = set()
    for study in inputs.of_kind("thesis"):
        cells = inputs.study_cells(study)  # (its run folders DIR/<scene>/<mode>, as the tables find them)
        in_study.update(r.path.resolve() for r in cells)
        order = list(THESIS_SCENES.values())
        scenes = sorted(dict.fromkeys(r.scene_label for r in cells),
                        key=lambda s: (order.index(s) if s in order else 9, s))
        rows = []
        for scene in scenes:
            by_mode = {r.mode: r for r in cells if r.scene_label == scene}
            any_run = next(iter(by_mode.values()))
            rows.append(Row(scene_title(any_run), _resolution(any_run), study_panels(by_mode, study.path.name)))
        if not rows:
            section.notes.append(f"thesis study {study.path.name}: no cell folders, so no images")
            continue
        for k in range(0, len(rows), MAX_ROWS):
            part = rows[k:k + MAX_ROWS]
            suffix = f" ({k // MAX_ROWS + 1})" if len(rows) > MAX_ROWS else ""
            number = (str(k // MAX_ROWS + 1),) if suffix else ()
            jobs.append((part, f"Thesis study {study.path.name}: image sets by mode{suffix}",
                         FigureName(("images", study.path.name, *number),
                                    "\n".join(("images", str(study.path.absolute()), *number))),
                         "Each panel is the cumulative composite of its mode as written by the study "
                         "(images/composite.png of the cell, tone-mapped with that cell's own exposure)."))
    runs = [r for r in inputs.runs if r.kind == "run" and r.path.resolve() not in in_study]
    points = [r for r in inputs.runs if r.kind == "sweep-point"]
    if points:
        section.notes.append(f"{len(points)} sweep points have no images (a sweep keeps results only); "
                             "render one point with 'tlm run' to see it")
    with_images = []
    for run in runs:
        if run.images is None and run.radiance is None:
            other = kept(run, "images") + kept(run, "radiance")
            section.notes.append(f"{run.label}: the run {'wrote' if other else 'folder has'} no images/ or radiance/"
                                 f"{other}, left out")
        else:
            with_images.append(run)
    for k in range(0, len(with_images), MAX_ROWS):
        part = with_images[k:k + MAX_ROWS]
        rows = [Row(r.label, _resolution(r), run_panels(r)) for r in part]
        n = k // MAX_ROWS + 1
        many = len(with_images) > MAX_ROWS
        title = "Runs: image sets by mode" + (f" ({n})" if many else "")
        if len(part) == 1:
            title = f"{scene_title(part[0])}: image set by mode, {part[0].label}"
        number = (str(n),) if many else ()
        jobs.append((rows, title, FigureName(("images_runs", *number), "\n".join(("images_runs", *number))),
                     "Each panel is the cumulative composite of its mode (the sum of the passes run up to it), "
                     "rebuilt from the run's linear radiance and tone-mapped with the run's one exposure."))
    if not jobs:
        section.absent = ("no thesis cell or run folder with images among the inputs"
                          + (" (sweep points keep no images)" if points else ""))
        return section
    if len(jobs) > MAX_FIGURES:
        left = [title for _, title, _, _ in jobs[MAX_FIGURES:]]
        section.notes.append(f"{len(left)} image figures left out (at most {MAX_FIGURES}): {'; '.join(left)}")
        jobs = jobs[:MAX_FIGURES]
    for rows, title, name, caption in jobs:
        for row in rows:
            for p in row.panels:
                if p.remark:
                    section.notes.append(f"{row.label}, {MODE_TITLE[p.mode]}: {p.remark}")
        section.figures.append(_draw(rows, title, out, name, caption))
    _error_figures(section, with_images, out)
    return section


def _unmeasured(run: Run, error: dict) -> str:
    """Why a run's photon-map error was not measured, and the command that computes its reference, as
    ``tlm run`` printed them: from ``results.json`` where it records them (``skipped``, ``command``);
    else the command from the run's config and overrides where its config is a run config file
    (:func:`_run_config`), or else from the run folder's ``config.resolved.yaml`` (every setting of the
    run, its ``--set`` values included, its scene by its absolute path: a thesis cell's ``results.json``
    ``config`` is the study file, which ``tlm reference`` refuses); and the reason from its config (a
    run with ``reference.auto`` true and no reference computed was run with ``--no-reference``)."""
    why, command = error.get("skipped"), error.get("command")
    if not isinstance(command, str) or not command:
        from tlm.experiments.run import reference_command  # (tlm run's rule; imported only here)

        resolved = run.wrote("config.resolved.yaml")
        config = run.results.get("config")
        if resolved is not None and not _run_config(run, config):
            command = reference_command(str(resolved.absolute()))
        else:
            command = reference_command(config if isinstance(config, str) else None,
                                        [o for o in run.results.get("overrides") or [] if isinstance(o, str)])
    if not isinstance(why, str) or not why:
        auto = (run.config.get("reference") or {}).get("auto") if isinstance(run.config, dict) else None
        why = "reference.auto: false" if auto is False else "--no-reference" if auto is True else ""
    key = error.get("reference")
    return (f"the photon-map frame's error was not measured: {f'skipped ({why})' if why else 'not measured'}: "
            f"no reference{f' {key}' if key else ''} cached; compute it with: {command}, then run it again")


def _run_config(run: Run, config) -> bool:
    """Whether ``config`` (a run's ``results.json`` ``config``) names a run config (or scene file) that
    ``tlm reference`` takes, as seen from here: a file of a run folder that is not a thesis cell
    (``<study>/<scene>/<mode>``, its config the study file), with no key of a study or sweep
    (:data:`tlm.builtin.EXPERIMENT_COMMANDS`, ``base``); not one not found from the working folder (a
    relative path from another folder)."""
    from tlm.builtin import EXPERIMENT_COMMANDS
    from tlm.config import read_yaml
    from tlm.errors import InputError

    if run.kind != "run" or not isinstance(config, str) or (run.path.parent.parent / "thesis_comparison.csv").is_file():
        return False
    try:
        raw = read_yaml(Path(config)) if Path(config).is_file() else None
    except (InputError, OSError, ValueError):
        return False
    return isinstance(raw, dict) and not any(k in raw for k in ("base", *dict(EXPERIMENT_COMMANDS)))


def _error_figures(section: Section, runs: list[Run], out: Path) -> None:
    """Each run's photon-map error: a figure (:func:`error_figure`) and a phrase of the lead."""
    from tlm.report.html import esc

    said = []
    converged: list[bool] = []  # (each said run's reference converged)
    for run in runs:
        error = run.results.get("error")
        if not error:
            continue  # no photon-map frame
        if not error.get("available"):
            section.notes.append(f"{run.label}: {_unmeasured(run, error)}")
            continue
        said.append(f"{esc(run.label)}: {esc(_error_words(error))} against {esc(reference_line(error))}"
                    + ("" if error.get("reference_converged") else " (its reference NOT converged)"))
        converged.append(bool(error.get("reference_converged")))
        if len(said) > MAX_ERROR_FIGURES:
            section.notes.append(f"{run.label}: its PMap error figure is left out (at most {MAX_ERROR_FIGURES})")
            continue
        fig = error_figure(run, out)
        if fig is None:
            diff = str(error.get("difference_image") or "images/pmap_error.png")
            section.notes.append(f"{run.label}: no images/pmap.png or {diff}{kept(run, 'images/pmap.png')}"
                                 f"{kept(run, diff)}: no error figure")
        else:
            section.figures.append(fig)
    if said:
        section.lead = ("PMap frame against its converged reference: " if all(converged) else
                        "PMap frame against its reference: ") + "; ".join(said) + "."
