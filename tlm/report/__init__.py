"""``tlm report``: the figures and tables researchers read, in one self-contained page.

:func:`build_report` reads any tlm output folders (:mod:`tlm.report.collect`), draws
every section's figures as PNG files with matplotlib (and, where asked, as PDF and SVG
files beside them: :func:`tlm.report.common.figure_output`) and writes ``report.html``,
which embeds the PNGs and links every file. First, unnumbered, what the model found
(:mod:`tlm.report.summary`: frame rates, the bottleneck PM, scaling with N, error against
run time), under the warnings the runs recorded (:mod:`tlm.report.warnings`); then the
sections:

1. Tables I-III, ours against the thesis (:mod:`tlm.report.tables`)
2. image sets in the style of Figs. 15-17 (:mod:`tlm.report.images`)
3. scaling with N pipelines, Figs. 18-20 and eq. 5.2, idle fraction per PM (:mod:`tlm.report.scaling`)
4. the sweeps' points, their frame rate per factor, BSP levels against floor(ln n)
   (:mod:`tlm.report.sweeps`)
5. where the cycles go: eq. 5.1 and the timeline (:mod:`tlm.report.cycles`)
6. error against run time (:mod:`tlm.report.tradeoff`)
7. peers: the frame rates the thesis quotes (:mod:`tlm.report.peers`)
8. the stiff and extreme cases, expected against measured (:mod:`tlm.report.extreme`)
9. provenance (:mod:`tlm.report.provenance`)

A section the inputs have nothing for still appears, saying why. The report folder is
written whole or not at all (a temporary sibling renamed into place).

Every section names a scene by its file (:func:`tlm.report.names.scene_label`: the built-in
``room`` and ``thesis/room`` are two scenes, though both files say ``name: room``), and the
inputs' paragraph says so where two scenes share a name (:func:`scenes_note`).
"""

from __future__ import annotations

import contextlib
import datetime
import gc
import shutil
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from tlm.config_words import listing
from tlm.errors import EnvironmentFailure, InputError, escaped_line, quoted
from tlm.report.collect import Inputs, read
from tlm.report.common import Section, count, current_output, drawable, figure_output, forget_names
from tlm.report.html import esc, page
from tlm.report.names import path_labels
from tlm.report.once import reading
from tlm.report.warnings import warnings_html
from tlm.storage import atomic_folder, check_destination, distinct_folders

MARKER = "report.html"
# subfolders of a report's folder that the report does not draw but keeps when it is
# written again: the side-by-side images benchmarks/bench_oracle.py writes into plots/oracle
KEPT_FOLDERS = ("oracle",)


SECTIONS = 9  # (the numbered sections, :func:`section_makers`: the progress bar counts them before importing them)


def section_makers() -> tuple[Callable[[Inputs, Path], Section], ...]:
    """The functions that make the numbered sections, in the page's order (:data:`SECTIONS` of them)."""
    from tlm.report.cycles import cycles_section
    from tlm.report.extreme import extreme_section
    from tlm.report.images import images_section
    from tlm.report.peers import peers_section
    from tlm.report.provenance import provenance_section
    from tlm.report.scaling import scaling_section
    from tlm.report.sweeps import sweeps_section
    from tlm.report.tables import tables_section
    from tlm.report.tradeoff import tradeoff_section

    return (tables_section, images_section, scaling_section, sweeps_section, cycles_section, tradeoff_section,
            peers_section, extreme_section, provenance_section)


def sections(inputs: Inputs, out: Path, step: Callable[[str], None] | None = None) -> list[Section]:
    """Every numbered section of the report, in order; ``step`` is told each one's name (``cycles``)
    as it begins (the progress bar: :func:`build_report`)."""
    made = []
    for make in section_makers():
        if step is not None:
            step(make.__name__.removesuffix("_section"))
        made.append(make(inputs, out))
    return made


def scenes_note(inputs: Inputs) -> str:
    """A paragraph saying how the report names scenes, where two scenes of the inputs share the
    name in their files (the built-in ``room`` and ``thesis/room`` both say ``name: room``); ""
    where none do."""
    shared = inputs.shared_names()
    if not shared:
        return ""
    each = "; ".join(f"{esc(quoted(name))} is the name in the files of {esc(listing(labels))}"
                     for name, labels in shared)
    return ("<p>Scenes are named by their files throughout (a built-in scene by its path under scenes/ without "
            ".yaml: thesis/room is scenes/thesis/room.yaml; another by the path its config gave), not by the "
            f"name inside the file, which different scenes here share: {each}.</p>")


