"""tlm's Python API: what the ``tlm`` command does, as functions that return data.

Every ``tlm`` subcommand is a call of this module (``tlm/cli.py`` only parses the
arguments and prints what these return), and a notebook uses the same calls (the
walkthrough: docs/api.md)::

    import tlm

    cfg = tlm.load_config("cornell", {"resolution": [64, 64]})  # a built-in experiment, or a YAML file
    res = tlm.render_image(cfg)                  # images, AOVs and work counts
    timing = tlm.simulate(res)                   # the timing model under cfg's arch
    wider = tlm.simulate(res, {"pipelines": 4})  # the same work on other hardware
    rows = tlm.sweep("sweep_fifo", "runs/fifo")  # a pandas DataFrame

A study (:func:`sweep`, :func:`thesis`, :func:`error_vs_cost`, ...) takes its experiment
file's path or a built-in experiment's name (``tlm config list``), as its ``tlm`` command
does (:func:`experiment_path`). The studies and the reports are written in
:mod:`tlm.api_studies`, the scenes' functions in :mod:`tlm.api_scenes`, the caches' in
:mod:`tlm.api_cache` and the configs' (:func:`load_config`, :class:`Config`) in :mod:`tlm.api_config` (what
they share with this module: :mod:`tlm.api_common`), and read from
here as every name of the API does: ``tlm.api.sweep`` is ``tlm.api_studies.sweep``.

Bad input of any kind raises :class:`InputError`, whose message names the file, the
key and the value (``tlm`` prints it on one line and exits with status 2); a timing
model that cannot finish raises :class:`Deadlock` (:class:`MaxEventsReached` when it stopped at
``arch.max_events``).

The heavy layers (the kernels, the timing model, the report) are imported when a
function first needs them, so that importing tlm, and every ``tlm`` command, stays fast.
A Ctrl-C (SIGINT) that arrives while one of those imports runs (numba, scipy, ... in the first
render of a session) is held until that import is complete, then raised as the
KeyboardInterrupt it would have been (:func:`tlm.whole_imports.imports_whole`): Python does not undo a
half-finished import, and a package left half-imported fails in every later call of the
process.
"""

from __future__ import annotations

import json
import math
import numbers
import os
from collections.abc import Callable, Iterable, Mapping
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tlm.api_cache import cache_info, clear_cache, prune_cache  # tlm's caches (see the end of this module)
from tlm.api_common import (
    argument_names,
    arguments_text,
    experiment_path,  # noqa: F401  (shared with tlm.api_studies; the CLI's tlm.api.experiment_path)
    flags_are_kept,
)
from tlm.api_common import checked as _checked
from tlm.api_common import renamed as _renamed
from tlm.api_common import shown as _shown
from tlm.api_config import (  # a run config loaded and checked (see "configs" below)
    Config,
    Overrides,  # noqa: F401  (not in __all__: the overrides' types, {"render.spp": 2} or ["render.spp=2"])
    load_config,
    scene_file,
)
from tlm.api_config import override_strings as _override_strings
from tlm.api_scenes import (  # the built-in scenes; a scene loaded, shown, exported (see "scenes" below)
    export_scene,
    list_scenes,
    load_scene,
    scene_description,
    scene_info,
)
from tlm.api_studies import (  # the many experiments and the reports (see the end of this module)
    StudyRows,  # noqa: F401  (not in __all__: what error_vs_cost returns, a list of rows with attrs)
    calibrate,
    calibration_table,  # noqa: F401  (not in __all__: the CLI's tlm.api.<name>, as in_checkout, report_output)
    callback,
    error_vs_cost,
    extreme,
    granularity,
    granularity_frames,  # noqa: F401  (not in __all__: the CLI's line under tlm granularity's table)
    in_checkout,  # noqa: F401
    out_folder,
    plots,
    report_output,  # noqa: F401
    run_sweep,
    scaling,
    sweep,
    thesis,
    tlm_version,  # noqa: F401  (not in __all__: tlm --version's, the running code's version)
    version_line,  # noqa: F401  (not in __all__: tlm --version's line)
    write_calibration,
    write_report,
)
from tlm.arch.units import Deadlock, MaxEventsReached
from tlm.config import MODES, RunConfig, apply_overrides, config_from_dict, describe, to_dict
from tlm.errors import InputError, StepsFailed, did_you_mean  # (StepsFailed: what plots raises)
from tlm.experiments.dask_workers import machine_key  # noqa: F401  (not in __all__: tlm sweep's, a machine said once)
from tlm.whole_imports import imports_whole

