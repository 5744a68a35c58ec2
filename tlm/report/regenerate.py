"""``tlm plots``: run every committed experiment and write the report of all of them.

One command regenerates ``plots/`` (the figures the README shows)::

    tlm plots                      # runs/ for the outputs, plots/ for the report

Each step is a tlm command over a file in ``configs/``; a sweep skips the points it
finished before, and the functional cache spares renders that were done before, so a
second call redoes only the simulations and the report. ``--only`` runs a subset of
the steps (the report still reads every step's folder that exists). A scaling sweep's
folder that the eq52 folder was fitted from (its ``eq52.json`` ``sweeps``) is shown
through that fit; another (no eq52 folder: ``--only scaling_cornell``) is reported as
the sweep it is. The eq52 step fits the scaling folders this command runs or that exist,
saying which are missing (a folder without a sweep in it, no ``sweep.jsonl``: an interrupted
or emptied one, is missing, and left out of the report, said); with none of them it is
refused before any step runs. A ``configs`` folder of one's own need not hold every step's file: without
``only``, a step whose file it lacks is skipped with a line (:func:`_present`); one holding none is refused.

A step that exits with status 1 has run and reports failures among its results (a case
of ``tlm extreme`` that differs from its expectation, a sweep point that failed, a model
that cannot finish): it is said, the other steps and the report still run, and
:class:`StepsFailed` (``tlm plots``: exit status 1) names such steps at the end. Any
other status, or bad input (an :class:`~tlm.errors.InputError` out of the step), stops
the command at that step. An ``out`` that the report could not be written into (a file, a read-only folder's), or
that is or holds ``runs`` or ``configs`` or is (or lies in) a step's folder under ``runs`` (the report replaces its
folder whole; the step writes its own), is refused before the first step, as a bad ``--only`` or ``--configs`` is;
so is one another process writes now. From then to its report written, ``out`` is this process's (a report's claim,
:func:`tlm.claims.claimed`, as ``tlm report`` holds its own): another ``tlm plots``, ``tlm report``, run or study
into it meanwhile is refused at once, naming this one; the claim goes as the command ends, stopped too.
A command stopped at a step writes no report, and the report an
earlier ``tlm plots`` left in ``out`` stays as it was (a command that fails leaves its
destination alone; ``plots/`` is the committed report the README shows): the error then
says that the report there is the earlier one, with its date (:func:`earlier_report`).
"""

from __future__ import annotations

import datetime
import numbers
import sys
from collections.abc import Callable
from pathlib import Path

from tlm.claims import FolderHeld, claimed
from tlm.errors import InputError, StepsFailed, escaped_line, quoted

SCALING = ("scaling_ring", "scaling_room", "scaling_cornell")  # the sweeps the eq52 step fits
SWEEPS = (*SCALING, "design_space", "bsp_levels", "sweep_fifo")

# (step name, argv with {configs} and {runs}); the report reads the folder named like the step
STEPS: tuple[tuple[str, list[str]], ...] = (
    ("thesis", ["thesis", "{configs}/thesis.yaml", "--out", "{runs}/thesis"]),
    *((s, ["sweep", f"{{configs}}/{s}.yaml", "--out", f"{{runs}}/{s}", "--no-progress"]) for s in SWEEPS),
    ("eq52", ["scaling", *(f"{{runs}}/{s}" for s in SCALING), "--out", "{runs}/eq52"]),
    ("tlm_granularity", ["granularity", "{configs}/tlm_granularity.yaml", "--out", "{runs}/tlm_granularity"]),
    ("error_vs_cost", ["error-vs-cost", "{configs}/error_vs_cost.yaml", "--out", "{runs}/error_vs_cost"]),
    ("cornell_pmap", ["run", "{configs}/cornell_pmap.yaml", "--out", "{runs}/cornell_pmap"]),
    ("extreme", ["extreme", "{configs}/extreme.yaml", "--out", "{runs}/extreme"]),
)
# the scaling sweeps are shown through eq52 (the same fits): they are not read as sweeps of
# their own (no second fit, no sweep tables, no extra points in the other sections) but
# passed to the scaling section only, for the idle fraction per PM that eq52 does not keep
REPORTED = tuple(name for name, _ in STEPS if name not in SCALING)


def earlier_report(out: Path, ran: list[str] | tuple[str, ...] = ()) -> str | None:
    """What a ``tlm plots`` that stopped before its report says of the report folder ``out``:
    None where it holds no report, else that its report is an earlier run's (with its date),
    not of this one; ``ran``: the steps that finished before it stopped."""
    page = Path(out) / "report.html"
    try:
        when = datetime.datetime.fromtimestamp(page.stat().st_mtime).isoformat(sep=" ", timespec="seconds")
    except OSError:
        return None
    since = f"; the steps that ran before it ({', '.join(ran)}) have rewritten their folders since" if ran else ""
    return f"no report written: {page} is the report of an earlier 'tlm plots' (written {when}), not of this one{since}"


