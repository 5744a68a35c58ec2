"""Command line: ``tlm run | sweep | scene | params | ...``. Argument parsing and printing only:
every command calls :mod:`tlm.api` and prints what it returns; how a command ends (its
signals, its one-line errors, its exit status) is :mod:`tlm.cli_signals`, the report it writes
at its end :mod:`tlm.cli_report`, what ``tlm run`` prints :mod:`tlm.cli_run`, each command's
arguments :mod:`tlm.cli_parser`."""

from __future__ import annotations

import tlm.cli_signals  # noqa: F401  (the first of tlm's modules: a signal from here on is the command's, early_signals)

# isort: split
import argparse
import json
import math
import sys
import time
from pathlib import Path

from tlm import api, claims, cli_parser, cli_report, storage
from tlm.api import Deadlock, InputError
from tlm.cli_args import Parser
from tlm.cli_cache import add_cache_parser, cache_command
from tlm.cli_failed import deadlock_line, exit_status
from tlm.cli_report import kept_whole, report_after, report_claimed, say_err, study_claimed, sweep_cut_short
from tlm.cli_run import blame_flag, default_out, figures3, print_run  # (what tlm run prints)
from tlm.cli_signals import (
    blas_buffer_mapped,
    escaped,
    forget_lost_interrupt,
    interrupted,
    signalled,
    signals,
    until_exit,
    writes_files,
)
from tlm.cli_tables import GranularityProgress, fit_lines, held_out_lines, print_granularity, print_point_warnings
from tlm.cli_tables import print_scaling as _print_scaling
from tlm.cli_tables import print_thesis as _print_thesis
from tlm.cli_tables import yaml_text as _yaml_text
from tlm.errors import check_numba_threads, shell_word


def _say(line: str) -> None:
    """A progress line on stdout, flushed, above any progress bar on stderr."""
    from tqdm import tqdm

    tqdm.write(line, file=sys.stdout)
    sys.stdout.flush()


def _cmd_report(args: argparse.Namespace) -> int:
    """The report of ``args.dirs`` into ``--out`` (default ``DIR/report``), its folder claimed as a run's is
    (another process's report into it meanwhile, this command's or the one a run, sweep or study writes at its
    end, is refused, exit 2, naming that process: :func:`tlm.cli_report.report_claimed`), the first folder locked as the
    report a run ends with locks it (no run replaces it while it is read)."""
    def note(line: str) -> None:  # (each as it is known: the figures may take a while)
        print(f"tlm: note: {escaped(line)}", file=sys.stderr, flush=True)

    out = Path(args.out) if args.out else Path(args.dirs[0]) / "report" if len(args.dirs) == 1 else None

    def write() -> Path:  # (the first folder's lock, unless it is --out itself, which the report's swap locks)
        lock = out is None or Path(out).resolve() != Path(args.dirs[0]).resolve()
        return api.write_report(args.dirs, args.out or None, args.title, lock=lock, formats=args.formats,
                                dpi=args.dpi, note=note, progress=not args.no_progress)

    if out is None or not all(Path(d).is_dir() for d in args.dirs):
        page = write()  # (the folders' own error, before any claim: the claim makes the folders on its way)
    else:
        with report_claimed(out, of=None if args.out else str(args.dirs[0])):  # (what the user gave: DIR or --out)
            page = write()
    print(f"wrote {page}")
    return 0


