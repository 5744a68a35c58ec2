"""The arguments of each ``tlm`` command (its positionals, its options and their help): one function a command
(:func:`run_arguments`, :func:`sweep_arguments`, ...; ``tlm scene`` and ``tlm config`` with their own commands:
:func:`scene_commands`, :func:`config_commands`), called on the command's parser by :func:`tlm.cli.build_parser`,
which names the commands, their help and their handlers; and the checks of the parsed arguments before a command
runs (:func:`experiment_arg`: an experiment command's config, a file or a built-in experiment's name;
:func:`figure_args`: ``--formats`` and ``--dpi``). Out of :mod:`tlm.cli` (h487); the argument types and the
options several commands share are :mod:`tlm.cli_args`'s, ``tlm cache``'s arguments :mod:`tlm.cli_cache`'s."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tlm import api
from tlm.api import MODES, InputError
from tlm.cli_args import NO_BAR, figure_files, folder_name, no_progress, no_report, seconds, table_file, title
from tlm.cli_args import experiment_argument as _experiment_file
from tlm.cli_report import say_err
from tlm.errors import path_shown


class VersionAction(argparse.Action):
    """``tlm --version``: one line (never wrapped to the terminal's width, as argparse's own would) saying what
    identifies the code that runs, computed only when asked (:func:`tlm.api.version_line`:
    the version, the git commit and whether the checkout is modified, the code fingerprint ``results.json``
    records), then the exit."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, **kw):
        kw.setdefault("help", "show what identifies this tlm's code (version, git commit, code fingerprint) and exit")
        super().__init__(option_strings=option_strings, dest=dest, default=default, nargs=0, **kw)

    def __call__(self, parser, namespace, values, option_string=None):
        from tlm.api import version_line

        parser._print_message(version_line() + "\n", sys.stdout)
        parser.exit()


def _set_option(parser: argparse.ArgumentParser, where: str, example: str = "'resolution=[64, 64]'") -> None:
    """``--set KEY=VALUE`` of a command that runs configs made from a file's base (``where``: what
    it applies to, and what it may not set), as ``tlm run --set`` reads it; ``example``: a --set,
    as typed, that the command takes with each of its built-in experiments (not a key they set
    themselves, which it refuses: tests/test_help_docs_h188.py)."""
    parser.add_argument("--set", action="append", metavar="KEY=VALUE",
                        help=f"override a parameter by dotted key, as tlm run --set does (repeated; e.g. --set "
                        f"{example}), in {where}")


def run_arguments(r: argparse.ArgumentParser) -> None:
    """``tlm run``'s arguments."""
    r.add_argument("config", help="experiment YAML (see 'tlm params'), a built-in experiment's name ('tlm config "
                   "list'), or a scene YAML to render at the default settings")
    r.add_argument("--out", type=folder_name, help="run folder (default: runs/<config name>)")
    r.add_argument("--mode", choices=MODES, help="override the mode")
    r.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="override a parameter by dotted key, e.g. --set render.reflect_depth=2")
    r.add_argument("--seed", type=int, help="override the seed")
    r.add_argument("--outputs", metavar="NAMES", help="what the run folder gets besides images/ and results.json: "
                   "a comma-separated list of aov, radiance, trace (default: all three; 'images' alone: none)")
    r.add_argument("--no-reference", action="store_true", help="a photon-map run without a cached reference "
                   "does not compute one (nor its error); default: reference.auto (see 'tlm reference')")
    no_progress(r)
    no_report(r)


def sweep_arguments(sw: argparse.ArgumentParser) -> None:
    """``tlm sweep``'s arguments."""
    _experiment_file(sw, "sweep YAML (base, set, grid, zip)", "sweep_fifo")
    sw.add_argument("--out", type=folder_name, help="output folder (default: runs/<config name>)")
    sw.add_argument("--jobs", type=int, help="worker processes (default: the CPUs available, as for "
                    "render.threads, without its cap of 8; 1 = in this process); a point that leaves "
                    "render.threads null gets max(1, CPUs // workers) kernel threads (at most 8), so --jobs x "
                    "render.threads stays within the CPUs; not with --dask tcp://...: its workers are the cluster's")
    sw.add_argument("--dask", metavar="local|tcp://HOST:PORT",
                    help="run on Dask: 'local' starts a LocalCluster of --jobs workers, else a scheduler address "
                    "(its points run as many at once as its workers have threads)")
    sw.add_argument("--dask-wait", type=seconds, metavar="SECONDS", help="with --dask: how long the sweep waits while "
                    "the scheduler has no worker (or does not answer) before it stops, keeping the points done "
                    "(default: 300)")
    _set_option(sw, "every point's base config, after the sweep file's set: and before its factors (a factor's "
                "key is refused); part of each point's hash, and listed in sweep.yaml")
    sw.add_argument("--reference", action="store_true", help="compute and cache, before the points, each photon-map "
                    "reference they need that is not cached, or cached short of its tolerance where more rounds are "
                    "allowed (as 'tlm reference' decides), so their error is measured")
    sw.add_argument("--dry-run", action="store_true", help="run nothing and write no output (no folder, no frame or "
                    "reference or parsed scene in the cache, no report): check "
                    "the sweep file, --set and --out as the sweep does, then say how many points are done already in "
                    "--out (skipped) and to run, how many frames they share and how many of those are cached, the "
                    "references --reference would compute, the stale folders it would remove and the warnings it "
                    "would give before its points run")
    sw.add_argument("--json", action="store_true", help="with --dry-run: print the plan as one JSON object (its "
                    "warnings in it) in place of the summary")
    no_progress(sw)
    no_report(sw)