def regenerate(configs: Path, runs: Path, out: Path, only: list[str] | None = None, *,
               run_command: Callable[[list[str]], int], say=print) -> Path:
    """Run the steps (all, or ``only``), then the report of their folders into ``out``.

    ``run_command`` runs one step's argv and returns its exit status, 1 where the step's
    results report failures; it raises on an error (the CLI hands down its command runner,
    so the report layer never imports it). Steps that return 1 are recorded and the rest
    run; the report is written, then :class:`StepsFailed` names them. Another status, or an
    InputError of the step, stops at that step; its error says so of a report an earlier
    run left in ``out`` (:func:`earlier_report`).
    """
    ran: list[str] = []
    try:
        return _regenerate(configs, runs, out, only, run_command, say, ran)
    except InputError as e:
        earlier = None if isinstance(e, FolderHeld) else earlier_report(out, ran)  # (another's report there now)
        if earlier is None:
            raise
        raise InputError(f"{e}; {earlier}") from None
    except StepsFailed:
        raise
    except BaseException:  # stopped before its report (a bug, a full disk, Ctrl-C): an earlier one is not its own
        earlier = earlier_report(out, ran)
        if earlier is not None:
            sys.stderr.write(f"tlm: plots: {escaped_line(earlier)}\n")
            sys.stderr.flush()
        raise


def _regenerate(configs: Path, runs: Path, out: Path, only: list[str] | None, run_command, say,
                ran: list[str]) -> Path:
    from tlm.report import check_out

    names = [n for n, _ in STEPS]
    for n in only or []:
        if n not in names:
            raise InputError(f"unknown step {n!r} (steps: {', '.join(names)})", key="--only")
    if not configs.is_dir():  # (every step reads its experiment file there: said once, before the first step)
        what = "is not a folder" if configs.exists() else "no such folder"
        raise InputError(f"{what}: name the folder of the experiment files (configs/)", source=str(configs),
                         key="--configs")
    # (the report's folder, refused as its write refuses it, or holding the steps' folders: before the first step)
    check_out(out, [], [runs, configs])
    for n in names:  # (a step's own folder: the step would write it in this process's claim, the report replace it;
        # one inside it: the claim's file, made before the step, lay in the step's folder, which it refused, h442)
        if out.resolve() == (runs / n).resolve():
            raise InputError(f"{quoted(out)} is step {n}'s folder under --runs: the report would replace the step's "
                             "output (it replaces its folder whole); name another folder", key="--out")
        if (runs / n).resolve() in out.resolve().parents:
            raise InputError(f"{quoted(out)} lies in step {n}'s folder under --runs, which the step writes (its "
                             "output there, not the report's); name a folder outside it", key="--out")
    only = _present(configs, runs, only, say)  # (a step whose file --configs lacks: skipped, said; h474)
    planned = [n for n in names if not only or n in only]
    # the scaling sweeps the eq52 step fits: those this command runs, and those an earlier one left under runs
    # (a missing one is said and left out of the fit; none at all is refused before any step runs)
    # (a folder without a sweep in it, an interrupted or emptied one, is no sweep to fit: absent, said so)
    absent = [s for s in SCALING if s not in planned and not _is_sweep(runs / s)]
    if "eq52" in planned and len(absent) == len(SCALING):
        raise InputError(f"step eq52 fits the scaling sweeps, and none is under {runs} ({_why_absent(runs, absent)}) "
                         f"nor among the steps to run: add {' or '.join(absent)} to --only", key="--only")
    # (--out held from here to its report written, as tlm report holds it, a report's claim: another tlm plots or
    # report into it meanwhile is refused at once naming this one, not last-wins; the steps, in this process or
    # not, claim their folders under --runs, which check_out keeps out of --out: h439)
    with claimed(out, "report"):
        return _steps(configs, runs, out, only, absent, run_command, say, ran)