if TYPE_CHECKING:
    import numpy as np

    from tlm.arch.costs import Programs
    from tlm.arch.model import Timing
    from tlm.config import ArchConfig
    from tlm.experiments.reference import Made
    from tlm.experiments.run import RenderResult

__all__ = [
    "MODES", "OUTPUTS", "Config", "Deadlock", "InputError", "MaxEventsReached", "StepsFailed", "cache_info",
    "calibrate", "clear_cache", "error_vs_cost", "export_scene", "extreme", "granularity", "list_scenes", "load_config",
    "load_scene", "params", "parse_outputs", "plots", "prune_cache", "reference", "render_image", "run", "run_sweep",
    "scaling", "scene_description", "scene_file", "scene_info", "simulate", "sweep", "thesis", "to_srgb",
    "write_calibration", "write_report",
]

OUTPUTS = ("aov", "radiance", "trace")  # what a run folder may leave out (tlm.experiments.run.OUTPUTS)


# ---------------------------------------------------------------- configs

# tlm/api_config.py, imported at the top of this module (``tlm.api.load_config is tlm.api_config.load_config``):
# Config, load_config and scene_file (with Overrides, the overrides' types).


@argument_names
def params() -> list[tuple[str, Any, str]]:
    """Every config parameter: (dotted key, default, meaning), as ``tlm params`` lists them; a key whose
    value a registry's names select (``estimate.filter``, ``arch.scheduler``) ends with the names it holds
    now, a plug-in's too (its entry point, or a class registered in this process)."""
    from tlm.registry import REGISTRIES

    names = {reg.setting: reg.names() for reg in REGISTRIES}
    return [(key, default, f"{text}; registered now: {', '.join(names[key])}" if key in names else text)
            for key, default, text in describe()]


def configs_dir() -> Path:
    """Where the built-in experiments are: the repository's ``configs/``, shipped inside
    the wheel as ``tlm/_configs``."""
    from tlm.builtin import configs_dir as folder

    return folder()


def list_experiments() -> list[str]:
    """The built-in experiments' names (``cornell``, ``cornell_pmap``, ``thesis``, ...: the
    files of :func:`configs_dir`), as ``tlm config list`` lists them."""
    from tlm.builtin import list_experiments as names

    return names()


def experiment_command(name: str) -> str:
    """The ``tlm`` command that runs the built-in experiment ``name`` (``run``, ``sweep``,
    ``thesis``, ``extreme``, ...)."""
    from tlm.builtin import experiment_command as command

    return command(name)


def experiment_description(name: str) -> str:
    """A built-in experiment's description (its ``description:``, else its first comment
    sentence)."""
    from tlm.builtin import experiment_description as description

    return description(name)


def export_experiment(name: str, file: str | Path) -> list[Path]:
    """Copy the built-in experiment ``name`` into ``file`` (``.yaml``) to edit it, and a
    sweep's base config beside it where it names one (``tlm config export``); returns the
    files written. A file that exists with other contents is not overwritten."""
    from tlm.builtin import export_experiment as export

    return export(name, file)


# ---------------------------------------------------------------- scenes

# tlm/api_scenes.py, imported at the top of this module (``tlm.api.load_scene is tlm.api_scenes.load_scene``):
# list_scenes, scene_description, load_scene, scene_info and export_scene.


# ---------------------------------------------------------------- one experiment


