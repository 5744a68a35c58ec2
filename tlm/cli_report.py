"""The report a command writes at its end (``OUT/report``, :func:`report_after`), the claim of a
report's folder that it and ``tlm report`` take (:func:`report_claimed`), and what a signal while
it is written says (:func:`_report_interrupted`), one while a sweep's points run
(:func:`sweep_cut_short`), and one while a reference is computed (:func:`reference_cut_short`); with the
line a command says on stderr (:func:`say_err`). Printing only, as
:mod:`tlm.cli`: the report itself is :mod:`tlm.api`'s."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager, suppress
from pathlib import Path

from tlm import api, claims, storage
from tlm.api import InputError
from tlm.cli_signals import Interrupted
from tlm.errors import EnvironmentFailure, chain, interrupted_by, path_shown, quoted, shell_word


def say_err(line: str) -> None:
    """A progress line on stderr, above any progress bar; none where stderr cannot be written (its reader gone,
    ``2>/dev/full``, ``2</dev/null``: the command goes on, as :func:`tlm.cli_streams.guard_streams` keeps it)."""
    from tqdm import tqdm

    with suppress(OSError):
        tqdm.write(f"tlm: {line}", file=sys.stderr)
        sys.stderr.flush()


def report_after(args: argparse.Namespace, out: Path, kept: str, files: str) -> None:
    """The report of a folder a command just wrote (``OUT/report``), unless ``--no-report``.
    ``kept``: what the command wrote there (``the run``, ``the sweep``), whole before the report
    begins; ``files``: its files, as the line names them (``results.json and its files``). The
    report's folder is claimed as ``tlm report`` claims it (:func:`report_claimed`: a ``tlm
    report`` into it meanwhile is refused at once), this command's report waiting, said, while
    another process's is written there (another sweep of the same points into the folder, a
    ``tlm report`` begun before): its own is of the folder as the command left it. It is written
    beside ``OUT/report`` and takes its place at the end (:func:`tlm.storage.atomic_folder`), so
    none is half written. A signal meanwhile ends the command saying that ``kept`` is kept,
    whole, and how to write the report (:func:`_report_interrupted`)."""
    if getattr(args, "no_report", False):
        return
    folder = out / "report"
    begun, earlier = False, None  # (the page in OUT/report as this report begins: a sweep's of its rows, kept)
    try:
        with report_claimed(folder, wait=lambda holder: say_err(
                f"note: another report is writing into {quoted(folder)} ({holder}): the report of {kept} in {out} "
                "waits for it to end")):
            begun, earlier = True, _page_id(folder)
            # no other run replaces the folder while its report is written
            print(f"report: {api.write_report([out], lock=True, formats=args.formats, dpi=args.dpi)}")
    except BaseException as e:  # (a Ctrl-C, or an error a C extension made of it: errors.interrupted_by)
        if isinstance(e, Interrupted) or not (isinstance(e, KeyboardInterrupt) or interrupted_by(e) is not None):
            if isinstance(e, EnvironmentFailure):  # (a full disk as the report is written: the output is whole)
                failed = EnvironmentFailure(f"{e}; {_not_written(args, out, f'{kept} in {out}', files)}")
                failed.source = e.source
                raise failed from e
            raise
        raise Interrupted(_report_interrupted(args, out, f"{kept} in {out}", files, earlier if begun else False)) from e


@contextmanager
def kept_whole(args: argparse.Namespace, out: Path, kept: str, files: str) -> Iterator[None]:
    """Around what a command does once its output in ``out`` is whole (swapped in: its lines on
    stdout, then :func:`report_after`): a signal meanwhile ends it saying that ``kept`` is kept, whole
    (``files``), and, unless ``--no-report``, how to write its report (not a bare ``tlm: interrupted``,
    which would leave the user to guess whether the run is there). A signal during the report itself:
    :func:`report_after`'s own line."""
    try:
        yield
    except BaseException as e:  # (a Ctrl-C, or an error a C extension made of it: errors.interrupted_by)
        if isinstance(e, Interrupted) or not (isinstance(e, KeyboardInterrupt) or interrupted_by(e) is not None):
            raise
        if getattr(args, "no_report", False):
            raise Interrupted(f"after {kept} was written: {kept} in {out} is kept, whole ({files})") from e
        raise Interrupted(f"before its report began: {_not_written(args, out, f'{kept} in {out}', files)}") from e