def linked(formats) -> str:
    """What the page says of each figure's files: ``Each figure links to its PNG file.``, or with
    ``pdf`` and ``svg`` its PNG, PDF and SVG files."""
    names = [f.upper() for f in formats]
    return f"Each figure links to its {listing(names)} file{'s' * (len(names) > 1)}."


def default_out(dirs: list[Path]) -> Path:
    """``DIR/report`` for one folder; several folders need ``--out``."""
    if len(dirs) == 1:
        return Path(dirs[0]) / "report"
    raise ValueError("several folders: name the report folder with --out")


def check_out(out: Path | None, dirs: list[Path], also: Iterable[Path] = ()) -> Path:
    """The report's folder (``out``; None: ``DIR/report`` of the one folder of ``dirs``), refused as
    its write refuses it (:func:`~tlm.storage.check_destination`: an InputError, or an EnvironmentFailure
    where its parent cannot be written, which says ``give --out`` where the folder was the default); and
    where it is, or holds, one of ``dirs`` or ``also`` (the inputs, ``tlm plots``' --runs and --configs):
    the report replaces its folder whole, which would remove them."""
    where = Path(out) if out is not None else default_out(dirs)
    try:
        resolved = check_destination(where, MARKER)
    except EnvironmentFailure as e:
        if out is not None:
            raise
        raise EnvironmentFailure(f"{e}; give --out") from None
    for d in (*dirs, *also):
        if resolved == (d := Path(d)).resolve() or resolved in d.resolve().parents:
            raise InputError(f"{quoted(where)} {'is' if resolved == d.resolve() else 'holds'} {quoted(d)}, an input of "
                             "the report: writing the report there would remove it (the report replaces its folder "
                             "whole); name another folder", key="--out")
    return resolved


def build_report(dirs: list[Path], out: Path | None = None, title: str | None = None,
                 scaling_sweeps: list[Path] | None = None, *, formats=None, dpi: int | None = None,
                 note: Callable[[str], None] | None = None, progress: bool = False) -> Path:
    """Read ``dirs``, write the report folder ``out``; returns the path of ``report.html``.

    ``formats``: the files each figure is written as, ``png`` and any of ``pdf`` and ``svg``
    (names, or ``"pdf,svg"``; the PNG always, as the page embeds it); ``dpi``: the PNG's
    resolution, from 50 to 1200. None: what :func:`~tlm.report.common.figure_output` set around
    the call, by default the PNG alone at 110 dpi. A bad value raises an
    :class:`~tlm.errors.InputError` before anything is read or written.

    ``scaling_sweeps``: sweep folders that a scaling study among ``dirs`` was fitted from;
    the scaling section draws their idle fractions per PM, and no other section reads them
    (their eq. 5.2 fits are the study's). By default, the sweeps the scaling studies
    recorded in their ``eq52.json`` that still exist and are not inputs themselves.

    ``note``: gets each of the inputs' notes (:attr:`~tlm.report.collect.Inputs.notes`: a folder
    passed over, a link not followed, ...; :attr:`~tlm.report.collect.Inputs.damaged`: a damaged file,
    left out of the report) as soon as the inputs are read; None: each is written on stderr
    (``tlm: note: ...``). The page says them either way (the damaged files with the warnings).

    ``progress``: a bar on stderr, drawn only when it is a terminal (:func:`tlm.progress.progress_bar`),
    with a step for reading the inputs, each section, the summary and the page, named as it runs
    (``report: cycles``); gone at the end. Nothing else the report prints or writes changes with it.

    From several threads of one process at once, each report writes what it writes alone: their figures
    are drawn one report at a time (:data:`DRAWING`; the bar says ``report: waiting for another report's
    figures`` meanwhile).
    """
    from tlm.experiments.provenance import identities_remembered

    # (the files set for every figure; a scene file's identity, which judges each thesis cell, computed once;
    # the objects the process held before, not scanned again by the collector while the figures are made)
    with figure_output(formats, dpi), identities_remembered(), older_objects_frozen():
        return _build_report(dirs, out, title, scaling_sweeps, note, progress)