@argument_names
@imports_whole
def render_image(config: str | Path | Mapping[str, Any] | Config, *, progress: bool = False) -> RenderResult:
    """Render every frame ``config`` plans (its ``mode``) over the whole image.

    The result (a :class:`~tlm.experiments.run.RenderResult`) holds each pass's
    ``radiance`` ((H, W, 3) linear, float64) and ``work`` (pass -> count -> (H, W) int32,
    int64 for a count that does not fit),
    the ``composite``, the eye rays' ``aov`` and ``work_totals()``, the ``scene``, the
    ``plan`` (passes run and left out), the photon map (``photons``) and the photon-map
    frame's ``error`` against its cached reference.
    ``progress``: a bar on stderr when it is a terminal (True or False).
    """
    from tlm.experiments import run as runs

    progress = _checked(progress, "progress", bool)
    cfg = load_config(config)
    res = runs.render(cfg.settings, cfg.base, cfg.label, progress=progress, overrides=cfg.overrides, via=cfg.via)
    return replace(res, base=cfg.base)


@argument_names
@imports_whole
def to_srgb(radiance: Any, exposure: float | None = None) -> np.ndarray:
    """(H, W, 3) linear radiance, or a RenderResult, as (H, W, 3) uint8 sRGB, to show or save.

    A RenderResult (``tlm.to_srgb(res)``): its composite at the run's exposure, ``res.exposure``: the image
    ``tlm run`` writes as ``images/composite.png`` (``render.exposure``, else automatic over the pixels that
    do not see a light directly); a pass at the run's exposure, as ``images/<pass>.png``:
    ``tlm.to_srgb(res.radiance[pass], res.exposure)``. Radiance: scaled by ``exposure`` (default: the 99.5th
    percentile of that radiance's luminance to 1, all its pixels, lights seen directly too, so a pass or an
    image with a light in view may come out darker than a run's), clipped.
    ``exposure`` is any real number (a numpy scalar too, ``np.percentile``'s); one that is not a
    finite number >= 0, radiance that is not real numbers, or radiance with no finite value
    (nothing to expose), is an InputError: the image would be black for no reason of the scene's."""
    import sys

    import numpy as np

    from tlm.render.image import auto_exposure, to_srgb8

    run = sys.modules.get("tlm.experiments.run")  # (imported wherever a RenderResult was made)
    if run is not None and isinstance(radiance, run.RenderResult):
        res, radiance = radiance, radiance.composite  # (made once: res.exposure would make it again)
        if exposure is None:  # (the run's own: images/composite.png's pixels, whatever the radiance holds)
            return to_srgb8(radiance, run.image_exposure(res, radiance)[0])
    given, radiance = radiance, np.asarray(radiance)
    if radiance.ndim < 1 or radiance.shape[-1] != 3 or radiance.dtype.kind not in "iuf":
        what = (f"an array of shape {radiance.shape} and dtype {radiance.dtype}" if radiance.dtype != object
                or isinstance(given, np.ndarray) else _shown(given))
        raise InputError(f"{what} is not RGB radiance: give (..., 3) real numbers, as a RenderResult's "
                         "res.radiance[pass], or the RenderResult (its composite)", key="radiance")
    if exposure is not None:
        value = math.nan  # (numpy's bool is not a numbers.Real)
        if not isinstance(exposure, bool) and isinstance(exposure, numbers.Real):
            try:
                value = float(exposure)
            except OverflowError:  # (an int past float's range)
                value = math.inf
        if not math.isfinite(value) or value < 0:
            raise InputError(f"{_shown(exposure)} is not a finite number >= 0 (None: automatic)", key="exposure")
        exposure = value
    if radiance.size and not np.isfinite(radiance).any():
        raise InputError("the radiance holds no finite value (all NaN or infinite): nothing to expose",
                         key="radiance")
    scale = auto_exposure(radiance.reshape(-1, 3)) if exposure is None else exposure
    return to_srgb8(radiance, scale)