def _cmd_plots(args: argparse.Namespace) -> int:
    from tlm.errors import StepsFailed

    def step(argv: list[str]) -> int:
        """One step's command: its exit status (1: its results report failures, as a model that
        cannot finish does); bad input and any other error propagate and stop ``tlm plots``.
        Not begun after a signal whose interrupt got lost in the step before (:func:`main`)."""
        if signalled() is not None:
            raise KeyboardInterrupt
        if args.no_progress:  # (every step's command takes it)
            argv = [*argv, "--no-progress"]
        sub = build_parser().parse_args(argv)
        sub.argv = argv  # (its file is the one in --configs: a name is not looked up among the built-in ones)
        try:
            return sub.func(sub)
        except Deadlock as e:  # (as the step's own command says it: bounded, a cap hit said as such)
            print(deadlock_line(e), file=sys.stderr, flush=True)
            return 1

    only = list(dict.fromkeys(args.only)) if args.only else None  # (--only a --only b: both)
    configs = args.configs
    if configs is None:  # ./configs (a checkout's root), else the built-in experiments (an installed copy)
        configs = "configs" if Path("configs").is_dir() else str(api.configs_dir())
    try:
        page = api.plots(configs, args.runs, args.out, only, run_command=step,
                         say=lambda line: print(line, flush=True), formats=args.formats, dpi=args.dpi)
    except StepsFailed as e:
        print(f"wrote {e.page}")
        print(f"tlm: plots: {escaped(str(e))}", file=sys.stderr)
        return 1
    print(f"wrote {page}")
    return 0


def _cmd_extreme(args: argparse.Namespace) -> int:
    out = default_out(args)

    def progress(row: dict) -> None:
        print(f"  {'pass' if row['passed'] else 'FAIL'}  {row['category']:10s} {row['case']:24s} {row['measured']}",
              flush=True)

    with study_claimed(out, "extreme.jsonl"):  # (its folder this process's, to the end of its report)
        rows = api.extreme(args.config, out, progress=progress, **_overrides(args))
        kept = ("the study", "extreme.csv, extreme.jsonl and the cases' run folders")
        with kept_whole(args, out, *kept):  # (a signal from here on: the study is kept, whole, said so)
            failed = [r["case"] for r in rows if not r["passed"]]
            print(f"{len(rows)} cases: {len(rows) - len(failed)} as expected, {len(failed)} not"
                  + (f" ({', '.join(failed)})" if failed else "") + f"; wrote {out}")
            report_after(args, out, *kept)
    return 1 if failed else 0


EXPERIMENT_ARGS = cli_parser.EXPERIMENT_ARGS  # (the commands whose config is an experiment's: importable here)


def _cmd_config(args: argparse.Namespace) -> int:
    if args.config_cmd == "list":
        names = api.list_experiments()
        if not args.long:
            print("\n".join(names))
            return 0
        runs = {name: f"tlm {api.experiment_command(name)} {name}" for name in names}
        wide, wider = max(map(len, names), default=0), max(map(len, runs.values()), default=0)
        for name in names:
            print(f"{name:{wide}s}  {runs[name]:{wider}s}  {api.experiment_description(name)}".rstrip())
        return 0
    written = api.export_experiment(args.name, args.file)
    file = Path(args.file)  # (not in written: it is already this copy, kept as it was)
    base = [f"{p} (its base config, which it names)" for p in written if p != file]
    said = (f"wrote {file} (a copy of the built-in experiment {args.name})" if file in written else
            f"{file} is already a copy of the built-in experiment {args.name}: kept")
    if base:
        said += (" and " if file in written else "; wrote ") + base[0]
    print(f"{said}; run it: tlm {api.experiment_command(args.name)} {shell_word(str(file))}")
    return 0


# a scene file's keys that are no run setting: `--set camera.vfov=50` on a scene file is told where they go
_SCENE_ONLY = ("camera", "lights", "materials", "parts", "default_material", "geometry", "transform",
               "crease_angle", "extends")