@contextmanager
def sweep_cut_short(out: Path) -> Iterator[None]:
    """Around a sweep's points (:func:`tlm.api.run_sweep`): a signal meanwhile ends it saying how many of its
    points are finished and kept in ``out`` (their rows in ``sweep.jsonl``, those done by an earlier run counted;
    how many failed, which a rerun runs again) and that the same command goes on from there, or that none had
    finished (not a bare ``tlm: interrupted``, which left the user to guess what the folder kept). Said where
    the sweep noted them (:func:`tlm.experiments.sweep_rows.note_kept`: not where its rows could not be written).
    A signal before the sweep claimed ``out`` (reading the sweep file and its points, the points done before: a
    moment for 10^4 of them; starting its workers), its ``sweep.yaml`` as it was (the sweep writes it first), and
    no earlier run's row there to count, says that no point ran and nothing was written; one that stopped the
    reference ``--reference`` computes then (before the folder is claimed too), with no such row, says what
    :func:`reference_cut_short` says, the rounds the cache keeps (not that nothing was written: h471)."""
    before = _marker_state(out)
    try:
        yield
    except BaseException as e:  # (a Ctrl-C, or an error a C extension made of it: errors.interrupted_by)
        kept = getattr(e, "kept_points", None)  # (sweep_rows.KEPT: the CLI reaches the layers through tlm.api only)
        if isinstance(e, Interrupted) or not (isinstance(e, KeyboardInterrupt) or interrupted_by(e) is not None):
            raise
        if (kept is None or not kept[0]) and (line := _reference_kept(e)) is not None:  # (a compute stopped)
            raise Interrupted(line) from e
        if (kept is None or not kept[0]) and _marker_state(out) == before:  # (not claimed, no earlier row: untouched)
            raise Interrupted("before any point ran: nothing was written") from e
        if kept is None:
            raise
        rows, failed, total = kept
        if not rows:
            raise Interrupted("before any point finished") from e
        if rows >= total and not failed:  # (every row written: nothing to go on with)
            raise Interrupted(f"with all {total} points finished and kept in {path_shown(out)}") from e
        of = f" ({failed} failed, to run again)" if failed else ""
        raise Interrupted(f"with {rows} of {total} points finished{of} and kept in {path_shown(out)}; "
                          "run the same command to go on") from e


@contextmanager
def reference_cut_short() -> Iterator[None]:
    """Around a command that may compute a photon-map reference (``tlm run``, ``tlm reference``, ``tlm
    error-vs-cost``): a signal while one is computed ends it saying how many of its rounds the cache keeps, read
    from the file they are saved in (``references/<key>.partial.npz``, :mod:`tlm.experiments.reference_resume`),
    and that the same command resumes from there, or that none were saved yet (not a bare ``tlm: interrupted``,
    which left the user to guess that the minutes spent are kept). A signal at another time: its own line."""
    try:
        yield
    except BaseException as e:  # (a Ctrl-C, or an error a C extension made of it: errors.interrupted_by)
        if isinstance(e, Interrupted) or not (isinstance(e, KeyboardInterrupt) or interrupted_by(e) is not None):
            raise
        line = _reference_kept(e)
        if line is None:
            raise
        raise Interrupted(line) from e


def _stopped_compute(e: BaseException | None):
    """The saved rounds (``tlm.experiments.reference_resume.Partial``) of the reference compute the interrupt ``e``
    stopped, or an error of its chain of causes and contexts did: its attribute ``reference_partial``
    (``reference_resume.MARK``, set as it left the rounds; the CLI reaches that layer through tlm.api only). None
    where it stopped none."""
    for c in chain(e):
        found = getattr(c, "reference_partial", None)
        if found is not None:
            return found
    return None


def _reference_kept(e: BaseException) -> str | None:
    """What :func:`reference_cut_short` says of the reference compute ``e`` stopped; None where it stopped none."""
    try:
        saved = _stopped_compute(e)
        rounds = 0 if saved is None else saved.kept()
    except Exception:  # (what stopped the command goes on whatever: its line the bare one)
        return None
    if saved is None:
        return None
    if rounds:
        return (f"while computing the reference: its {rounds} rounds are kept in {path_shown(saved.path)}; "
                f"run the same command to resume from round {rounds}")
    if saved.off:  # (its one line said the cache cannot be written: tlm.caches)
        return ("while computing the reference: none of its rounds are kept (the cache cannot be written); "
                "the same command computes it from round 1")
    # (another compute's rounds of the key in the file, which this one does not resume; 0 where it cannot be read:
    # partial_info, which kept() called on the same path above, raises for none)
    held = saved.others()
    where = path_shown(saved.path)
    if saved.saved:  # (its rounds were in the file, and are no longer: another compute's in their place, or none)
        gone = (f"were replaced by another compute's {held} rounds, which the same command does not resume" if held
                else "are gone (removed since)")
        return (f"while computing the reference: its {saved.saved} rounds saved in {where} {gone}; the same "
                "command computes it from round 1")
    if held and saved.held_off:  # (a save it would have made waits for more rounds than those: Partial.save)
        return (f"while computing the reference, before its first rounds were saved (the {held} rounds kept in "
                f"{where} are another compute's, which it does not resume nor save over with fewer: remove the file "
                "to save its own): the same command computes it from round 1")
    return ("while computing the reference, before its first rounds were saved: the same command computes it "
            "from round 1")


def _marker_state(out: Path) -> tuple | bool:
    """What :func:`sweep_cut_short` compares to tell whether a sweep claimed ``out``: its ``sweep.yaml``'s file
    (written anew, atomically, as the sweep claims the folder, before anything else there), or whether the
    folder is there where it has none."""
    try:
        st = (out / "sweep.yaml").stat()
    except (OSError, ValueError):
        return out.is_dir()
    return (st.st_dev, st.st_ino, st.st_mtime_ns, st.st_size)