def _arch_overrides(arch: Mapping[str, Any]) -> dict[str, Any]:
    """:func:`simulate`'s ``arch`` mapping as dotted keys of the config (``pipelines`` or
    ``arch.pipelines``: ``arch.pipelines``). A key of another section (``render.spp``, ``mode``)
    is an InputError that says simulate changes the architecture only, naming the key as given;
    a key that is no setting of arch names it as given too, with the keys of arch."""
    import dataclasses

    from tlm.config import ArchConfig

    fields = [f.name for f in dataclasses.fields(ArchConfig)]
    others = [f.name for f in dataclasses.fields(RunConfig) if f.name != "arch"]
    out = {}
    for k, v in arch.items():
        if not isinstance(k, str):
            raise InputError(f"{_shown(k)} is not a key of arch: give its name, 'pipelines'", key="arch")
        name = k.removeprefix("arch.")
        head = name.split(".")[0]
        if head not in fields:
            if head in others and not k.startswith("arch."):
                raise InputError(f"{k!r} is not a key of arch: simulate takes arch keys only ({{'pipelines': 4}}) "
                                 "and times the render as it is, without rendering it again; for other settings, "
                                 "render again (tlm.render_image(cfg.updated({...})))", key="arch")
            raise InputError(f"{k!r} is not a key of arch{did_you_mean(head, fields)} (its keys: "
                             f"{', '.join(fields)})", key="arch")
        out[f"arch.{name}"] = v
    return out


@argument_names
@imports_whole
def simulate(result: RenderResult, arch: ArchConfig | Mapping[str, Any] | None = None, *,
             programs: Programs | str | Path | None = None, progress: bool = False) -> Timing:
    """The timing model's outcome for the work of ``result`` (a :func:`render_image`): cycles per
    PM, ``throughput`` and ``latency`` (``.cycles``), ``.fps``, and every unit's busy, stall
    and idle cycles (``.to_dict()``).

    ``arch``: the architecture to simulate, an :class:`~tlm.config.ArchConfig` or keys of
    ``arch`` to change (``{"pipelines": 4}``; a relative ``programs`` among them is relative
    to the working folder); default the render's own. The render is not repeated: only the
    timing model runs. ``programs``: an instruction-cost table or its path (relative to the
    working folder, and named so in an error: ``/home/me/nb/my.yaml: programs: file not found``);
    default ``arch.programs`` (relative to the config's folder). ``arch`` holds keys of ``arch``
    only: another setting (``render.spp``) would need the render again, and is an InputError
    that says so. ``progress``: True or False.

    ``.warnings``: the simulated stream's warning lines (a list; empty: none), those ``tlm run`` prints and
    ``results.json`` ``warnings`` holds after the render's (``result.warnings``) for this timing and config
    (:func:`~tlm.experiments.run_warnings.stream_warnings`): packets too coarse (the granularity caveat), images
    in flight taking turns, too few frames for a steady throughput, tiles without pixels, an arch key that
    changes nothing here. An A/B of two ``simulate`` calls reads each one's.
    """
    from tlm.arch.costs import Programs, load_programs
    from tlm.config import ArchConfig
    from tlm.experiments import run as runs
    from tlm.experiments.run_warnings import stream_warnings

    if not isinstance(result, runs.RenderResult):
        raise InputError(f"{type(result).__name__} is not a render: give what render_image returns", key="result")
    if not (arch is None or isinstance(arch, (ArchConfig, Mapping))):
        raise InputError(f"{_shown(arch)}: arch is an ArchConfig or a mapping of its keys ({{'pipelines': 2}})",
                         key="arch")
    if not (programs is None or isinstance(programs, (Programs, str, os.PathLike))):
        raise InputError(f"{_shown(programs)} is not an instruction-cost table: give its path or a Programs (None: "
                         "the config's arch.programs)", key="programs")
    progress = _checked(progress, "progress", bool)
    cfg = result.cfg
    if isinstance(arch, ArchConfig):  # (checked as the mapping is: its keys' types and ranges)
        cfg = config_from_dict({**to_dict(cfg), "arch": to_dict(arch)}, "(simulate: arch)")
    elif arch is not None:
        cfg = config_from_dict(apply_overrides(to_dict(cfg), _override_strings(_arch_overrides(arch)), cwd=Path.cwd()),
                               "(simulate: arch)")
    if isinstance(programs, Programs):
        table = programs
    elif programs is not None:  # (relative to the working folder, named as the absolute path it tried)
        path = Path(programs)
        try:
            table = load_programs(path if path.is_absolute() else Path.cwd() / path)
        except InputError as e:
            raise (_renamed(e, "programs") if e.key == "arch.programs" else e) from None
    else:
        table = runs.programs_for(cfg, result.base)
    timing = runs.simulate_run(replace(result, cfg=cfg) if cfg is not result.cfg else result, table, progress)
    # (Timing.warnings, None until here: tlm.arch.model's Timing knows no config, and the stream's warnings need it;
    # copy, deepcopy, pickle and dataclasses.replace keep it, as every field of a Timing)
    timing.warnings = stream_warnings(timing, cfg)
    return timing