def _cmd_run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    storage.SAID.clear()
    overrides = list(args.set or [])
    flagged = {}  # (--mode/--seed: recorded as the --set they amount to, their errors named by the flag)
    for flag, value in (("mode", args.mode), ("seed", args.seed)):
        if value is None:
            continue
        twice = [o for o in overrides if o.partition("=")[0].strip() == flag]
        if twice:  # (which one was meant: neither is dropped silently)
            raise InputError(f"--{flag} {value} and --set {twice[-1]} both set {flag}: give one", key=f"--{flag}")
        overrides.append(f"{flag}={value}")
        flagged[f"--{flag} {value}"] = overrides[-1]
    outputs = None if args.outputs is None else api.parse_outputs(args.outputs)  # (named before the config)
    out = default_out(args)  # (a pipe's config, of no name of its own: --out asked for before it is read)
    try:
        cfg = api.load_config(args.config, overrides)
    except InputError as exc:
        blame_flag(args.config, list(args.set or []), flagged)
        root = (exc.key or "").split(".", 1)[0]
        # (--set camera.vfov=50 on a scene file; a pipe's text is read once, by the load: no hint on it)
        if root in _SCENE_ONLY and Path(args.config).is_file() and api.scene_file(args.config) is not None:
            raise InputError(f"{exc} ({root} is a key of the scene file, not a run setting that --set takes: edit "
                             f"{args.config}'s {root}:, or write a scene file with `extends: "
                             f"{Path(args.config).resolve()}` (extends: is read from the new file's folder) and "
                             f"the {root}: to change (docs/scenes.md), and run that)") from None
        raise
    storage.check_destination(out, "results.json")  # (a bad --out its one line, nothing said before it)
    if cfg.scene_file:  # (a note on stdout, with the run's lines, once the config loaded and --out checked: bad
        # input is its one line on stderr, and a warning said before the render is stderr's first line)
        if Path(str(cfg.scene)).resolve() == Path(cfg.source).resolve():  # (the scene file the config was read from)
            _say(f"{args.config} is a scene file: rendering it with the default settings "
                 f"(a config would say `scene: {args.config}`; see 'tlm params')")
        else:  # (--set scene=... replaced it: say what is rendered)
            _say(f"{args.config} is a scene file, but --set scene={cfg.scene} replaces it: rendering {cfg.scene} "
                 "with the default settings")
    skip = "--no-reference" if args.no_reference else None if cfg.reference.auto else "reference.auto: false"
    with claims.claimed(out, "run"):  # (the run's, and its report's: another process's run into it is refused)
        with cli_report.reference_cut_short():  # (a signal as its reference is computed: its rounds kept, said)
            results = api.run(cfg, out, outputs=outputs, progress=not args.no_progress, reference=skip is None,
                              say=say_err)
        with kept_whole(args, out, "the run", "results.json and its files"):  # (a signal from here on: the run
            print_run(results, out, skip, lambda: _reference_command(args, overrides), t0)  # is in place, said so)
            report_after(args, out, "the run", "results.json and its files")
    return 0


def _reference_command(args: argparse.Namespace, overrides: list[str]) -> str:
    """The ``tlm reference`` command that computes the reference of the run ``args``: its config as
    typed, and the overrides the run had (``--set``, and ``--mode``/``--seed`` as ``--set``)."""
    argv = args.argv if getattr(args, "argv", None) is not None else sys.argv[1:]
    try:
        typed = build_parser().parse_args(list(argv)).config
    except (InputError, SystemExit, AttributeError):  # (a run not from a command line: its config's path)
        typed = args.config
    gone = api.experiment_path.nameless(args.config)  # (a pipe's /dev/fd/63: no file to read again later)
    command = " ".join(["tlm reference", "FILE" if gone else shell_word(str(typed)),
                        *(f"--set {shell_word(o)}" for o in overrides)])
    return f"{command} (FILE: the config, saved to a file: {typed} is {gone})" if gone else command