@contextmanager
def report_claimed(folder: Path, wait: Callable[[str], None] | None = None, of: str | None = None
                   ) -> Iterator[None]:
    """A context holding the report folder ``folder`` for this process while a report is written
    into it (:func:`tlm.claims.claimed`), as ``tlm report`` holds its ``--out`` and a command the
    ``OUT/report`` of its end (:func:`report_after`). Where another process holds it: without
    ``wait`` (``tlm report``), refused at once, exit 2, naming that process (``another report is
    writing into 'OUT/report' (process ...)``); with it, ``wait`` is told that process, once, and
    this one waits until the folder is free (the command's own report, of what it just wrote). A
    folder that is not a report's is refused first, as such (:func:`tlm.storage.check_destination`).
    ``of``: the folder the user gave where ``folder`` is its default report folder (``tlm report DIR``
    without ``--out``): the refusal names it, not ``--out``, which the user did not give; a parent that cannot be
    written is said with ``; give --out``."""
    try:  # (a bad --out said as such, before the claim's file beside it)
        storage.check_destination(folder, "report.html")
    except claims.FolderHeld:  # (another process's report there: refused, or waited for, as its claim is below)
        pass
    except EnvironmentFailure as e:  # (DIR/report, unwritable: the user may name another, tlm report's own flag)
        if of is None or wait is not None:
            raise
        raise EnvironmentFailure(f"{e}; give --out") from None
    told = False
    with ExitStack() as held:
        while True:
            try:
                held.enter_context(claims.claimed(folder, "report"))
                break
            except claims.FolderHeld as e:
                what, given, holder = e.held
                if wait is None and of is not None:  # (the same words, of its report folder, --out named)
                    raise InputError(claims.held_line(what, given, holder, report_folder=True), source=of) from None
                if wait is None:
                    raise
                if not told:
                    wait(holder)
                    told = True
                time.sleep(0.1)
        yield


@contextmanager
def study_claimed(out: Path, marker: str) -> Iterator[None]:
    """A study's folder ``out`` (``tlm granularity``, ``error-vs-cost``, ``thesis``, ``extreme``, ``scaling``:
    ``marker`` its file) held by this process from before its work to the end of its report, as ``tlm run``
    holds its own (:func:`tlm.claims.claimed`): a run, a study, a sweep or a report of another process into it
    meanwhile is refused at once, naming this one, not found out at its end. A bad ``out``, or one another
    process writes now, is refused first, as such (:func:`tlm.storage.check_destination`)."""
    storage.check_destination(out, marker)
    with claims.claimed(out, "study"):
        yield


def _page_id(folder: Path) -> tuple[int, int] | None:
    """Which ``report.html`` is in the report folder ``folder`` now (its device and inode), None for none."""
    try:
        st = (folder / "report.html").stat()
    except OSError:
        return None
    return st.st_dev, st.st_ino


def _report_command(args: argparse.Namespace, out: Path) -> str:
    """``tlm report OUT`` that writes the report of ``out`` as the command would have (its
    ``--formats`` and ``--dpi``), ready to paste (quoted for a shell)."""
    command = ["tlm report", shell_word(str(out))]
    command += [f"--{flag} {shell_word(str(value))}" for flag in ("formats", "dpi")
                if (value := getattr(args, flag, None)) is not None]
    return " ".join(command)


def _report_interrupted(args: argparse.Namespace, out: Path, kept: str, files: str,
                        earlier: tuple[int, int] | bool | None) -> str:
    """What ``tlm: terminated (SIGTERM)`` (``tlm: interrupted``) says after a signal came while
    the report of ``out`` was written: ``kept`` (``the run in OUT``) is whole (``files``), and no
    report was written (the command that writes it: :func:`_report_command`), an earlier one
    left as it was (``earlier``: its :func:`_page_id` as this report began; False: it had not
    begun, waiting for another's); or the report was, whole, where the signal came as it took its
    place."""
    page = out / "report" / "report.html"  # (what api.write_report returns: the page, written last)
    now = _page_id(page.parent)
    if earlier is not False and now is not None and now != earlier:  # (this report's folder took its place)
        return f"as its report was written: {kept} and its report ({page}) are complete"
    return f"while writing the report: {_not_written(args, out, kept, files)}"


def _not_written(args: argparse.Namespace, out: Path, kept: str, files: str) -> str:
    """``the run in OUT is kept, whole (FILES); no report was written (...): write it with: tlm report OUT``:
    what a command whose report was not written (a signal, a full disk) says of what it wrote."""
    page = out / "report" / "report.html"
    left = ("none is left half-written" if _page_id(page.parent) is None else
            f"none is left half-written; the earlier report in {page.parent} is left as it was")
    return (f"{kept} is kept, whole ({files}); no report was written ({left}): write it with: "
            f"{_report_command(args, out)}")
