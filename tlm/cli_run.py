"""``tlm run``'s lines: what it prints of the run it wrote (:func:`print_run`: the scene, each pass's
work, the photon-map frame's error against its reference, the timing, the warnings; :func:`figures3`: a
number to three figures, ``tlm thesis``'s frame rates too), and which flag a refused config is named by
(:func:`blame_flag`: ``with --seed -1``, not ``with --set``), and the folder an experiment command writes by
default (:func:`default_out`). The command itself is :mod:`tlm.cli`'s."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

from tlm import api, storage
from tlm.api import InputError
from tlm.errors import escaped_line as escaped  # (tlm.cli_signals.escaped: the same lines)
from tlm.errors import shell_word


def blame_flag(config: str, sets: list[str], flagged: dict[str, str]) -> None:
    """Where ``config`` with ``sets`` (the --set strings) and the ``flagged`` ones (``{"--seed -1": "seed=-1"}``)
    is refused: the error of the first flag refused on top of ``sets`` alone, named by that flag (``cornell.yaml,
    with --seed -1: seed: -1 must be >= 0``, not ``with --set``); nothing where ``sets`` alone are refused or each
    flag alone passes (the caller's error, with --set, stands)."""
    if not flagged:
        return
    try:
        cfg = api.load_config(config, sets)
    except InputError:
        return
    for given, item in flagged.items():
        api.load_config(cfg, [item], via=given)


RESOLVED = "config.resolved.yaml"  # (what a run folder and a sweep point keep of their config)


def default_out(args: argparse.Namespace) -> Path:
    """The folder ``tlm run``, ``tlm sweep`` and the studies write: ``--out``, else ``runs/<the config's name>``.
    A config whose name is none of its own (:func:`~tlm.api_common.nameless`: a pipe, ``<(...)``'s
    ``/dev/fd/63``, ``/dev/stdin``) is refused, one line, nothing read: its default folder, ``runs/63``, would be
    every piped config's, the second replacing the first; so is a named FIFO's (read once: ``runs/c`` would be
    every config's written to it). So is a run folder's (or a sweep point's) ``config.resolved.yaml``: its default,
    ``runs/config.resolved``, would be the folder of every run folder's config run again, one replacing another's
    results; the line suggests a folder named after the run's (``runs/a-again`` for ``runs/a/config.resolved.yaml``).
    A file of another command's (a run folder's config given to ``tlm sweep``) is refused first as that, with the
    command to use (:func:`~tlm.api_common.other_command_first`), not asked for an ``--out`` it does not need."""
    if args.out:
        return Path(args.out)
    default = Path("runs") / Path(args.config).stem
    if Path(args.config).name == RESOLVED:
        # (a file the command does not take: what to run it with first, not --out: tlm sweep of a run folder's)
        api.experiment_path.other_command_first(args.config, getattr(args, "cmd", None) or "run")
        folder = shell_word(f"runs/{Path(args.config).absolute().parent.name or 'run'}-again")  # (run as printed)
        raise InputError(f"is a run folder's {RESOLVED}: give --out, say --out {folder} ({default}, the "
                         f"default, would be the folder of every run folder's {RESOLVED} run again, one replacing "
                         "another)", source=args.config)
    what = api.experiment_path.nameless(args.config)  # (tlm.api_common.nameless)
    if what == "a named FIFO":  # (a name of its own, but read once: each config written to it is another)
        raise InputError(f"is {what}, read once: give --out ({default}, the default, would be the folder of every "
                         f"config written to it, one replacing another)", source=args.config)
    if what is not None:
        raise InputError(f"is {what}: give --out (a name not its own: {default}, the default, would be the folder of "
                         f"every config given so, one replacing another)", source=args.config)
    return default


def print_run(results: dict, out: Path, skip: str | None, command: Callable[[], str], t0: float) -> None:
    """What ``tlm run`` prints of the run it wrote into ``out``: the scene, each pass's work, the
    error, the timing, and the warnings not said during the run; ``command()``: the ``tlm reference``
    command that computes a reference the run did not have (tlm/cli.py's ``_reference_command``), but for a
    config read once (a pipe), whose command ``results.json`` records: it names the run's ``config.resolved.yaml``
    (:func:`tlm.experiments.run.skipped_reference`)."""
    sc = results["scene"]
    print(f"scene {sc['name']}: {sc['triangles']} triangles, {sc['resolution'][0]}x{sc['resolution'][1]}, "
          f"BSP {sc['bsp']['levels']} levels, {sc['bsp']['leaves']} leaves")
    for name in results["plan"]["run"]:
        w = results["work"][name]
        if name == "pmap":
            ph = results["photons"]
            print(f"  pass {name:8s} photons {ph['emitted']:>8d} stored {ph['stored']:>8d} "
                  f"({ph['caustic']} caustic); {ph['filter']} gathers {w['gathers']}, "
                  f"photons tested {w['photons_tested']}")
            per = [(f"{m} (no radius" if ph.get(key) is None else f"{m} r={ph[key]:.4g} ({ph[f'{key}_rule']}")
                   + (f", ~{ph[f'{key}_photons']} photons" if f"{key}_photons" in ph else "")
                   + f"): tested {g['photons_tested_per_gather']:.1f} accepted {g['photons_accepted_per_gather']:.1f}"
                   for m, key in (("caustic", "caustic_radius"), ("indirect", "radius"), ("photons", "radius"),
                                  ("global", "global_radius"))
                   if (g := ph.get("gather", {}).get(m))]
            print(f"    per gather: tested {w['photons_tested_per_gather']:.1f} accepted "
                  f"{w['photons_accepted_per_gather']:.1f}" + "".join(f"; {x}" for x in per))
            continue
        print(f"  pass {name:8s} rays {w['primary_rays'] + w['secondary_rays']:>8d} "
              f"shadow {w['shadow_rays']:>8d} tri tests {w['tri_tests'] + w['shadow_tri_tests']:>10d} "
              f"({w['tri_tests_per_ray']:.1f} per ray, {w['tri_tests_per_shadow_ray']:.1f} per shadow ray)")
    if (error := results.get("error")) is not None:  # (a config read once, a pipe: the run's copy, as recorded)
        once = error.get("config_read_once")
        print(_error_line(error, skip, f"{error.get('command')} ({once})" if once else command()))
    for name, why in results["plan"]["left_out"].items():
        print(f"  left out {name}: {why}")
    for note in results["plan"]["notes"]:
        print(f"  note: {note}")
    cyc = results.get("cycles")
    if cyc:
        tm = results["timing"]
        asked = tm.get("frames_asked", tm["frames"])  # a dynamic stream runs on until it settles (tlm.arch.steady)
        ran = f"{tm['frames']} frames" + (f" run, {asked} asked" if asked != tm["frames"] else "")
        print(f"timing ({ran}, packets of {tm['packet_size']}, "
              f"{tm['clock_hz'] / 1e6:g} MHz), millions of cycles per frame:")
        print("  " + "  ".join(f"{k} {cyc[k] / 1e6:.3f}" for k in
                               ("vertex", "traversal", "intersection", "fragment", "throughput", "latency")))
        fps = results["fps"]  # (None: no cycles to time)
        print(f"  {figures3(fps)} frames per second" if fps is not None else "  no frame rate: a frame of no cycles")
    print(f"wrote {out} ({time.perf_counter() - t0:.2f} s)")  # (wall: the stages may overlap on threads)
    for warning in results["warnings"]:  # (less those said during the run: a render that may not end says why first)
        if " ".join(warning.split()) not in storage.SAID:
            print(f"tlm: warning: {escaped(warning)}", file=sys.stderr)


def figures3(x: float) -> str:
    """A number to 3 significant figures, its zeros kept (``0.0500``, ``12.0``); 100 and more whole (``1234``)."""
    return f"{x:.0f}" if abs(x) >= 99.95 else f"{x:#.3g}"


def _error_line(error: dict, skip: str | None, command: str = "tlm reference CONFIG") -> str:
    """``tlm run``'s line on the photon-map frame's error against its reference; ``command``: the
    ``tlm reference`` command that computes it."""
    if not error.get("available"):
        why = f"skipped ({skip})" if skip else "not measured"
        return f"  pmap error: {why}: no reference {error['reference']} cached; compute it with: {command}"
    rel = "n/a (black reference)" if error.get("rel_mse") is None else f"{error['rel_mse']:.4g}"
    ref = (f"{error.get('reference_rounds')} rounds, relative standard error "
           f"{error.get('reference_standard_error') or 0.0:.4f}")
    if not error.get("reference_converged"):
        ref += ", NOT converged"
    if error.get("reference_seconds") is not None:
        ref += f", computed now in {error['reference_seconds']:.1f} s"
    line = f"  pmap error against reference {error['reference']}: relative MSE {rel}, RMSE {error['rmse']:.4g} ({ref})"
    if error.get("difference_image"):
        line += f"; {error['difference_image']}"
    return line