def _cmd_sweep(args: argparse.Namespace) -> int:
    out = default_out(args)
    storage.SAID.clear()  # (a cache's line said during the sweep is not passed to warned again)

    def warned(line: str) -> None:  # (each as it is known: the factors' before the points run)
        print(f"tlm: warning: {escaped(line)}", file=sys.stderr, flush=True)

    if args.json and not args.dry_run:  # (asked for, and read by nothing: refused, not dropped)
        raise InputError("prints the plan of a dry run as JSON: give --dry-run too (a sweep prints its rows' "
                         "summary and writes sweep.jsonl and sweep.csv)", key="--json")
    if args.dry_run:  # what the sweep would do: its checks, then a summary; nothing run or written
        plan = api.run_sweep(args.config, out, jobs=args.jobs, dask=args.dask, dask_wait=args.dask_wait,
                             reference=args.reference, dry_run=True, **_overrides(args))
        print(json.dumps(plan.record(), indent=1) if args.json else "\n".join(plan.lines()), flush=True)
        for line in plan.warnings:  # (on stderr, as the sweep says them; in the JSON too)
            warned(line)
        return 0
    with sweep_cut_short(out):  # (a signal: how many of its points the folder keeps, and how to go on)
        done = api.run_sweep(args.config, out, jobs=args.jobs, dask=args.dask, progress=not args.no_progress,
                             dask_wait=args.dask_wait, warn=warned, reference=args.reference, say=_say,
                             **_overrides(args))
    with kept_whole(args, out, "the sweep", "its points, sweep.jsonl and sweep.csv"):
        for row in done.rows:
            if row["status"] != "ok":
                print(f"  point {row['point']} ({row['hash']}) failed: {row['error']}")
        n = len(done.rows)
        print(f"{n} points: {done.ok} ok, {done.failed} failed, {done.skipped} skipped (done before); "
              f"{done.renders} rendered; {done.seconds:.1f} s; wrote {out}")
        print_point_warnings(done.rows, out, done.warnings)  # (on stderr: how many points recorded each)
        report_after(args, out, "the sweep", "its points, sweep.jsonl and sweep.csv")
    return 1 if done.failed else 0


def _cmd_scaling(args: argparse.Namespace) -> int:
    dirs = [Path(d) for d in args.sweeps]
    out = Path(args.out) if args.out else Path("runs") / f"eq52_{dirs[0].name}"
    with study_claimed(out, "eq52.json"):
        done = api.scaling(dirs, out)
        with kept_whole(args, out, "the fit", "eq52.json, eq52.csv and a figure per scene"):
            _print_scaling(done, out)
            report_after(args, out, "the fit", "eq52.json, eq52.csv and a figure per scene")
    return 0


def _cmd_scene(args: argparse.Namespace) -> int:
    if args.scene_cmd == "list":
        names = api.list_scenes()
        # a scene whose description starts "Bad input" is one on purpose: a test of an error message
        hidden = [] if args.all else [n for n in names if api.scene_description(n).startswith("Bad input")]
        for name in names:
            if name not in hidden:
                print(f"{name:28s} {api.scene_description(name)}".rstrip() if args.long else name)
        if hidden:  # (on stderr: stdout stays the names a config may give)
            say_err(f"scene list: {len(hidden)} scenes of bad input on purpose (tests of tlm's error messages: "
                     f"{', '.join(hidden)}) left out; --all lists them")
        return 0
    scene = api.load_scene(args.name)
    if args.scene_cmd == "show":
        print(json.dumps(api.scene_info(scene), indent=2))
        return 0
    scene = api.export_scene(scene, args.file)  # (the scene as written: the materials its triangles use)
    file = Path(args.file)
    mtl = f"{file.with_suffix('.mtl')} ({len(scene.materials)} materials)"
    if file.suffix.lower() in (".yaml", ".yml"):
        lights = sum(1 for lt in scene.lights if lt.kind != "mesh")
        besides = " besides emitting materials" if any(m.emits for m in scene.materials) else ""
        print(f"wrote {file} (the scene file: {lights} light{'s' if lights != 1 else ''}{besides}, "
              f"the camera, {scene.camera.width}x{scene.camera.height}, {scene.photons} photons), "
              f"{file.with_suffix('.obj')} ({scene.n_triangles} triangles) and {mtl}")
        return 0
    also = f" and {mtl}" if file.suffix.lower() == ".obj" else ""
    print(f"wrote {file} ({scene.n_triangles} triangles){also}; the scene file's lights, camera and "
          "resolution are not in it (export to a .yaml file for all of them)")
    return 0


