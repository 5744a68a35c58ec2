"""tlm's Python API, the studies and the reports: the functions of many experiments (``tlm sweep``,
``tlm scaling``, ``tlm thesis``, ``tlm calibrate``, ``tlm granularity``, ``tlm error-vs-cost``,
``tlm extreme``) and of the report of their folders (``tlm report``, ``tlm plots``).

Read them from :mod:`tlm.api` (or ``tlm``), which re-exports every public name of this
module: ``tlm.sweep is tlm.api.sweep``. A study takes its experiment file's path or a
built-in experiment's name, as its ``tlm`` command does (:func:`tlm.api.experiment_path`);
bad input raises :class:`~tlm.errors.InputError`, and a layer is imported when a function
first needs it, whole (:func:`tlm.whole_imports.imports_whole`), as in :mod:`tlm.api`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from tlm.api_common import argument_names, arguments_text, flags_are_kept
from tlm.api_common import checked as _checked
from tlm.api_common import experiment_file as _experiment_file
from tlm.api_common import folder as _folder
from tlm.api_common import kind_check as _kind_check
from tlm.api_common import shown as _shown
from tlm.config import config_from_dict
from tlm.errors import InputError, quoted, shell_word
from tlm.whole_imports import imports_whole

if TYPE_CHECKING:
    import pandas as pd

    from tlm.arch.costs import Programs
    from tlm.experiments.sweep import Outcome
    from tlm.experiments.sweep_plan import SweepPlan


# ---------------------------------------------------------------- the arguments' checks (tlm.api's too)


def callback(value: object, name: str, what: str = "a function of one line") -> Callable | None:
    """The argument ``name``'s ``value`` where it is a function (or None: none); anything else is an
    InputError naming the argument, before any work (it was called only once the work was done: a
    render's whole frame, then ``TypeError: 'int' object is not callable``)."""
    if value is not None and not callable(value):
        raise InputError(f"{_shown(value)} is not a function: give {what}, or None", key=name)
    return value


def out_folder(out: object, key: str = "out") -> Path:
    """``out`` as the path of a folder to write (:func:`~tlm.api_common.folder`), ``~`` expanded (:func:`home`)."""
    return home(_folder(out, key), key)


def home(path: str | os.PathLike, key: str) -> Path:
    """``path`` with its ``~`` (``~/x``, ``~user/x``) expanded; a ``~`` that names no home folder
    (``~nosuchuser/x``, or ``~`` with no HOME) is an InputError naming the argument ``key`` (it was
    ``RuntimeError: Could not determine home directory``)."""
    try:
        return Path(path).expanduser()
    except RuntimeError:
        tilde = Path(path).parts[0]
        raise InputError(f"{quoted(path)}: {tilde} names no home folder ("
                         f"{'no such user' if tilde != '~' else 'HOME is not set'}): give the path in full",
                         key=key) from None


def expanded(path: object, key: str) -> object:
    """A path argument ``key`` with ``~`` expanded (``"~/runs/x"``: the home folder's, not ``./~/runs/x``;
    :func:`home`); anything else as given, for its own check to name."""
    if isinstance(path, (str, os.PathLike)) and os.fspath(path).startswith("~"):
        return home(path, key)
    return path


def folder_list(value: object, key: str, what: str) -> list[Path]:
    """``value``, a list of folders or one folder's path (a string or a Path: that folder, not the
    characters of its name), as paths (``~`` expanded); anything else, an item that is no path, or
    no folder at all, is an InputError naming the argument ``key``; ``what``: what the folders are."""
    if isinstance(value, (str, os.PathLike)):
        value = [value]
    elif not isinstance(value, Iterable) or isinstance(value, bytes):
        raise InputError(f"{_shown(value)} is not a folder or a list of folders: give {what}", key=key)
    given = list(value)
    for d in given:
        if not isinstance(d, (str, os.PathLike)):
            raise InputError(f"{_shown(d)} is not a folder's path: give {what}", key=key)
    if not given:
        raise InputError(f"no folder given: name {what}", key=key)
    return [home(d, key) for d in given]


def _formats(formats: object) -> str | list[str] | None:
    """``formats`` as :func:`write_report` takes it: None, ``"pdf,svg"`` or names; anything else is an
    InputError naming the argument (the report's own check names the values)."""
    if formats is None or isinstance(formats, str):
        return formats
    if isinstance(formats, Iterable) and not isinstance(formats, (bytes, os.PathLike)):
        given = list(formats)
        if all(isinstance(f, str) for f in given):
            return given
    raise InputError(f"{_shown(formats)} is not figure formats: give \"pdf,svg\" or a list of names of png, "
                     "pdf and svg (None: the PNG alone)", key="formats")


def _experiment(path: object, command: str) -> Path:
    """The experiment file a study was given (:func:`~tlm.api_common.experiment_file`), ``~`` expanded."""
    return _experiment_file(expanded(path, "path"), command)


def _study(path: object, command: str, out: object = None):
    """``(the study file ``tlm COMMAND`` runs, a block whose one read of it checks its kind)``: a file that is another
    command's refused, naming it (:func:`~tlm.experiments.study.checking`, :func:`~tlm.api_common.kind_check`); given
    ``out``, the study's folder (checked after the file's path: :func:`out_folder`), the block holds it too
    (:func:`_held`)."""
    found = _experiment(path, command)
    return found, _running(found, command, None if out is None else out_folder(out))


@contextmanager
def _running(found: Path, command: str, out: Path | None) -> Iterator[None]:
    """:func:`_study`'s block: the folder ``out`` held (:func:`_held`), then the study file ``found`` checked."""
    from tlm.experiments.study import checking

    with ExitStack() as block:
        if out is not None:
            block.enter_context(_held(out, _MARKERS[command]))
        block.enter_context(checking(found, _kind_check(command)))
        yield


# the file that marks each study's output (its folder's :func:`tlm.storage.check_destination`)
_MARKERS = {"thesis": "thesis_comparison.csv", "granularity": "granularity.jsonl", "error-vs-cost": "rows.jsonl",
            "extreme": "extreme.jsonl", "scaling": "eq52.json"}


@contextmanager
def _held(out: Path, marker: str) -> Iterator[None]:
    """The study folder ``out`` (``marker``: its file) held by this process while the study runs, as its command
    holds it (:func:`tlm.claims.claimed`, a study's claim): another process's run, study, sweep or report into it
    meanwhile is refused at once, naming this one, and this study is refused one that another process writes now,
    before any work (two studies into one folder ended last-wins: h422). A bad ``out`` is refused first, as such
    (:func:`tlm.storage.check_destination`). From the command line, which holds it already to the end of its
    report (:func:`tlm.cli_report.study_claimed`), the claim is that one, shared (:func:`~tlm.claims.claimed`
    counts its holders in a process), never a second."""
    from tlm.claims import claimed
    from tlm.storage import check_destination

    check_destination(out, marker)
    with claimed(out, "study"):
        yield


# ---------------------------------------------------------------- many experiments


def _overrides(overrides: Iterable[str] | None) -> tuple[str, ...]:
    """A study's or a sweep's ``overrides``: ``dotted.key=value`` strings, as ``tlm run --set``
    takes them (``tlm sweep --set``, ``tlm thesis --set``, ...); None: none."""
    if overrides is None:
        return ()
    if isinstance(overrides, (str, bytes, dict)) or not isinstance(overrides, Iterable):
        # (the shape asked for against the one given, in the argument's own words: no --set, which
        # argument_names would rename to overrides)
        if isinstance(overrides, str):
            given = f"one string: put it in a list, [{_shown(overrides)}]"
        elif isinstance(overrides, dict):
            given = "a mapping: one 'dotted.key=value' string per key, ['render.spp=2', ...]"
        else:
            name = type(overrides).__name__
            given = f"{'an' if name[:1].lower() in 'aeiou' else 'a'} {name}"
        raise InputError(f"{_shown(overrides)}: overrides are a list of dotted.key=value strings, not {given}",
                         key="overrides")
    given = tuple(overrides)
    for o in given:
        if not isinstance(o, str):
            raise InputError(f"{_shown(o)} is not a dotted.key=value string", key="overrides")
    return given


@argument_names
@imports_whole
def run_sweep(path: str | Path, out: str | Path, *, jobs: int | None = None, dask: str | None = None,
              progress: bool = False, dask_wait: float | None = None,
              warn: Callable[[str], None] | None = None, overrides: Iterable[str] | None = None,
              reference: bool = False, say: Callable[[str], None] | None = None,
              dry_run: bool = False) -> Outcome | SweepPlan:
    """Run every point of the sweep file ``path`` (or the built-in sweep of that name:
    :func:`experiment_path`) not already done in ``out`` (``tlm sweep``); returns the rows
    (``.rows``, dicts; ``.table``, a DataFrame) and the counts of points ok, failed, skipped
    and rendered. ``jobs``: worker processes (default the CPUs available to
    the process, within a container's CPU quota, as for ``render.threads``; 1: in this
    process); ``dask``: ``"local"`` or a scheduler's address; ``dask_wait`` (with ``dask``): the
    seconds the sweep waits while the scheduler has no worker before it stops (``tlm sweep
    --dask-wait``; default 300). ``warn`` gets each of the sweep's warning lines as it is known
    (the factors' before the points run); None: nothing is printed, and every line is in
    ``Outcome.warnings`` either way. ``overrides``: ``dotted.key=value`` strings (``tlm sweep --set``)
    applied to every point's base config before its factors (a factor's key refused): in each
    point's config and hash, and in ``sweep.yaml``. ``reference`` (``tlm sweep --reference``): each photon-map
    reference the points need that is not cached is computed and cached before them, so that they are
    measured; ``say`` gets its lines (as ``tlm reference`` prints them). ``dry_run`` (``tlm sweep --dry-run``):
    nothing is run or written (no output folder, no cache entry): the same checks of the arguments, the sweep
    file and ``out``, then what the sweep would do, a :class:`~tlm.experiments.sweep_plan.SweepPlan` (``.points``,
    ``.done``, ``.to_run``, ``.frames``, ``.frames_cached``, ``.renders``, ``.references`` with ``reference``,
    ``.stale``, ``.other_folders``, ``.warnings``; ``.lines()`` and ``.record()``, its summary and its JSON)."""
    from tlm.experiments.sweep import run_sweep as run_all
    from tlm.experiments.sweep_plan import plan_sweep

    jobs = _checked(jobs, "jobs", int, "a whole number of worker processes", none="the CPUs available")
    progress = _checked(progress, "progress", bool)
    warn, say = callback(warn, "warn"), callback(say, "say")
    check = _kind_check("sweep")  # (a run config's, a study's file: the command to use, from the sweep's one read)
    if _checked(dry_run, "dry_run", bool):
        return plan_sweep(_experiment(path, "sweep"), out_folder(out), jobs=jobs, dask=dask, dask_wait=dask_wait,
                          overrides=_overrides(overrides), reference=_checked(reference, "reference", bool),
                          check=check)
    return run_all(_experiment(path, "sweep"), out_folder(out), jobs=jobs, dask=dask, progress=progress,
                   dask_wait=dask_wait, warn=warn, overrides=_overrides(overrides),
                   reference=_checked(reference, "reference", bool), say=say, check=check)


@argument_names
@imports_whole
def sweep(path: str | Path, out: str | Path, *, jobs: int | None = None, dask: str | None = None,
          progress: bool = False, dask_wait: float | None = None,
          warn: Callable[[str], None] | None = None, overrides: Iterable[str] | None = None,
          reference: bool = False, say: Callable[[str], None] | None = None) -> pd.DataFrame:
    """Run the sweep file ``path`` (or the built-in sweep of that name) into ``out``
    (:func:`run_sweep`) and return its rows as a
    pandas DataFrame: one row per point, in point order, the columns of ``sweep.csv``
    (``point``, ``hash``, ``status``, ``error``, the factors, ``cycles.*``, ``fps``, ...).
    The sweep's warnings (:attr:`Outcome.warnings`: a factor no point read, a cache its workers
    could not write, point folders not its own; what ``tlm sweep`` prints) are the table's
    ``attrs["warnings"]``, a list of lines (empty: none); ``warn`` gets each as it is known too.
    None: nothing is printed, as by :func:`run_sweep`. ``attrs["findings"]``: what ``tlm report`` of ``out``
    says of the sweep, a list of plain lines (:func:`_findings`; empty: no factor or no ok point)."""
    done = run_sweep(path, out, jobs=jobs, dask=dask, progress=progress, dask_wait=dask_wait, warn=warn,
                     overrides=overrides, reference=reference, say=say)
    table = done.table
    table.attrs["warnings"] = list(done.warnings)
    table.attrs["findings"] = _findings(done.out)
    return table


def _findings(folder: Path) -> list[str]:
    """What ``tlm report`` of the sweep ``folder`` finds, as plain lines: the code of its summary's
    (:func:`tlm.report.summary_effects.sweep_findings`: the factor that moves the frame rate most, ties, factors that
    move with it or change nothing, the best point; then ``error_factor``: the image error's), tags left out."""
    import html
    import re

    from tlm.report.collect import read
    from tlm.report.summary_effects import error_factor, sweep_findings

    inputs = read([Path(folder)])
    lines = [*sweep_findings(inputs), error_factor(inputs).strip()]
    return [html.unescape(re.sub(r"<[^>]+>", "", line)) for line in lines if line]


@argument_names
@imports_whole
def scaling(sweeps: Iterable[str | Path], out: str | Path) -> dict:
    """Fit eq. 5.2 to sweeps over ``arch.pipelines`` (``tlm scaling``): the fits, a table and
    a figure per scene in ``out``. ``sweeps``: a list of sweep folders, or one folder's path; none
    is an InputError, nothing written."""
    from tlm.experiments.scaling import analyse
    from tlm.report.scaling import plot_scaling

    dirs = folder_list(sweeps, "sweeps", "the sweep folders to fit (tlm sweep's output folders)")
    out = out_folder(out)
    if not dirs:  # (no folder: the fit's own error, before the folder's claim)
        return analyse(dirs, out, plot=plot_scaling)
    with _held(out, _MARKERS["scaling"]):
        return analyse(dirs, out, plot=plot_scaling)


@argument_names
@imports_whole
def thesis(path: str | Path, out: str | Path, *, progress: Callable[[str, str, dict], None] | None = None,
           bar: bool = False, overrides: Iterable[str] | None = None,
           warn: Callable[[str], None] | None = None) -> dict:
    """Tables I-III (``tlm thesis``): every scene and mode of the study file ``path`` (or the
    built-in study of that name, ``"thesis"``) beside the thesis; returns ``rows``, ``summary``
    and ``warnings``. ``progress`` gets ``(scene, mode, results)``. ``overrides``: ``dotted.key=value``
    strings (``tlm thesis --set``) applied to the study's base (not ``scene`` nor ``mode``).
    ``warnings``: the study's warning lines, each once: a ``--set`` some cells never read, then each
    distinct warning of the cells' ``results.json`` with the cells it is of (``tlm thesis`` prints
    them on stderr after its table); ``warn`` gets each once the cells ran (None: nothing is printed)."""
    from tlm.experiments.thesis import run_thesis

    bar = _checked(bar, "bar", bool)
    progress = callback(progress, "progress", "a function of (scene, mode, results)")
    warn = callback(warn, "warn")
    path, checked = _study(path, "thesis", out)
    with checked:
        return run_thesis(path, out_folder(out), progress, bar=bar, overrides=_overrides(overrides),
                          warn=warn if warn is not None else (lambda line: None))


@argument_names
@imports_whole
def calibrate(path: str | Path, *, progress: Callable[..., None] | None = None, held_out: bool = False
              ) -> tuple[Programs | None, dict]:
    """``tlm calibrate`` of the study ``path`` (a file, or a built-in study's name): the PM programs' free parameters
    fitted to the RCast column of Tables I-III; the table and the report (``cells``; ``fit``: how well determined).
    ``held_out`` (``--leave-one-out``): ``(None, each scene's fitted cells by a fit to the others)``, no table."""
    from tlm.experiments import thesis

    progress = callback(progress, "progress", "a function of (iteration, report)")
    path, checked = _study(path, "calibrate")
    with checked:
        return (None, thesis.leave_one_out(path, progress=progress)) if held_out else thesis.calibrate(path,
                                                                                                       progress=progress)


def tlm_version() -> str:
    """The version of the tlm code that runs (:func:`tlm.experiments.provenance.tlm_version`; ``tlm --version``'s)."""
    from tlm.experiments.provenance import tlm_version as running

    return running()


def version_line() -> str:
    """``tlm --version``'s line: what identifies the code that runs, as ``results.json`` records it
    (:func:`tlm.experiments.provenance.version_line`: the version, the git commit and whether the checkout is
    modified, the code fingerprint)."""
    from tlm.experiments.provenance import version_line as line

    return line()


def _package_dir() -> Path:
    """The folder of the tlm package that runs (site-packages/tlm in an installed copy)."""
    return Path(__file__).resolve().parent


def in_checkout(package: str | Path) -> bool:
    """Whether the tlm package folder ``package`` is a checkout's (a source tree: a
    ``pyproject.toml`` or ``.git`` beside it) rather than an installed copy (inside a
    ``site-packages`` or ``dist-packages`` folder, or with neither beside it)."""
    package = Path(package)
    if {part.lower() for part in package.parts} & {"site-packages", "dist-packages"}:
        return False
    return (package.parent / "pyproject.toml").is_file() or (package.parent / ".git").exists()


def _refuse_installed(target: Path, study: str | Path | None = None) -> None:
    """An InputError, nothing written, where the default table ``target`` lies inside the
    package of an installed copy (its packaged ``tlm/arch/programs.yaml``): a calibration
    there would change the table of every user of that installation, and the fingerprint
    of its code (every cached result of it would be stale). Its message reads the same from
    the command line and from Python: it names each way by its whole command or call, no
    bare flag that :func:`~tlm.api_common.argument_names` would rename for a caller in Python
    (``--write FILE`` before the study, where that command is told from a flag of the call's
    at any length of the study's path). Its commands run as printed: ``study``, the study
    as given (a path, a built-in study's name; quoted: :func:`~tlm.errors.shell_word`), else
    ``STUDY`` (:func:`write_calibration`, which is not given it)."""
    package = _package_dir()
    if not in_checkout(package) and Path(target).resolve().is_relative_to(package):
        given = "STUDY" if study is None else os.fspath(study)
        named = shell_word(f"./{given}" if given.startswith("-") else given)  # (-th.yaml: no flag to argparse)
        raise InputError(f"not written: the table is inside the installed tlm package ({package}, not a checkout), "
                         f"where a fit would change it for every user of this installation: name another table "
                         f"(tlm calibrate --write FILE {named}, or tlm.write_calibration's target=), or fit and "
                         f"print only (tlm calibrate --dry-run {named}, or tlm.calibrate alone)", source=str(target))


@imports_whole
def calibration_table(path: str | Path, target: str | Path | None = None) -> Path:
    """The instruction table that :func:`write_calibration` writes for a :func:`calibrate`
    of the study ``path`` (a file, or a built-in study's name): ``target``, else the study's own table (its
    ``base.arch.programs``), else the packaged ``tlm/arch/programs.yaml``. Refused with an
    :class:`InputError` before any fit, as :func:`write_calibration` refuses it: that
    default table inside the package of an installed copy (:func:`in_checkout`)."""
    from tlm.arch.costs import DEFAULT_PATH
    from tlm.experiments.run import programs_for
    from tlm.experiments.thesis import load_study

    if target is not None:  # (named: written where it is named, an installed package's folder included)
        return Path(target)
    given = path  # (as the user gave it: the refusal's commands name it)
    path, checked = _study(path, "calibrate")
    with checked:
        base, scenes, _, folder = load_study(path)
    used = Path(programs_for(config_from_dict({**base, "scene": scenes[0], "mode": "rcast"}, str(path)),
                             folder).source)
    target = used if used.is_file() else DEFAULT_PATH
    _refuse_installed(target, given)
    return target


@argument_names
@imports_whole
def write_calibration(programs: Programs, report: dict, target: str | Path | None = None,
                      command: str = "") -> Path:
    """Write a :func:`calibrate` fit into the instruction table ``target``, keeping its
    comments; returns the path written.

    ``target`` defaults to the table the study uses (its ``arch.programs``, else the
    packaged ``tlm/arch/programs.yaml``). Refused with a one-line
    :class:`~tlm.errors.InputError`, nothing written: an empty path, a folder, a path whose
    folder does not exist, the packaged table from a fit whose ``report`` says it is
    not comparable with the thesis (``report["not_comparable"]``: its parameters would
    measure that setting, not the model; name another file), and, unless ``target`` names
    it, a table inside the package of an installed copy (:func:`in_checkout`)."""
    from tlm.arch.costs import DEFAULT_PATH
    from tlm.experiments.thesis import write_calibrated

    if target is not None and not str(target).strip():
        raise InputError("an empty path names no table (leave it out for the study's own table)", key="--write")
    named = target is not None
    if target is None:
        used = Path(programs.source)
        target = used if used.is_file() else DEFAULT_PATH
    target = Path(target)
    if target.is_dir():
        raise InputError("is a folder, not a table file", source=str(target), key="--write")
    if not target.parent.is_dir():
        raise InputError(f"its folder {target.parent} does not exist", source=str(target), key="--write")
    if not named:
        _refuse_installed(target)
    differ = report.get("not_comparable") or {}
    if differ and target.resolve() == DEFAULT_PATH.resolve():
        why = "; ".join(f"{s} is {', '.join(w)}" for s, w in differ.items())
        raise InputError(f"not written: the packaged table is fitted to the thesis's setting only, and this study's "
                         f"is not ({why}); name another file with --write", source=str(target))
    write_calibrated(programs, report, target, command)
    return target


@argument_names
@imports_whole
def granularity(path: str | Path, out: str | Path, *, progress: Callable | None = None,
                overrides: Iterable[str] | None = None, warn: Callable[[str], None] | None = None,
                start: Callable[[list[int]], None] | None = None) -> StudyRows:
    """Cycle error of coarse packets against one ray per packet (``tlm granularity``) for the
    study file ``path`` (or the built-in study of that name): a list of dicts (:class:`StudyRows`).
    ``overrides``: ``dotted.key=value`` strings (``tlm granularity --set``) applied to its base (not
    ``arch.packet_size``). Its warnings (an override that sets nothing, ``render={}``), which ``tlm
    granularity`` prints on stderr, are the rows' ``attrs["warnings"]``; ``warn`` gets each as it is
    known too (None: nothing is printed). Its notes, which ``tlm granularity`` prints under its table,
    are their ``attrs["notes"]``: where two or more packet sizes are at or past the items of the frame's
    largest phase, the line saying they run every phase as one packet, so their rows are the same; with
    them ``attrs["one_packet"]`` (the sizes at or past it, a list, maybe of one) and
    ``attrs["largest_phase"]`` (``{"phase", "items", "unit"}``, with ``tiles`` where its stage has
    several; None where no phase is cut by the packet size), as its ``granularity_summary.json`` keeps
    them (h407). ``progress(packet_size, timing, seconds)`` is called as each
    size is simulated (``timing``: its Timing; ``len(timing.frames)`` the frames it ran, more than
    ``arch.frames`` where the stream ran on: the rows' ``frames`` and ``*_per_frame`` columns);
    ``start(packet_sizes)`` once before the first, with the sizes in the order they are simulated
    (increasing; ``tlm granularity`` aligns its progress lines by the widest)."""
    from tlm.experiments.granularity import run_granularity

    progress = callback(progress, "progress", "a function of (packet size, timing, seconds)")
    start = callback(start, "start", "a function of (packet sizes)")
    warned = _Warned(callback(warn, "warn"))
    path, checked = _study(path, "granularity", out)
    kept: list[dict] = []  # (the study's granularity_summary.json, as it was written)
    with checked:
        rows = run_granularity(path, out_folder(out), progress, overrides=_overrides(overrides), start=start,
                               noted=kept.append, **warned.arguments())
    record = kept[-1] if kept else {}
    found = StudyRows(rows, notes=record.get("notes") or [], warnings=warned.lines)
    found.attrs.update(one_packet=list(record.get("one_packet") or []), largest_phase=record.get("largest_phase"))
    return found


class _Warned:
    """A study's warning lines, kept (and given to the caller's ``warn``), as a call of the API returns
    them; from the command line (:func:`~tlm.api_common.flags_are_kept`) the study prints them itself."""

    def __init__(self, hear: Callable[[str], None] | None) -> None:
        self.hear, self.lines = hear, []

    def __call__(self, line: str) -> None:
        self.lines.append(line)
        if self.hear is not None:
            self.hear(line)

    def arguments(self) -> dict:
        """The study's ``via`` and ``warned`` (none from the command line: ``--set``, on stderr)."""
        return {} if flags_are_kept() else {"via": "the overrides", "warned": self}



def granularity_frames(rows: list[dict]) -> dict[int, list[int]]:
    """``{frames: [packet sizes]}`` of :func:`granularity`'s rows where they ran different frame counts, ``{}``
    where they ran the same (:func:`tlm.experiments.granularity.frames_differ`, as the report groups them): what
    ``tlm granularity`` says under its table."""
    from tlm.experiments.granularity import frames_differ

    return frames_differ(rows)


def _stderr_warning(line: str) -> None:
    from tlm.storage import warn

    warn(line)


class StudyRows(list):
    """A study's rows, a list of dicts (one per point), with ``attrs`` as a pandas DataFrame has
    them (:func:`sweep`'s table): ``attrs["notes"]`` and ``attrs["warnings"]``, lists of the lines
    the study said (empty: none)."""

    def __init__(self, rows: Iterable[dict] = (), notes: Iterable[str] = (), warnings: Iterable[str] = ()):
        super().__init__(rows)
        self.attrs = {"notes": list(notes), "warnings": list(warnings)}


@argument_names
@imports_whole
def error_vs_cost(path: str | Path, out: str | Path, *, truth_spp: int = 4096,
                  progress: Callable[[int, int, dict], None] | None = None,
                  note: Callable[[str], None] | None = None, overrides: Iterable[str] | None = None,
                  warn: Callable[[str], None] | None = None) -> StudyRows:
    """Photon-map filters, image error against work and host time (``tlm error-vs-cost``):
    one row per point of the experiment file ``path`` (or the built-in experiment of that
    name), a list of dicts (:class:`StudyRows`); ``truth_spp``: samples per pixel of Mitsuba 3's
    ground truth (0: none); ``overrides``: ``dotted.key=value`` strings (``tlm error-vs-cost
    --set``) applied to its base (not a key its points vary). The study's notes (the reference
    computed, or the ground truth; no ground truth, and why: its ``truth_*`` columns are then empty)
    are the rows' ``attrs["notes"]``, and ``note`` gets each as it is known too (None: nothing is
    printed); its warnings (the reference not converged, or not cached; an override that sets nothing,
    ``render={}``; a camera that faces nothing; a black reference or ground truth; the points whose photon paths
    ``photons.max_bounces`` cut with over 5% of the light in flight, their rows' ``cut_share``), which
    ``tlm error-vs-cost`` prints on stderr and its ``reference.json`` keeps (``warnings``, which the report
    lists), are their ``attrs["warnings"]``; ``warn`` gets each as it is known too (None: nothing is printed)."""
    from tlm.experiments.error_cost import Truth, run_error_vs_cost

    notes: list[str] = []
    warnings: list[str] = []
    kept = flags_are_kept()
    names = {"path", "out", "truth_spp", "progress", "note", "overrides", "warn"}

    def said(lines: list[str], hear: Callable[[str], None] | None) -> Callable[[str], None]:
        def told(line: str) -> None:  # (a caller in Python: truth_spp=0, not --truth-spp 0)
            line = line if kept else arguments_text(line, names)
            lines.append(line)
            if hear is not None:
                hear(line)

        return told

    progress = callback(progress, "progress", "a function of (point, points, row)")
    note = callback(note, "note")
    # (the command line's: printed on stderr by the study, once each, as tlm.storage.warn prints them)
    hear = callback(warn, "warn") or (_stderr_warning if kept else None)
    path, checked = _study(path, "error-vs-cost", out)
    with checked:
        rows = run_error_vs_cost(path, out_folder(out), progress=progress, truth=Truth(spp=truth_spp),
                                 note=said(notes, note), overrides=_overrides(overrides),
                                 warned=said(warnings, hear), via="--set" if kept else "the overrides")
    return StudyRows(rows, notes, warnings)


@argument_names
@imports_whole
def extreme(path: str | Path, out: str | Path, *, progress: Callable[[dict], None] | None = None,
            overrides: Iterable[str] | None = None, warn: Callable[[str], None] | None = None) -> StudyRows:
    """The stiff and extreme cases of the study file ``path`` (or the built-in study of that
    name, ``"extreme"``), expected against measured (``tlm extreme``): one row a case, a list of
    dicts (:class:`StudyRows`). ``overrides``: ``dotted.key=value`` strings (``tlm extreme --set``)
    applied to its base (not a key a case's config gives). Its warnings (an override that sets
    nothing, one some cases never read), which ``tlm extreme`` prints on stderr, are the rows'
    ``attrs["warnings"]``; ``warn`` gets each as it is known too (None: nothing is printed)."""
    from tlm.experiments.extreme import run_extreme

    progress = callback(progress, "progress", "a function of one row")
    warned = _Warned(callback(warn, "warn"))
    path, checked = _study(path, "extreme", out)
    with checked:
        rows = run_extreme(path, out_folder(out), progress, overrides=_overrides(overrides), **warned.arguments())
    return StudyRows(rows, warnings=warned.lines)


# ---------------------------------------------------------------- reports


@argument_names
@imports_whole
def write_report(dirs: Iterable[str | Path], out: str | Path | None = None, title: str | None = None, *,
                 lock: bool = False, formats: str | Iterable[str] | None = None, dpi: int | str | None = None,
                 note: Callable[[str], None] | None = None, progress: bool = False) -> Path:
    """The self-contained HTML report of run, sweep or study folders (``tlm report``);
    returns the path of ``report.html`` (default folder: ``DIR/report`` of the one folder).
    ``lock``: hold the folder's lock meanwhile, so no other run replaces it. ``formats``:
    the files each figure is written as, ``"pdf,svg"`` or names of png, pdf and svg (the
    PNG always, as the page embeds it); ``dpi``: the PNG's, 50 to 1200 (default 110)
    (``tlm report --formats --dpi``; a bad value is an InputError before anything is written).
    ``note`` receives one-line notes on a folder of folders it searched, as soon as it has searched
    them (a folder in it with no run, sweep or study, a link not followed, the folders of installed
    software passed over, a long search: :func:`tlm.report.folders.find`); the page says them too,
    and nothing is printed (``tlm report`` prints them on stderr, ``tlm: note: ...``). With ``lock``,
    where another process holds the folder (a run replacing it, a report reading it), ``note`` is
    told so, naming that process where it can (:func:`tlm.claims.lock_holder`), before this waits.
    ``dirs``: a list of folders, or one folder's path (a string or a Path: that folder, not the
    characters of its name). ``progress``: a bar on stderr while it is written, when stderr is a
    terminal (True or False; ``tlm report`` draws it unless ``--no-progress``)."""
    from tlm.report import build_report

    lock = _checked(lock, "lock", bool)
    progress = _checked(progress, "progress", bool)
    dirs = folder_list(dirs, "dirs", "the run, sweep or study folders to report")
    if out is None and len(dirs) > 1:
        raise InputError("several folders: name the report folder", key="--out")
    out = out_folder(out) if out is not None else None
    formats = _formats(formats)
    hear = callback(note, "note") or (lambda line: None)  # (None: the page alone says them; nothing printed)
    with _report_held(dirs, out, formats, dpi):
        if not lock:
            return build_report(dirs, out, title, formats=formats, dpi=dpi, note=hear, progress=progress)
        from tlm.claims import lock_holder
        from tlm.storage import folder_lock

        def waiting() -> None:  # (another process holds it: a run replacing the folder, a report reading it)
            holder = lock_holder(dirs[0]) or "another process"
            hear(f"{quoted(dirs[0])} is held by {holder}, a run replacing it or a report reading it: the report "
                 "waits for it to end")

        with folder_lock(dirs[0], waiting=waiting, probe=False):  # (a reader: nothing written beside the folder)
            return build_report(dirs, out, title, formats=formats, dpi=dpi, note=hear, progress=progress)


@contextmanager
def _report_held(dirs: list[Path], out: Path | None, formats: str | list[str] | None,
                 dpi: int | str | None) -> Iterator[None]:
    """:func:`write_report`'s block: its folder (``out``; None: ``DIR/report`` of the one folder) held by this
    process while the report is written, as ``tlm report`` holds it (:func:`tlm.claims.claimed`, a report's claim):
    another process's report, run, study or sweep into it meanwhile is refused at once, naming this one, and this
    report is refused a folder another process writes now, before any work (was: none held from Python, two
    reports into one folder last-wins: h434). What :func:`tlm.report.build_report` refuses before it reads
    anything is refused first, as it says it, nothing made for the claim: bad ``formats`` or ``dpi``, a bad ``out``
    or one that is an input (:func:`tlm.report.check_out`); a folder of ``dirs`` that is not there takes no claim
    (its own error, from the report). From the command line, which holds it already (``tlm report`` and a
    command's report at its end: :func:`tlm.cli_report.report_claimed`), the claim is that one, shared
    (:func:`~tlm.claims.claimed` counts its holders in a process), never a second."""
    if not dirs or not all(Path(d).is_dir() for d in dirs):
        yield
        return
    from tlm.claims import claimed
    from tlm.report import check_out
    from tlm.report.common import output

    output(formats, dpi)  # (checked as the report checks them, first)
    check_out(out, dirs)
    with claimed(out if out is not None else Path(dirs[0]) / "report", "report"):
        yield


@imports_whole
def report_output(formats: str | Iterable[str] | None = None,
                  dpi: int | str | None = None) -> tuple[tuple[str, ...], int]:
    """The files each figure of a report is written as and the PNG's dots per inch, as
    :func:`write_report` takes ``formats`` and ``dpi`` (``("png", "svg"), 110`` for ``"svg"``);
    a bad value is the InputError it raises (naming ``--formats`` or ``--dpi``), here before
    any work: ``tlm run --formats`` checks it so."""
    from tlm.report.common import output

    chosen = output(formats, dpi)
    return chosen.formats, chosen.dpi


@argument_names
@imports_whole
def plots(configs: str | Path, runs: str | Path, out: str | Path, only: str | list[str] | None = None, *,
          run_command: Callable[[list[str]], int], say: Callable[[str], None] | None = None,
          formats: str | Iterable[str] | None = None, dpi: int | str | None = None) -> Path:
    """Every committed experiment of ``configs`` (or the steps ``only``) and their report into
    ``out`` (``tlm plots``); returns the path of ``report.html``. ``run_command`` runs one step's
    ``tlm`` argv (``["sweep", "configs/bsp_levels.yaml", "--out", ...]``) and returns its exit
    status: 1 when its results report failures, an exception on bad input or a bug (``tlm plots``
    hands down its own; from Python, ``lambda argv: subprocess.run(["tlm", *argv]).returncode``
    runs each step as its command). ``say`` gets a line before each step and after one that
    returns 1 (None: nothing is printed). Steps that return 1 and the rest run; the report is
    written, then :class:`tlm.api.StepsFailed` (``.page``, ``.steps``) names them. ``formats`` and
    ``dpi``: the report's figure files, as :func:`write_report` takes them (checked before the
    first step). ``only``: a list of steps' names, or one step's name. ``out`` is held by this process from
    after those checks to its report written (a report's claim, as :func:`write_report` holds its folder):
    another process's ``tlm plots`` or report into it is refused at once, naming this one."""
    from tlm.report.common import figure_output
    from tlm.report.regenerate import regenerate

    if run_command is None or callback(run_command, "run_command") is None:
        raise InputError("None is not a function: give one that runs a step's tlm argv and returns its exit status, "
                         "lambda argv: subprocess.run([\"tlm\", *argv]).returncode", key="run_command")
    hear = callback(say, "say") or (lambda line: None)  # (None: nothing printed, as every API function)
    steps = [only] if isinstance(only, str) else only  # (one step: that step, not the characters of its name)
    if steps is not None:
        steps = list(steps) if isinstance(steps, Iterable) and not isinstance(steps, bytes) else [steps]
        if not all(isinstance(n, str) for n in steps):
            raise InputError(f"{_shown(only)} is not steps' names: give a list of them, or one (None: every step)",
                             key="only")
    folders = []
    for name, value in (("configs", configs), ("runs", runs)):
        if not isinstance(value, (str, os.PathLike)):
            raise InputError(f"{_shown(value)} is not a folder's path", key=name)
        folders.append(home(value, name))
    with figure_output(_formats(formats), dpi):  # (the report's figures; a bad value stops here, before any step)
        return regenerate(*folders, out_folder(out), steps, run_command=run_command, say=hear)