def scaling_arguments(sc: argparse.ArgumentParser) -> None:
    """``tlm scaling``'s arguments."""
    sc.add_argument("sweeps", nargs="+", help="output folders of 'tlm sweep', e.g. runs/scaling_cornell")
    sc.add_argument("--out", type=folder_name, help="output folder (default: runs/eq52_<first sweep folder's name>)")
    no_progress(sc, NO_BAR)
    no_report(sc)


def scene_commands(s: argparse.ArgumentParser) -> None:
    """``tlm scene``'s commands (``list``, ``show``, ``export``) and their arguments."""
    ss = s.add_subparsers(dest="scene_cmd", required=True, metavar="{list,show,export}")
    sl = ss.add_parser("list", help="the built-in scenes (names for a config's scene: key)")
    sl.add_argument("-l", "--long", action="store_true", help="with each scene's description")
    sl.add_argument("--all", action="store_true", help="also the scenes of bad input on purpose (tests of the "
                    "error messages: a description that starts 'Bad input')")
    sh = ss.add_parser("show", help="triangle count, bounds, materials, lights, camera, and notes on what the mesh "
                       "files gave that was imported or left out")
    sh.add_argument("name", help="built-in scene name or scene YAML path")
    se = ss.add_parser("export", help="world-space triangles in triangle-id order (PLY or OBJ), or the whole "
                       "scene as a scene file (.yaml, with its OBJ and MTL beside it)")
    se.add_argument("name", help="built-in scene name or scene YAML path")
    se.add_argument("file", help="output .ply, .obj or .yaml")


def reference_arguments(rf: argparse.ArgumentParser) -> None:
    """``tlm reference``'s arguments."""
    rf.add_argument("config", help="experiment YAML, or a built-in experiment's name: cornell_pmap")
    rf.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a parameter by dotted key")
    rf.add_argument("--force", action="store_true", help="compute again even if cached")
    no_progress(rf)


def error_vs_cost_arguments(ev: argparse.ArgumentParser) -> None:
    """``tlm error-vs-cost``'s arguments."""
    _experiment_file(ev, "experiment YAML (base config and grids of points)", "error_vs_cost")
    ev.add_argument("--out", type=folder_name, help="output folder (default: runs/<config name>)")
    ev.add_argument("--truth-spp", type=int, default=4096, metavar="N",
                    help="samples per pixel of the Mitsuba 3 path-traced ground truth the composites are also "
                         "measured against (default: %(default)s; computed once and cached; needs Mitsuba 3 and "
                         "flip-evaluator: pip install -e '.[oracle]' in a checkout); 0: none")
    _set_option(ev, "the base config of every point (a key the points vary, or mode, is refused)")
    no_progress(ev, NO_BAR)
    no_report(ev)


def thesis_arguments(th: argparse.ArgumentParser) -> None:
    """``tlm thesis``'s arguments."""
    _experiment_file(th, "study YAML (base, scenes, modes; without base every cell runs at the default "
                        "settings, not the thesis's)", "thesis")
    th.add_argument("--out", type=folder_name, help="output folder (default: runs/<config name>)")
    _set_option(th, "the base config of every cell (scene and mode, which scenes: and modes: set, are refused)")
    no_progress(th)
    no_report(th)


def granularity_arguments(gr: argparse.ArgumentParser) -> None:
    """``tlm granularity``'s arguments."""
    _experiment_file(gr, "YAML with base and packet_sizes", "tlm_granularity")
    gr.add_argument("--out", type=folder_name, help="output folder (default: runs/<config name>)")
    _set_option(gr, "the base config (arch.packet_size, which packet_sizes sets, is refused)")
    no_progress(gr, NO_BAR)
    no_report(gr)


def calibrate_arguments(ca: argparse.ArgumentParser) -> None:
    """``tlm calibrate``'s arguments."""
    _experiment_file(ca, "study YAML with at least two of the thesis's scenes and mode rcast", "thesis")
    ca.add_argument("--write", type=table_file, metavar="TABLE",
                    help="table to write (default: the study's own, its base.arch.programs, else the packaged "
                    "tlm/arch/programs.yaml; the packaged table is never written from a study at another setting "
                    "than the thesis's)")
    ca.add_argument("--dry-run", action="store_true", help="fit and print, write nothing")
    ca.add_argument("--leave-one-out", action="store_true",
                    help="a held-out check, writing nothing: fit to all scenes but one, for each scene, and print the "
                    "left-out scene's fitted cells' |rel error| (median, max) beside the in-sample fit's")
    no_progress(ca, "this command draws none, but drops the fit's iteration lines (its cells' and fit's lines stay)")