def _cmd_reference(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    with cli_report.reference_cut_short():  # (a signal as it is computed: the rounds kept, and how to resume)
        made = api.reference(
            api.load_config(args.config, list(args.set or [])), force=args.force, say=print,
            progress=lambda k, c, e: None if math.isnan(e) else _say(  # (NaN: a round that ends no measured cycle)
                f"  round {k:3d}  change {c:.4f}  relative standard error {e:.4f}"),
            bar=not args.no_progress,
        )
    meta = made.meta
    if not made.computed and made.meets:  # (a cached one kept that misses the tolerance: said below)
        print(f"reference {made.key} is cached, relative standard error {meta['relative_standard_error']:.4f} "
              f"< tolerance {made.settings.tolerance} after {meta['rounds']} rounds (use --force to compute it again)")
        return 0
    ok = made.meets  # (judged against the tolerance asked for now, as the cache was: not its stored flag)
    state = "converged" if ok else "NOT converged (max_rounds reached)"
    rse = meta.get("relative_standard_error")
    err = "no relative standard error" if rse is None else f"relative standard error {rse:.4f}"
    if not ok and rse is not None and rse > made.settings.tolerance:
        err += f" > tolerance {made.settings.tolerance}"
    where = f"the cache keeps {made.folder}" if made.kept else f"wrote {made.folder}"  # (the line before says why)
    # (the seconds of a computation; none computed: the cached one was found, its rounds run by an earlier command)
    took = f" in {time.perf_counter() - t0:.1f} s" if made.computed else ", found cached (nothing computed)"
    print(f"{state} after {meta['rounds']} rounds ({err}){took}; {where}"
          + ("" if ok else " (raise reference.max_rounds"  # (h473: how far, estimated)
             f"{made.advice}, or reference.tolerance; exit status 1)"))
    return 0 if ok else 1  # (a result to act on, as a failed sweep point or extreme case is)


def _cmd_error_vs_cost(args: argparse.Namespace) -> int:
    out = default_out(args)

    def progress(i: int, n: int, row: dict) -> None:
        # (rel_mse against tlm's own photon-map reference; the composite's against Mitsuba, FLIP where measured)
        rel = "n/a" if row["rel_mse"] is None else f"{row['rel_mse']:.4g} vs reference"
        if row["truth_rel_mse"] is not None:
            flip = "" if row["truth_flip"] is None else f", FLIP {row['truth_flip']:.3f}"
            rel += f" (composite vs Mitsuba {row['truth_rel_mse']:.4g}{flip})"
        fps = "-" if row.get("fps") is None else f"{row['fps']:.3g}"
        settings = f"  ({row['factors']})" if row.get("factors") else ""  # (every setting the point varies)
        # (no radius: the filter takes none, knn, or the map is not gathered: '-', as the CSV's empty cell)
        radius = "-" if row["radius"] is None else f"{row['radius']:.3g}"
        print(f"  [{i + 1:3d}/{n}] {row['filter']:6s} photons {row['photons']:>7d} radius {radius:>8s} "
              f"k {row['k'] or row['k_nearest'] or '-'!s:>4s}  relMSE {rel:>9s}  tested {row['photons_tested']:>10d}  "
              f"gather {row['gather_seconds']:.2f} s  simulated {fps} fps{settings}", flush=True)

    def note(message: str) -> None:
        print(f"error-vs-cost: {message}", flush=True)

    with study_claimed(out, "rows.jsonl"):
        with cli_report.reference_cut_short():  # (a signal as its reference is computed: its rounds kept, said)
            rows = api.error_vs_cost(args.config, out, truth_spp=args.truth_spp, progress=progress, note=note,
                                     **_overrides(args))
        with kept_whole(args, out, "the study", "rows.csv, rows.jsonl and reference.json"):
            print(f"wrote {out} ({len(rows)} rows)")
            report_after(args, out, "the study", "rows.csv, rows.jsonl and reference.json")
    return 0


def _cmd_params(args: argparse.Namespace) -> int:
    rows = api.params()
    wide = max((len(key) for key, _, _ in rows), default=0)  # (the longest key's width: each value in its column)
    for key, default, help_text in rows:
        print(f"{key:{wide}s} {_yaml_text(default):>10s}  {help_text}")
    return 0


def _cmd_thesis(args: argparse.Namespace) -> int:
    out = default_out(args)

    def progress(scene, mode, results):
        c = results["cycles"]
        fps = "-" if results["fps"] is None else figures3(results["fps"])
        _say(f"  {scene} {mode}: throughput {c['throughput'] / 1e6:.2f} M cycles, {fps} fps")

    with study_claimed(out, "thesis_comparison.csv"):
        done = api.thesis(args.config, out, progress=progress, bar=not args.no_progress, **_overrides(args))
        kept = ("the study", "thesis_comparison.csv, thesis_summary.json and a run folder per scene and mode")
        with kept_whole(args, out, *kept):  # (a signal from here on: the study is kept, whole, said so)
            _print_thesis(done, out)
            report_after(args, out, *kept)
    return 0


def _cmd_granularity(args: argparse.Namespace) -> int:
    out = default_out(args)

    progress = GranularityProgress()  # (its lines as wide as the widest packet size: h407)
    with study_claimed(out, "granularity.jsonl"):
        rows = api.granularity(args.config, out, progress=progress, start=progress.start, **_overrides(args))
        with kept_whole(args, out, "the study", "granularity.csv and granularity.jsonl"):
            print_granularity(rows, out)  # (and, where the sizes ran different frame counts, a line saying so)
            report_after(args, out, "the study", "granularity.csv and granularity.jsonl")
    return 0


def _cmd_calibrate(args: argparse.Namespace) -> int:
    def progress(it, params):  # (--no-progress: none of these lines; the fit's result lines stay)
        if not args.no_progress:
            print(f"  iteration {it}: " + ", ".join(f"{k} {v:.4g}" for k, v in params.items()), flush=True)

    if args.leave_one_out:  # (a dry run of each fit: no table written)
        if args.write is not None:
            raise InputError("--leave-one-out writes no table: drop --write", source=args.config)
        _, loo = api.calibrate(args.config, held_out=True,
                               progress=lambda left, it, params: progress(f"{it} without {left}", params))
        print("\n".join(held_out_lines(loo)))
        if loo["not_comparable"]:
            print(escaped("tlm: warning: a fit to another setting than the thesis's measures the setting, not the "
                          "model: " + "; ".join(f"{s} is {', '.join(w)}" for s, w in loo["not_comparable"].items())),
                  file=sys.stderr)
        return 0
    once = api.experiment_path.nameless(args.config)  # (tlm.api_common.nameless: a pipe, a named FIFO: read once)
    if not args.dry_run and args.write is None and once in ("a pipe", "a named FIFO"):
        raise InputError(f"is {once}, read once: its own table (base.arch.programs) is found by a read of the study "
                         "before the fit's: give --write FILE, or --dry-run", source=args.config)
    if not args.dry_run:  # (a table it may not write is refused before the fit, not after it)
        api.calibration_table(getattr(args, "given", args.config), args.write)  # (its refusal names it as typed)
    programs, report = api.calibrate(args.config, progress=progress)
    for scene, cells in report["cells"].items():
        print(f"  {scene:8s} " + "  ".join(f"{m} {v['ours']:.3f} (thesis {v['thesis']})" for m, v in cells.items()))
    print("\n".join(fit_lines(report.get("fit") or {})))
    differ = report.get("not_comparable") or {}
    warning = ("tlm: warning: a fit to another setting than the thesis's measures the setting, not the model: "
               + "; ".join(f"{s} is {', '.join(w)}" for s, w in differ.items())) if differ else None
    if not args.dry_run:
        command = "tlm calibrate " + " ".join(sys.argv[2:]) if args.argv is None else "tlm " + " ".join(args.argv)
        # (refused, nothing written, for the packaged table from such a fit: api.write_calibration)
        target = api.write_calibration(programs, report, args.write, command)
    if warning:
        print(escaped(warning), file=sys.stderr)
    if not args.dry_run:
        print(f"wrote {target}")
    return 0


def _overrides(args: argparse.Namespace) -> dict[str, list[str]]:
    """A study's or sweep's ``--set`` strings, in the order given, as the keyword argument of its
    API function (``overrides``); none given: no argument (the function's default, none)."""
    given = list(getattr(args, "set", None) or [])
    return {"overrides": given} if given else {}


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``tlm`` and its commands: each command's name, help and handler here, its arguments
    :mod:`tlm.cli_parser`'s."""
    p = Parser(prog="tlm", description="Transaction-level model of J. Ling's "
                                "ray-tracing and photon-mapping GPU (2004).")
    p.add_argument("--version", action=cli_parser.VersionAction)
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="render one experiment into a run folder")
    cli_parser.run_arguments(r)
    r.set_defaults(func=_cmd_run)
    sw = sub.add_parser("sweep", help="run a base config over a grid of factors, one folder and one row per point "
                        "(resumable)")
    cli_parser.sweep_arguments(sw)
    sw.set_defaults(func=_cmd_sweep)
    sc = sub.add_parser("scaling", help="fit eq. 5.2 to scaling sweeps over arch.pipelines; table and figures "
                        "(Figs. 18-20)")
    cli_parser.scaling_arguments(sc)
    sc.set_defaults(func=_cmd_scaling)
    s = sub.add_parser("scene", help="list, show or export scenes")
    cli_parser.scene_commands(s)
    s.set_defaults(func=_cmd_scene)
    rf = sub.add_parser("reference", help="compute and cache the converged photon-map reference of a config",
                        description="Compute and cache the converged photon-map reference of a config. Exit "
                        "status 0 when it is converged (or cached so), 1 when it stopped at reference.max_rounds "
                        "without reaching reference.tolerance (cached where it is better than a cached one, else "
                        "the cache keeps its own; the line says which, and what to raise), 2 for bad input.")
    cli_parser.reference_arguments(rf)
    rf.set_defaults(func=_cmd_reference)
    ev = sub.add_parser("error-vs-cost", help="photon-map filters: image error against work and host time")
    cli_parser.error_vs_cost_arguments(ev)
    ev.set_defaults(func=_cmd_error_vs_cost)
    th = sub.add_parser("thesis", help="reproduce Tables I-III: every scene x mode, thesis_comparison.csv")
    cli_parser.thesis_arguments(th)
    th.set_defaults(func=_cmd_thesis)
    gr = sub.add_parser("granularity", help="cycle error of coarse packets against one ray per packet, "
                        "with host wall time")
    cli_parser.granularity_arguments(gr)
    gr.set_defaults(func=_cmd_granularity)
    ca = sub.add_parser("calibrate", help="fit the PM programs' free parameters (scales, cycles per record) "
                        "to the RCast column of Tables I-III")
    cli_parser.calibrate_arguments(ca)
    ca.set_defaults(func=_cmd_calibrate)
    rp = sub.add_parser("report", help="figures and report.html from run, sweep, thesis, scaling, granularity, "
                        "error-vs-cost or extreme folders")
    cli_parser.report_arguments(rp)
    rp.set_defaults(func=_cmd_report)
    ex = sub.add_parser("extreme", help="stiff and extreme cases: each case's expected behaviour against the "
                        "measured one (exit 1 if any differs)")
    cli_parser.extreme_arguments(ex)
    ex.set_defaults(func=_cmd_extreme)
    pl = sub.add_parser("plots", help="run the committed studies of configs/ (thesis, six sweeps and their eq. 5.2 "
                        "fit, granularity, error-vs-cost, extreme) and the cornell_pmap run, not the other "
                        "single-scene run configs, and write their report into plots/")
    cli_parser.plots_arguments(pl)
    pl.set_defaults(func=_cmd_plots)
    co = sub.add_parser("config", help="list the built-in experiments (the repository's configs/, shipped with "
                        "tlm), or copy one out to edit")
    cli_parser.config_commands(co)
    co.set_defaults(func=_cmd_config)
    pa = sub.add_parser("params", help="every config parameter with its default and meaning")
    pa.set_defaults(func=_cmd_params)
    add_cache_parser(sub)  # tlm cache [info | prune | clear] (tlm/cli_cache.py)
    return p