# matplotlib draws text through state that every thread of the process shares: mathtext's one parser (its
# state while it parses) and its cache of parsed labels, which hold the fonts of the thread that parsed them,
# and the rcParams set around a PDF's or SVG's save (:func:`tlm.report.common.write_png`). Two reports drawing
# at once in one process drew some tick labels wrong ("10^6" as "0^6", a stray "1") or failed ("failed to load
# glyph"): a report's figures are drawn while it holds this lock, one report at a time (reentrant: a report
# written from inside another's drawing does not wait for itself; released however the drawing ends).
DRAWING = threading.RLock()


@contextlib.contextmanager
def drawing(bar=None) -> Iterator[None]:
    """Within it, this thread holds :data:`DRAWING`; where another thread's report holds it, the progress
    bar ``bar`` says so while this one waits."""
    if not DRAWING.acquire(blocking=False):
        if bar is not None:
            bar.set_description_str("report: waiting for another report's figures", refresh=True)
        DRAWING.acquire()
    try:
        yield
    finally:
        DRAWING.release()


_FROZEN = threading.Lock()
# the reports being written now (in this process's threads), and whether the first of them froze the objects
_FREEZERS = {"reports": 0, "froze": False}


@contextlib.contextmanager
def older_objects_frozen() -> Iterator[None]:
    """Within it, the objects the process held as it began are left out of the cyclic garbage
    collector's passes (:func:`gc.freeze`), and given back to it at its end (:func:`gc.unfreeze`,
    by the last of several reports written at once). A report makes and drops many objects (each
    figure's artists, ticks, texts and paths), and each full pass of the collector that they set
    off scanned every object of the process again: after a run, the compiled kernels', the
    scene's, matplotlib's and the run's own (about 180,000 objects, 0.11 - 0.19 s a pass here,
    of a report's 1.5 s). The report's own garbage is collected as before; a cycle of older
    objects that is garbage waits for the collector's first full pass after the report.

    Nothing is frozen where the collector is off (:func:`gc.disable`) or objects are frozen
    already (a caller's own :func:`gc.freeze`, which the end of a report must not undo)."""
    with _FROZEN:
        if _FREEZERS["reports"] == 0:
            _FREEZERS["froze"] = gc.isenabled() and gc.get_freeze_count() == 0
            if _FREEZERS["froze"]:
                gc.freeze()
        _FREEZERS["reports"] += 1
    try:
        yield
    finally:
        with _FROZEN:
            _FREEZERS["reports"] -= 1
            if _FREEZERS["reports"] == 0 and _FREEZERS["froze"]:
                _FREEZERS["froze"] = False
                gc.unfreeze()


def _build_report(dirs: list[Path], out: Path | None, title: str | None, scaling_sweeps: list[Path] | None,
                  note: Callable[[str], None] | None, progress: bool = False) -> Path:
    from tlm.progress import Ticking, progress_bar

    # (its steps: the inputs read, each section, the summary and the page; redrawn meanwhile, so that its
    # time goes on in a long section; no rate or time left: one section takes 100 times another's time)
    with progress_bar(progress, desc="report: read", total=SECTIONS + 3, unit="step", leave=False,
                      bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}]") as bar, Ticking(bar):
        return _build_report_steps(dirs, out, title, scaling_sweeps, note, bar)


def _found(dirs: list[Path]) -> None:
    """An InputError naming the first of ``dirs`` that is not there ("not found", not the "is not a
    folder" of one that is there and is a file)."""
    for d in dirs:
        if not Path(d).exists():
            raise InputError("not found", source=str(d))