def report_arguments(rp: argparse.ArgumentParser) -> None:
    """``tlm report``'s arguments."""
    rp.add_argument("dirs", nargs="+", metavar="DIR", help="tlm output folders, or folders of them (e.g. runs/)")
    rp.add_argument("--out", type=folder_name,
                    help="report folder (default: DIR/report; required for several folders)")
    rp.add_argument("--title", type=title, help="the page's title (default: tlm report: and the folders' names)")
    no_progress(rp)
    figure_files(rp)


def extreme_arguments(ex: argparse.ArgumentParser) -> None:
    """``tlm extreme``'s arguments."""
    _experiment_file(ex, "cases YAML", "extreme")
    ex.add_argument("--out", type=folder_name, help="output folder (default: runs/<config name>)")
    _set_option(ex, "the base config merged under every case's (a key a case's config gives is refused)",
                example="render.spp=2")  # (its cases set resolution)
    no_progress(ex, NO_BAR)
    no_report(ex)


def plots_arguments(pl: argparse.ArgumentParser) -> None:
    """``tlm plots``'s arguments."""
    pl.add_argument("--configs", help="folder of the experiment files (default: ./configs where it exists, else "
                    "the built-in experiments: 'tlm config list'); a step whose file NAME.yaml it lacks is skipped, "
                    "said in a line, unless --only names it")
    pl.add_argument("--runs", default="runs", help="folder for the experiments' outputs (default: runs)")
    pl.add_argument("--out", type=folder_name, default="plots", help="report folder (default: plots)")
    pl.add_argument("--only", nargs="+", action="extend", metavar="STEP", help="run only these steps, of: thesis "
                    "scaling_ring scaling_room scaling_cornell design_space bsp_levels sweep_fifo eq52 tlm_granularity "
                    "error_vs_cost cornell_pmap extreme (--only may be given again); the report reads every step's "
                    "folder that exists; a step that exits 1 (failures among its results) is said, the others and "
                    "the report still run, and tlm plots then exits 1")
    no_progress(pl, "passed to every step (of them tlm thesis and tlm run draw bars, when stderr is a terminal; "
                "the sweep steps run with --no-progress always, and the report tlm plots writes draws none)")
    figure_files(pl)


def config_commands(co: argparse.ArgumentParser) -> None:
    """``tlm config``'s commands (``list``, ``export``) and their arguments."""
    cs = co.add_subparsers(dest="config_cmd", required=True, metavar="{list,export}")
    cl = cs.add_parser("list", help="the built-in experiments: names that the commands taking an experiment file "
                       "take instead (tlm run cornell_pmap)")
    cl.add_argument("-l", "--long", action="store_true", help="with the command that runs each one and its "
                    "description")
    ce = cs.add_parser("export", help="copy a built-in experiment into a file to edit (a sweep's base config "
                       "beside it too)")
    ce.add_argument("name", help="built-in experiment name ('tlm config list')")
    ce.add_argument("file", help="output .yaml")


# the commands whose positional ``config`` is an experiment file or a built-in experiment's name
EXPERIMENT_ARGS = ("run", "sweep", "reference", "error-vs-cost", "thesis", "granularity", "calibrate", "extreme")


def figure_args(args: argparse.Namespace) -> None:
    """``--formats`` and ``--dpi`` checked before the command does any work (as ``tlm report``
    checks them, :func:`tlm.api.report_output`); with ``--no-report`` they would be read by
    nothing: refused, not dropped."""
    given = [f"--{k}" for k in ("formats", "dpi") if getattr(args, k, None) is not None]
    if not given:
        return
    if getattr(args, "no_report", False):
        raise InputError(f"{'set' if len(given) > 1 else 'sets'} the report's figure files, and --no-report "
                         "writes no report: give one or the other", key=" and ".join(given))
    api.report_output(args.formats, args.dpi)


def experiment_arg(args: argparse.Namespace) -> None:
    """``args.config`` of an experiment command as the file it names: the path given when it
    exists, else the built-in experiment of that name (said on stderr, with its file);
    anything else is an InputError (:func:`tlm.api.experiment_path`)."""
    if getattr(args, "cmd", None) not in EXPERIMENT_ARGS:
        return
    path = api.experiment_path(args.config, args.cmd)
    if path == Path(args.config):  # (the path given, as given: dd/ and ./dd are no built-in experiment's)
        if path.is_dir():  # (said once, as such: not read as a file, which says it cannot)
            raise InputError("is a folder, not a config file: name a YAML file, or a built-in experiment "
                             "('tlm config list')", source=args.config)
        return
    say_err(f"{path_shown(args.config)}: the built-in experiment {path_shown(path)}")
    args.config, args.given = str(path), args.config  # (given: as typed, for a command printed to run again)