def _writes_files(args: argparse.Namespace) -> bool:
    """Whether the command ``args`` writes files (all but ``params`` and the listing and showing
    of scenes and experiments): a reader of its stdout that goes away stops it only once they are
    written (:func:`tlm.cli_signals.writes_files`)."""
    if args.func is _cmd_params:
        return False
    if args.func in (_cmd_scene, _cmd_config):
        return getattr(args, "scene_cmd", None) == "export" or getattr(args, "config_cmd", None) == "export"
    return True


def main(argv: list[str] | None = None) -> int:
    """The ``tlm`` command ``argv`` (None: the process's own, ``sys.argv[1:]``): its exit status.
    Its calls of the API keep the command line's flags in their errors (``--out: ...``, not
    ``out: ...``: :func:`tlm.api_common.argument_names`)."""
    finished = False  # the command returned: what it wrote is whole
    try:
        with signals(), api.argument_names.flags_kept():
            parser = build_parser()  # (a signal meanwhile is the command's: 130 / 143, its one line)
            if not (sys.argv[1:] if argv is None else argv):  # a bare ``tlm``: what it can do
                print(parser.format_help(), end="")  # (as ``tlm --help``: asked for, not an error)
                status = 0
            else:
                args = parser.parse_args(argv)
                args.argv = argv
                cli_parser.experiment_arg(args)
                cli_parser.figure_args(args)
                writes = _writes_files(args)
                if writes:  # (a render, a report's figures: OpenBLAS's buffer mapped first, blas_buffer_mapped)
                    blas_buffer_mapped()
                if args.func not in (_cmd_params, _cmd_scene, _cmd_config, _cmd_report, _cmd_scaling, cache_command):
                    # (those that may render: the others never import numba)
                    check_numba_threads()  # (numba's import fails on a NUMBA_NUM_THREADS below 1: said first)
                with writes_files(writes):
                    status = args.func(args)
            finished = True
            if argv is None and signalled() is None:  # the process's own command, done: a signal until
                return until_exit(status)  # the process exits still says that it ran to its end (130 / 143)
    except SystemExit as e:  # --help, --version: ended as a command that returned
        code = e.code if isinstance(e.code, int) else 0
        return until_exit(code) if argv is None else code
    except (Exception, KeyboardInterrupt) as e:  # its one line and its exit status
        if not (finished and isinstance(e, KeyboardInterrupt)):
            return exit_status(e, argv)
        return interrupted(argv, finished=True)  # (came as the command returned)
    if signalled() is not None:  # signalled, yet it ran to its end: its interrupt was raised where
        # CPython ignores exceptions (an at-fork hook, a ctypes callback), after the command's last
        # checkpoint (tlm.progress.checkpoint: one before stops it there). Still 130 / 143, and
        # its output, whole, is kept (as an interrupt during a run's report keeps the run's folder)
        return interrupted(argv, finished=True)
    return status


if __name__ == "__main__":
    status = main()
    forget_lost_interrupt()  # (see there: else ``python -m tlm.cli`` may die by SIGINT whatever the status)
    sys.exit(status)