@argument_names
def parse_outputs(text: str) -> tuple[str, ...]:
    """``tlm run --outputs`` (``"aov,trace"``): the optional outputs named, in :data:`OUTPUTS`
    order (``"images"``: none of them); an unknown name is an :class:`InputError` naming ``text``
    (``--outputs`` from the command line)."""
    from tlm.experiments.run import parse_outputs as parse

    try:
        return parse(text)
    except InputError as e:
        if e.key != "--outputs" or flags_are_kept():
            raise
        raise _renamed(e, "text") from None


@argument_names
@imports_whole
def run(config: str | Path | Mapping[str, Any] | Config, out: str | Path, *,
        outputs: str | Iterable[str] | None = None, progress: bool = False, reference: bool | None = None,
        say: Callable[[str], None] | None = None) -> dict:
    """Render, simulate and write the run folder ``out``, as ``tlm run`` does; returns what
    ``results.json`` holds, equal to ``json.loads`` of the file (a number that is not finite,
    which strict JSON does not have, is None there and here: the ``fps`` of no cycles to time).

    ``outputs``: which of :data:`OUTPUTS` the folder gets besides its images and
    ``results.json`` (``"aov,trace"`` or a list; ``"images"`` or ``[]``: none; default all,
    the trace only where the config's ``arch.trace`` is true; named here, the trace is
    written whatever ``arch.trace`` says, and the run's overrides record ``arch.trace=true``).
    ``progress``: the bars on stderr, the render's and a reference's rounds (when it is a
    terminal), and, with no ``say``, the lines on a reference computed now on stderr too (a
    notebook shows them: a reference may take minutes). ``reference``: compute the photon-map
    frame's reference when none is cached (True or False; default None: the config's
    ``reference.auto``); ``say`` gets a line before and after computing it (naming this call's
    arguments, ``reference=False``, where ``tlm run`` names its flags).
    A destination that is not a tlm folder, or bad input, fails before any work.
    """
    from tlm.experiments import run as runs

    progress = _checked(progress, "progress", bool)
    reference = _checked(reference, "reference", bool, none="the config's reference.auto")
    say = callback(say, "say")
    out = out_folder(out)
    cfg = load_config(config)
    if outputs is None:
        chosen = runs.OUTPUTS
    elif isinstance(outputs, str):
        chosen = runs.parse_outputs(outputs)
    else:
        names = list(outputs) if isinstance(outputs, Iterable) else [outputs]
        bad = [n for n in names if not isinstance(n, str)]
        if bad:
            raise InputError(f"{_shown(bad[0])} is not an output's name: give "
                             f"\"aov,trace\" or a list of names ({', '.join(runs.OUTPUTS)}; \"images\": none)",
                             key="outputs")
        chosen = runs.parse_outputs(",".join(names)) if names else ()
    if outputs is not None and "trace" in chosen and not cfg.arch.trace:
        cfg = cfg.updated({"arch.trace": True})  # (asked for by name: the config's arch.trace: false gives way)
    auto = cfg.settings.reference.auto if reference is None else reference
    hear = _said(say, progress)

    def named(line: str) -> None:  # (a caller in Python: reference=False, not --no-reference)
        hear(arguments_text(line, {"config", "out", "outputs", "progress", "reference", "say"}, {"progress"}))

    told = named if hear is not None and not flags_are_kept() else hear
    results = runs.run(cfg.settings, out, cfg.base, config_path=cfg.source, overrides=list(cfg.overrides), via=cfg.via,
                       outputs=chosen, progress=progress, reference=auto, say=told)
    from tlm.storage import json_text

    return json.loads(json_text(results))  # (what the file holds: inf and nan as None)