def _build_report_steps(dirs: list[Path], out: Path | None, title: str | None, scaling_sweeps: list[Path] | None,
                        note: Callable[[str], None] | None, bar) -> Path:
    t0 = time.perf_counter()

    def step(name: str) -> None:  # (the step ``name`` begins: the one before it is done)
        bar.update()
        bar.set_description_str(f"report: {name}", refresh=True)

    def say(line: str) -> None:  # (a note on stderr, the bar cleared for it and drawn again below it)
        with bar.external_write_mode(file=sys.stderr):
            if note is not None:
                note(line)
            else:
                sys.stderr.write(f"tlm: note: {escaped_line(line)}\n")
                sys.stderr.flush()

    _found([*dirs, *(scaling_sweeps or ())])
    dirs = distinct_folders(dirs)  # (a folder given twice is read once)
    check_out(out, dirs, scaling_sweeps or ())  # (refused as its write would refuse it, before the inputs are read)
    # (the report's own folder, where it lies among the inputs, is not read: runs/report)
    inputs = read(dirs, skip=Path(out) if out is not None else Path(dirs[0]) / "report" if len(dirs) == 1 else None)
    for line in [*inputs.notes, *inputs.damaged]:  # (the folders passed over, the damaged files left out, said
        # now too: the page may not be read soon)
        say(line)
    sys.stderr.flush()
    recorded = scaling_sweeps is None  # (not given: a damaged one is said and left out, as a damaged input is)
    if scaling_sweeps is None:  # the sweeps a scaling study among the inputs recorded, where they still are
        shown = {sw.path.resolve() for sw in inputs.sweeps}
        scaling_sweeps = []
        for st in inputs.of_kind("scaling"):
            for rel in st.meta.get("sweeps", []):
                p = (st.path / rel).resolve()  # (relative to the study's folder; an absolute path stays)
                if p in shown or p in scaling_sweeps:
                    continue
                if (p / "sweep.jsonl").is_file():
                    scaling_sweeps.append(p)
                else:
                    inputs.scaling_missing.append(f"{st.path.name}: its sweep {p} is gone: no idle fractions from it")
    if scaling_sweeps:
        try:
            extra = read([Path(d) for d in scaling_sweeps], reads=inputs.reads)  # (each file read once a report)
        except InputError as e:
            if not recorded:
                raise
            extra = Inputs([])
            extra.damaged.append(f"{e}: the idle fractions of the scaling study's sweeps are left out of this report")
        if extra.studies or any(r.kind != "sweep-point" for r in extra.runs):
            raise InputError("a scaling study's sweeps must be sweep folders",
                             source=", ".join(str(d) for d in scaling_sweeps))
        inputs.scaling_sweeps = extra.sweeps
        for line in extra.damaged:  # (a damaged point of such a sweep: left out of the idle fractions, said)
            inputs.damaged.append(line)
            say(line)
    out = Path(out) if out is not None else default_out(dirs)
    with atomic_folder(out, MARKER) as tmp:
        for name in KEPT_FOLDERS:  # what others wrote into the report's folder stays
            if (out / name).is_dir():
                shutil.copytree(out / name, tmp / name)
        try:
            # (a file that collect.read read, not read again: a scaling study's sweep; the figures drawn by one
            # report at a time in this process: :data:`DRAWING`)
            with reading(inputs.reads), drawing(bar):
                # (no bar drawn: sections called as before, with the inputs and the folder alone)
                secs = sections(inputs, tmp, step) if not bar.disable else sections(inputs, tmp)
                from tlm.report.summary import summary_section

                step("summary")
                summary = summary_section(inputs, tmp)
            step("page")
        finally:
            forget_names(tmp)  # (the figures are written: their names need no record now)
        kinds = ", ".join(f"{esc(d)}" for d in dirs)
        if inputs.scaling_sweeps:
            kinds += " (and, for the scaling section only, " + ", ".join(
                esc(sw.path) for sw in inputs.scaling_sweeps) + ")"
        n_fig = len(summary.figures) + sum(len(s.figures) for s in secs)  # (every figure the page embeds)
        studies = ", ".join(sorted({s.kind for s in inputs.studies})) or "none"
        intro = (f"<p>Inputs: {kinds}: {count(len(inputs.runs), 'run')}, {count(len(inputs.sweeps), 'sweep')}, "
                 f"{count(len(inputs.studies), 'study', 'studies')} ({esc(studies)})"
                 + (f"; {count(len(inputs.damaged), 'damaged file')} left out (see the warnings below)"
                    if inputs.damaged else "") + "."
                 f" {count(n_fig, 'figure')}, written {esc(datetime.datetime.now().isoformat(timespec='seconds'))} "
                 f"in {time.perf_counter() - t0:.1f} s. {linked(current_output().formats)}</p>")
        intro += "".join(f'<p class="note">{esc(n)}.</p>' for n in inputs.notes)  # (a folder with no tlm output)
        intro += scenes_note(inputs)
        text = page(title or f"tlm report: {', '.join(path_labels(dirs))}", intro, secs, tmp,
                    summary=summary, notice=warnings_html(inputs))
        (tmp / MARKER).write_text(drawable(text), encoding="utf-8")  # (a folder name of bytes not UTF-8 escaped)
    return Path(out) / MARKER