def _steps(configs: Path, runs: Path, out: Path, only: list[str] | None, absent: list[str], run_command, say,
           ran: list[str]) -> Path:
    """The steps (all, or ``only``) and the report of their folders into ``out``, which this process holds
    (:func:`_regenerate`); ``absent``: the scaling sweeps neither run nor under ``runs``, left out of eq52's fit."""
    from tlm.report import build_report

    names = [n for n, _ in STEPS]
    failed = []
    for name, argv in STEPS:
        if only and name not in only:
            continue
        if name == "eq52" and absent:
            argv = [a for a in argv if a not in {f"{{runs}}/{s}" for s in absent}]
            say(f"== eq52: fits {', '.join(s for s in SCALING if s not in absent)} alone: "
                f"{_why_absent(runs, absent)} under {runs} (run {'its step' if len(absent) == 1 else 'their steps'} "
                f"with --only to fit {'it' if len(absent) == 1 else 'them'} too)")
        argv = [a.format(configs=configs, runs=runs) for a in argv] + ["--no-report"]
        say(f"== {name}: tlm {' '.join(argv)}")
        try:
            status = run_command(argv)
        except InputError as e:
            raise InputError(f"step {name} stopped on bad input: {e}", key="tlm plots") from None
        if isinstance(status, bool) or not isinstance(status, numbers.Integral):  # (a caller's run_command)
            raise InputError(f"step {name}: run_command returned {status!r}, not an exit status (a whole number: "
                             "0 for success, 1 where the step's results report failures)", key="run_command")
        if status == 1:  # a result: failures among the step's results, said above
            say(f"== {name}: exit status 1 (its results report failures, see above); the other steps and the "
                "report still run")
            failed.append(name)
        elif status != 0:
            raise InputError(f"step {name} failed with exit status {status} (see above)", key="tlm plots")
        ran.append(name)
    # a scaling sweep that the eq52 folder was fitted from is shown through it (its idle fractions alone read from
    # the sweep); one it was not (no eq52 folder, or one fitted from the others) is reported as the sweep it is
    fitted_by = _fitted_by(runs / "eq52")
    dirs, fitted = [], []
    for n in names:
        if n in SCALING and (runs / n).is_dir() and not _is_sweep(runs / n):
            say(f"== report: {runs / n} left out: no sweep in it (no sweep.jsonl; run step {n} to fill it)")
        elif (runs / n).is_dir() and (n in REPORTED or n in SCALING):
            (fitted if n in SCALING and (runs / n).resolve() in fitted_by else dirs).append(runs / n)
    if not dirs:
        raise InputError(f"no step's folder exists under {runs}", key="--runs")
    page = build_report(dirs, out, "tlm: the committed experiments", scaling_sweeps=fitted)
    if failed:
        raise StepsFailed(page, failed)
    return page


def step_files(configs: Path) -> dict[str, Path]:
    """Each step's experiment file in ``configs`` (``thesis`` -> ``configs/thesis.yaml``); ``eq52`` has none (it
    fits the scaling sweeps' folders)."""
    return {name: Path(a.format(configs=configs, runs="")) for name, argv in STEPS for a in argv if "{configs}" in a}


def _present(configs: Path, runs: Path, only: list[str] | None, say) -> list[str] | None:
    """The steps to run: ``only`` where given (a step it names runs, and one whose file is missing stops on the
    step's bad input, as ever); else every step whose experiment file ``configs`` holds, each other one said in a
    line and skipped (a researcher's --configs folder of their own studies need not hold every committed one), and
    eq52 too where no scaling sweep is left to fit (none runs, none under ``runs``). A folder holding none of the
    files is an InputError before any step runs. None (every step) where every file is there."""
    files = step_files(configs)
    missing = [n for n, f in files.items() if not f.exists()]
    if only or not missing:
        return only
    if len(missing) == len(files):
        raise InputError(f"holds none of the steps' experiment files ({', '.join(f.name for f in files.values())}): "
                         "name the folder that holds one or more of them", source=str(configs), key="--configs")
    planned = [n for n, _ in STEPS if n not in missing]
    for n in missing:
        say(f"== {n}: skipped: {files[n]} is not there (--configs {configs} lacks it; the report shows its folder "
            "under --runs where one exists)")
    if all(s not in planned and not _is_sweep(runs / s) for s in SCALING):
        planned.remove("eq52")
        say(f"== eq52: skipped: no scaling sweep to fit ({', '.join(SCALING)} skipped, and none under {runs})")
    return planned


def _is_sweep(folder: Path) -> bool:
    """Whether the scaling step's folder ``folder`` holds a sweep (its ``sweep.jsonl``) to fit and report."""
    return (folder / "sweep.jsonl").is_file()


def _why_absent(runs: Path, absent: list[str]) -> str:
    """The scaling folders ``absent`` under ``runs`` in words: no such folder, or one without a sweep in it."""
    gone = [s for s in absent if not (runs / s).is_dir()]
    empty = [s for s in absent if s not in gone]
    return "; ".join([*([f"no folder {', '.join(gone)}"] if gone else []),
                      *([f"no sweep in {', '.join(empty)} (no sweep.jsonl)"] if empty else [])])


def _fitted_by(eq52: Path) -> set[Path]:
    """The sweep folders (resolved) that the scaling folder ``eq52`` records in its ``eq52.json`` as fitted
    from; none where it has no readable one (the report says what is wrong with it)."""
    import json

    try:
        sweeps = json.loads((eq52 / "eq52.json").read_text(encoding="utf-8")).get("sweeps")
    except (OSError, ValueError, AttributeError):
        return set()
    return {(eq52 / rel).resolve() for rel in sweeps if isinstance(rel, str)} if isinstance(sweeps, list) else set()