@argument_names
@imports_whole
def reference(config: str | Path | Mapping[str, Any] | Config, *, force: bool = False,
              say: Callable[[str], None] | None = None,
              progress: Callable[[int, float, float], None] | bool | None = None, bar: bool = False) -> Made:
    """The converged photon-map reference of ``config``'s scene, as ``tlm reference``
    computes it: the cached one when it meets ``reference.tolerance`` (unless ``force``),
    else computed and cached (a cached one that computing again would not better, fewer rounds
    asked for or the same rounds repeated, is kept: ``kept`` says why). Returns its ``key``,
    ``settings``, ``meta``, whether it was ``computed`` now (False where the cache's was returned),
    its ``folder`` and ``warnings``; ``say`` gets a line before computing, and the line on a cached one kept,
    ``progress`` ``(round, change, relative standard error)`` after each round (the round's number
    from 1; the two measures after each cycle of ``reference.spp`` rounds from the second, when they
    are measured, and NaN after the other rounds), ``bar`` a bar of the rounds on stderr (when it is
    a terminal). ``progress=True``, as :func:`render_image` and :func:`run` take it: that bar, and
    with no ``say``, its line before computing on stderr (a notebook shows it); ``force`` and
    ``bar``: True or False."""
    from tlm.experiments.reference import make_reference

    force = _checked(force, "force", bool)
    bar = _checked(bar, "bar", bool)
    say = callback(say, "say")
    if progress is not None and not callable(progress):
        shown = _checked(progress, "progress", bool, "True, False or a function of (round, change, relative "
                         "standard error)", none="no progress")
        bar, say, progress = bar or shown, _said(say, shown), None
    cfg = load_config(config)
    if flags_are_kept():  # (tlm reference: its lines name its flags, --force)
        return make_reference(cfg.settings, cfg.base, cfg.label, force=force, say=say, progress=progress, bar=bar,
                              overrides=cfg.overrides, via=cfg.via)
    names = {"force", "say", "progress", "bar"}

    def named(line: str) -> str:  # (a caller in Python: force=True, not --force)
        return arguments_text(line, names, {"force", "bar"})

    told = None if say is None else (lambda line: say(named(line)))
    warnings: list[str] = []  # (returned, as tlm.run's; tlm reference prints them on stderr)
    made = make_reference(cfg.settings, cfg.base, cfg.label, force=force, say=told, progress=progress, bar=bar,
                          overrides=cfg.overrides, via=cfg.via, warned=warnings.append)
    if made is not None and made.kept:
        made = replace(made, kept=named(made.kept))
    return replace(made, warnings=tuple(warnings)) if made is not None else made


def _said(say: Callable[[str], None] | None, progress: bool) -> Callable[[str], None] | None:
    """Where a long computation's lines go: ``say``; else, with ``progress`` on, stderr, as its bars
    (a notebook shows stderr, and a reference computed now may take minutes); else nowhere."""
    if say is not None or not progress:
        return say
    import sys

    def line_on_stderr(line: str) -> None:
        sys.stderr.write(f"{line}\n")
        sys.stderr.flush()

    return line_on_stderr


# ---------------------------------------------------------------- tlm's caches (tlm.cache_admin)

# tlm/api_cache.py, imported at the top of this module (``tlm.api.cache_info is tlm.api_cache.cache_info``):
# cache_info, prune_cache and clear_cache.


# ---------------------------------------------------------------- many experiments, reports

# tlm/api_studies.py, imported at the top of this module (``tlm.api.sweep is tlm.api_studies.sweep``):
# run_sweep, sweep, scaling, thesis, calibrate (with calibration_table, write_calibration and
# in_checkout), granularity, error_vs_cost and extreme; write_report, report_output and plots.
