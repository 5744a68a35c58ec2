"""Error against cost of the photon-map filters: one row per (filter, photons, radius, k).

An experiment file names a base run config and a union of grids over dotted config
keys; every point renders the photon-map frame of the base scene and records its
error against the converged reference (:mod:`tlm.experiments.reference`) beside its
cost. The reference is found as ``tlm reference`` finds it (:func:`study_reference`):
the cached one when it meets the base's ``reference.tolerance``, else computed first
with the base's reference settings (a line says so first, as ``tlm run`` says it) and
cached (where the cache cannot take it, kept where ``tlm reference`` keeps it,
``<tmp>/tlm-cache-<uid>``, with one line that says so, and the study goes on). One that still misses the tolerance
(``reference.max_rounds`` reached) is used all the same, with a warning, and every
row's ``reference_converged`` (and ``reference.json``'s) is false. "Meets" is judged against the
base's ``reference.tolerance`` and ``min_rounds`` (:func:`meets_tolerance`: its error and rounds),
not by the ``converged`` flag of the run that computed it, which ``reference.json`` keeps as it
is: one that missed a stricter tolerance but meets the base's is used, converged. The cost: the
gather's work (node visits, leaves visited, photons tested and accepted), host seconds
(photon tracing and gathering, one-off work excluded: below) and the simulated time of the whole
photon-map frame. That frame is what ``tlm run``
simulates in pmap mode: the passes the planner runs (ray cast, and reflect and refract
when the scene has mirrors or glass), the point's photon trace (its work and photon
tree) and its photon-map pass, through the timing model (:func:`tlm.arch.model.simulate`
under the point's ``arch`` settings, without a trace; a point whose photon pass the
planner leaves out, e.g. ``photons.count: 0``, simulates the other passes). The row gets its
``throughput_cycles`` and ``latency_cycles``, ``frame_seconds`` (throughput cycles /
``arch.clock_hz``), ``fps`` and ``simulate_seconds`` (host seconds of the simulation).

A row's radii are those its photon-map pass gathered with (:func:`~tlm.render.pmap.gathered_radii`),
in scene units: ``radius`` the indirect light's, the indirect map's, or under final gathering
(``final_gather`` > 0) the global map's, where the final-gather rays land (``estimate.radius`` or
``radius_fraction`` when given, else the density rule with ``estimate.final_gather_photons``);
``caustic_radius`` the caustic map's. Not the indirect map's under final gathering: that map is
built but not gathered, and its radius (``estimate.radius_photons``) is not computed. Each is empty
where its map is not gathered (it holds no photon) or the filter takes no radius (``knn``).
``radius_rule`` and ``caustic_radius_rule`` (the last columns) say the rule that gave each, in the
words of a run's ``results.json`` (:func:`radius_rule_used`): ``radius``, ``fraction``, ``density``,
or ``fallback`` where the density rule's map was too small to measure; empty where its radius is.

The scene, its BSP and the eye rays are the base's, cast once: a point may not vary
``scene``, ``mode`` (every point is a photon-map frame), ``resolution``, ``bsp.*`` or
``render.spp`` (:data:`FIXED`), nor what the reference depends on, nor how it is found or
computed (``reference.tolerance``, ``min_rounds``, ``max_rounds`` and ``spp``: every point is
measured against the base's reference), nor ``reference.auto`` and ``render.exposure``, which
change nothing in the rows (all refused, naming the point's key, before any work); a base that
gives a ``mode`` other than ``pmap`` is refused
too (:func:`load_experiment`), not run as a photon-map frame unsaid. The other passes' work
is computed once per setting of
what it depends on (everything but ``photons``, ``estimate`` and ``arch``); each photon
map (one per photon count, seed and tracing setting) is traced once and shared by every
filter, radius and k that uses it. A row's ``factors`` names the point's own settings
(``photons.count=30000; estimate.filter=disk``).

Host seconds: a row's ``trace_seconds`` is its photon maps' making: their trace, their leaf
order (which every gather reads) and the density radii the point's gathers ask for; made
once, each is counted in full by every row that uses it (the same trace seconds on every row
that shares a map: its cost if run alone). ``gather_seconds`` is its photon-map pass; both with
the kernels warm. What a process pays once, whichever point first needs it, is charged to no
row: numba compiling the kernels (or loading them from its on-disk cache), the first imports
of the modules they use, and the eye paths' walks through mirrors and glass to the gather
points (computed once per render setting for the base's eye rays, as the ray cast is).
Before its first row, each setting of what selects the kernels (:func:`warm_key`: the filter,
final gathering, the caustic group and a density rule each on or off, the aim, the render
settings; not photon counts, radii, ``k`` or seeds) is warmed up (:class:`WarmUp`: a trace of
at most :data:`WARM_PHOTONS` photons gathered at :data:`WARM_PIXELS` pixels, and the walks of
the whole image), untimed; numba compilation and first imports that still fall inside a row's timed work
(what its warm-up missed) are measured (:class:`~tlm.experiments.error_cost_clock.CompileClock`) and taken
out of it. Each row's ``one_off_seconds`` is what was excluded on its account: the seconds in which numba
compiled or loaded a kernel, or a module was imported for the first time, during its warm-up and its
timed trace and gather, and the walks' seconds where its warm-up made them. The warm-ups' own small
traces and gathers are no row's work and are in no column; nor is what the study does before
its first row (the reference, the eye rays' cast).

File format::

    base: {scene: cornell, seed: 0}        # a run config (see 'tlm params')
    points:                                # a list of grids, each a product
      - {estimate.filter: [disk, mvoxel], photons.count: [30000, 120000],
         estimate.radius_fraction: [0.01, 0.02]}
      - {estimate.filter: [kvoxel], estimate.k: [4, 8, 16], ...}

Output folder: ``rows.csv`` and ``rows.jsonl`` (one row per point, readable by
pandas; in the CSV a null of a setting's column, :data:`SETTING_COLUMNS`, is ``null``, any other
an empty cell; a row's ``cut_share``: its trace's, as ``results.json``'s ``photons.cut_share``),
``reference.json`` (the reference used: its metadata, its ``photons`` a round, ``k_nearest`` and
``rounds`` among them, its ``resolution`` [width, height], ``reference_converged``
and whether it was ``computed`` by this study; ``reference_black`` and ``truth_black``, where the reference or
the ground truth is black and no relative error can be measured; and the study's ``warnings``, each line it
said once, which ``tlm report`` lists in its warnings box), ``config.resolved.yaml`` and
``provenance.json`` (versions, git revision, host seconds).
"""

from __future__ import annotations

import itertools
import json
import math
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from tlm.arch.functional import TreeWork
from tlm.arch.model import simulate
from tlm.caches import cached_image
from tlm.config import RunConfig, apply_overrides, config_from_dict, file_folder, to_dict
from tlm.config_words import sets_nothing, value_text, with_overrides
from tlm.errors import EnvironmentFailure, InputError, shell_word
from tlm.experiments.error_cost_blur import StudyBlur
from tlm.experiments.error_cost_clock import CompileClock
from tlm.experiments.error_cost_frame import frame_functional, frame_time
from tlm.experiments.error_cost_frame import others_key as _others_key
from tlm.experiments.error_cost_frame import own_passes as _own_passes
from tlm.experiments.error_cost_truth import Truth, black_lines, truth_error, truth_noise_words
from tlm.experiments.loading import cast_image, load_frame
from tlm.experiments.photon_warnings import study_cut_said
from tlm.experiments.reference import compute_reference, image_error, reference_key
from tlm.experiments.reference_cache import (
    ReferenceSettings,
    computing_line,
    kept_back,
    kept_root,
    load_reference,
    meets_tolerance,
    save_reference,
    store_reference,
    verdict,
)
from tlm.experiments.run import programs_for
from tlm.experiments.study import override_key, read_study, refuse_own_keys, refuse_set, run_study, with_set
from tlm.experiments.sweep_factors import given_once
from tlm.experiments.sweep_factors import keys_given as _keys_given
from tlm.experiments.sweep_rows import csv_text
from tlm.kernels.work import GATHER_KEYS
from tlm.registry import ESTIMATORS
from tlm.render.checks import camera_warnings
from tlm.render.frame import Frame, GBuffer, cast
from tlm.render.passes import gather_points_full, sees_a_light
from tlm.render.planner import photon_count, same_frame_settings, uses_radius
from tlm.render.pmap import (
    density_requests,
    gathered_maps,
    gathered_radii,
    map_radius_used,
    pmap_pass,
    trace_photon_map,
)
from tlm.storage import check_destination, warn

COLUMNS = (
    "point", "factors", "filter", "photons", "stored", "radius", "caustic_radius", "radius_fraction", "k",
    "k_nearest", "cone_k", "final_gather", "caustic_photons", "aim",
    "rmse", "rel_mse", "reference_converged", "truth_rmse", "truth_rel_mse", "truth_flip", "truth_spp",
    *(k for k in GATHER_KEYS[1:] if k != "photons_weighted"), "gathers",
    "trace_seconds", "gather_seconds", "one_off_seconds",
    "throughput_cycles", "latency_cycles", "frame_seconds", "fps", "simulate_seconds",
    "radius_rule", "caustic_radius_rule",  # (appended: the columns before keep their places)
    "photons_weighted",  # (the accepted photons whose weight the filter computed: appended too)
    "cut_share",  # (the share of the light photons.max_bounces cut, results.json photons.cut_share: appended, h529)
)
# the columns that hold a point's setting as its config has it: their null is the setting's value
# (estimate.radius_fraction: null, the density rule), ``null`` in rows.csv as in a sweep's sweep.csv; any other
# column's null is a measure not taken or of no meaning for the row (no ground truth, the k of a filter that
# samples no voxels, the fps of no cycles): an empty cell. The radius_fraction of a filter that uses no radius
# (knn: :func:`tlm.render.planner.uses_radius`), or of a point that gives estimate.radius, is of no meaning too:
# null in rows.jsonl, an empty cell in rows.csv
SETTING_COLUMNS = ("filter", "radius_fraction", "cone_k", "final_gather", "aim")


# what every point shares with the base (the module's docstring): key -> what it is
FIXED = {"scene": "every point renders the base's scene", "mode": "every point is a photon-map frame",
         "resolution": "every point renders the base's resolution", "bsp": "every point traces the base's BSP",
         "render.spp": "every point shares the base's eye rays",
         # (what finds or computes the base's reference: its stopping rule, its rounds' eye rays, tlm run's auto;
         # what it depends on, reference.photons and k_nearest, is refused as such: run_error_vs_cost)
         **{f"reference.{k}": "every point is measured against the base's reference, found or computed with the "
                              "base's reference settings" for k in ("tolerance", "min_rounds", "max_rounds", "spp")},
         "reference.auto": "it changes nothing in the rows (the study finds or computes the base's reference "
                           "whatever it says: it is tlm run's)",
         "render.exposure": "it changes nothing in the rows (their errors are of the radiance, which the exposure "
                            "does not scale; the study writes no image)"}
# the keys of FIXED a point is told to leave out, not to give under base with one experiment per value
UNUSED = ("render.exposure", "reference.auto")


def _check_factor(key: str, source: str, where: str, section: str | None = None, whole: bool = True) -> None:
    """An InputError for a point key every point takes from the base (:data:`FIXED`);
    ``section``: the point gave that key's section, whole (``render: null``, which gives the section
    at its defaults, ``whole``) or as a mapping that sets the key (which merges into the base's section)."""
    why = FIXED.get("bsp" if key.startswith("bsp.") else key)
    if why is not None:
        how = (" (mode: pmap; leave it out)" if key == "mode" else "; leave it out" if key in UNUSED else
               "; set it under base, and run one experiment per value")
        if section and whole:
            how = (f" (the point's {section}: replaces the base's whole section: give {section}.<key> for what it "
                   "changes)")
        elif section:
            how = f" (the point's {section} sets it){how}"
        raise InputError(f"a point cannot vary {key}: {why}{how}", source=source, key=where)


def expand(points: Any, source: str) -> list[dict[str, Any]]:
    """The union of the grids: a list of {dotted key: value} overrides, in file order. A value a grid's
    key lists twice is refused (``points[0].photons.count: 5000 given twice``) by the check ``tlm sweep``
    refuses one with (:func:`~tlm.experiments.sweep_factors.given_once`): its rows would be one point
    measured twice."""
    if isinstance(points, dict):
        points = [points]
    if not isinstance(points, list) or not points:
        raise InputError("must be a non-empty list of grids (mappings of key: [values])", source=source,
                         key="points")
    out = []
    for i, grid in enumerate(points):
        if not isinstance(grid, dict) or not grid:
            raise InputError(f"grid {i} must be a mapping of key: [values]", source=source, key=f"points[{i}]")
        keys = list(grid)
        values = []
        for k in keys:
            _check_factor(str(k), source, f"points[{i}].{k}")
            v = grid[k]
            v = v if isinstance(v, list) else [v]
            if not v:
                raise InputError("has no values", source=source, key=f"points[{i}].{k}")
            try:  # (a value given twice: two rows of one point, refused by tlm sweep's own check, its words)
                given_once({str(k): v}, {}, source)
            except InputError as e:  # (named by the point's key, not a sweep's grid.<key>; its class kept)
                raise e.replaced(key=f"points[{i}].{k}") from None
            values.append(v)
        out.extend(dict(zip(keys, combo, strict=True)) for combo in itertools.product(*values))
    return out


def _override_strings(point: dict[str, Any]) -> list[str]:
    return [f"{k}={json.dumps(v)}" for k, v in point.items()]


def load_experiment(path: Path, overrides: tuple[str, ...] = (), warned=None,
                    via: str = "--set") -> tuple[dict, list[dict], Path]:
    """``(base, points, folder)`` of the experiment file ``path``, every point checked before
    any work. A base that sets a ``mode`` other than ``pmap`` is refused (InputError naming
    ``base.mode``): every point is a photon-map frame, which the base's mode would not be.
    ``overrides``: ``tlm error-vs-cost --set`` strings, applied to the base as ``tlm run --set``
    applies them (a key a point varies refused: the point's value would win unsaid; ``mode``
    other than ``pmap`` too), in every point's config. ``warned``: called, once every point is
    checked, with a line for each ``--set`` and each points value that sets nothing (a section's
    mapping that names no key, ``--set render={}``, ``render: [{}]``, merges into the base's:
    :func:`empty_lines`; ``via``: what those lines call the overrides)."""
    overrides = tuple(overrides)  # (read twice: an iterator's, once; h455)
    raw, base, src = read_study(path, ("points",), overrides)
    points = expand(raw.get("points"), src)
    base_cfg = config_from_dict(base, src)  # (a mode that is no mode is refused here, as by tlm run)
    if "mode" in base and base_cfg.mode != "pmap":
        raise InputError(f"{base_cfg.mode!r}: error-vs-cost measures the photon map, and every point is a photon-map "
                         "frame (mode: pmap): give mode: pmap, or leave it out", source=src, key="base.mode")
    folder = file_folder(path)  # (a pipe's, <(...): the working folder, as its paths were typed)
    label = src  # (what a point's config is named by in its errors)
    if overrides:
        base = with_set(base, overrides, [folder])
        refuse_own_keys(overrides, ("points",), src)
        varied: dict[str, str] = {}  # each key a point sets, by the first grid that does (a section's mapping:
        for i, grid in enumerate(_grids(raw.get("points"))):  # the keys it names, as it merges into the section)
            for k, v in grid.items():
                for leaf in _keys_given(str(k), v if isinstance(v, list) else [v]):
                    varied.setdefault(leaf, f"varied by the study's points (points[{i}].{k}): change its values in "
                                            "the experiment file, not by --set")
        refuse_set(overrides, varied, src)
        label = with_overrides(src)
        base_cfg = config_from_dict(base, label)
        if "mode" in base and base_cfg.mode != "pmap":  # (a --set's: the file's was checked above)
            item = next(o for o in reversed(overrides) if override_key(o) == "mode")
            raise InputError(f"{base_cfg.mode!r}: error-vs-cost measures the photon map, and every point is a "
                             "photon-map frame (mode: pmap): leave --set mode out", source=src,
                             key=f"--set {item.strip()}")
    shared = _fixed(base_cfg)
    first: dict[str, dict] = {}  # each point's whole config -> the first point that gives it
    for p in points:  # check every point before any work starts
        cfg = config_from_dict(apply_overrides(base, _override_strings(p)), f"{label} (point {p})")
        for key, value in _fixed(cfg).items():  # (a section given, render: {spp: 1} or render: null, caught here)
            if value != shared[key]:
                given = next((k for k in p if k == key or key.startswith(f"{k}.")), None)
                _check_factor(key, src, f"points: {p}", section=given if given not in (None, key) else None,
                              whole=not isinstance(p.get(given), dict))
        other = first.setdefault(json.dumps(to_dict(cfg), sort_keys=True, default=str), p)
        if other is not p:  # (two grids that list one point, or two points that give one config: as tlm sweep)
            both = f"{{{factors_text(p)}}} given twice" if other == p else \
                f"{{{factors_text(other)}}} and {{{factors_text(p)}}} are one point (one config)"
            raise InputError(f"{both}: its rows would be one measurement written twice; list it once",
                             source=src, key="points")
    for line in empty_lines(raw.get("points"), overrides, src, via) if warned is not None else ():
        warned(line)
    return base, points, folder


def empty_lines(points: Any, overrides: tuple[str, ...], source: str, via: str = "--set") -> list[str]:
    """A line for each ``--set`` (:func:`~tlm.experiments.run_warnings.empty_sets`, as ``tlm run`` says
    it) and each value of a grid of ``points`` (``points[0].render: the value {} ...``, as ``tlm sweep``
    says a factor's) that gives a section a mapping naming no key: it merges into the base's section,
    so it sets nothing (:func:`~tlm.config_words.sets_nothing`); a line given twice, once."""
    from tlm.experiments.run_warnings import empty_sets

    lines = empty_sets(overrides, via)  # (via: what the lines call the overrides, "the overrides" in the API's)
    for i, grid in enumerate(_grids(points)):
        for k, values in grid.items():
            base = f"its points have the base's {k}"
            lines += [f"{source}: points[{i}].{k}: the value {value_text(v)} {sets_nothing('a value null', base)}"
                      for v in (values if isinstance(values, list) else [values]) if not _keys_given(str(k), [v])]
    return list(dict.fromkeys(lines))


def _grids(points: Any) -> list[dict]:
    """The grids of a file's ``points`` (checked by :func:`expand`): a list of them, or one."""
    return [points] if isinstance(points, dict) else list(points)


def _fixed(cfg: RunConfig) -> dict[str, Any]:
    """The settings of :data:`FIXED` of a resolved config (the mode as the study runs it)."""
    return {"scene": cfg.scene, "resolution": cfg.resolution, "bsp": cfg.bsp,
            **{k: getattr(getattr(cfg, k.split(".")[0]), k.split(".")[1]) for k in FIXED if "." in k}}


def run_error_vs_cost(path: Path, out: Path, progress=None, truth: Truth | None = None, note=None,
                      overrides: tuple[str, ...] = (), warned=None, via: str = "--set") -> list[dict]:
    """Run every point of the experiment file ``path``; write the rows into ``out``.

    Each row measures the point's photon-map frame against our converged reference
    (``rmse``, ``rel_mse``: the estimator's error at this photon path model) and its whole
    composite (every planned frame) against the independent ground truth (``truth_*``:
    Mitsuba's path tracer, so bias of the model shows as well as noise), when there is
    one. ``note`` receives one-line messages (the reference or the ground truth computed, or no
    ground truth); ``warned`` each warning line, in place of stderr (None: printed there; the reference not
    converged, or not cached: :func:`study_warning`; a ``--set`` or points value that sets nothing,
    ``render={}``, before any work: :func:`empty_lines`, naming the overrides ``via``; the frame's camera that
    faces nothing; a black reference or ground truth, :func:`black_lines`; a truth of few samples; once the points
    ran, those whose photon paths photons.max_bounces cut with over 5% of the light in flight (their ``cut_share``:
    :func:`~tlm.experiments.photon_warnings.study_cut_line`), and those measured against a reference much blurrier
    than their photons, :class:`StudyBlur`). Those lines,
    each once, are kept in ``reference.json``'s ``warnings``, which the report lists (h417).
    ``overrides``: ``tlm error-vs-cost --set`` strings, applied to the base (:func:`load_experiment`);
    ``config.resolved.yaml`` holds their values, ``provenance.json`` lists them.
    """
    truth = Truth() if truth is None else truth
    if not isinstance(truth.spp, int) or isinstance(truth.spp, bool) or truth.spp < 0:
        raise InputError(f"{truth.spp!r} is not a count of samples per pixel (0: no ground truth)", key="--truth-spp")
    start = time.perf_counter()
    overrides = tuple(str(o) for o in overrides)
    said: list[str] = []  # (each warning line, kept in reference.json's warnings, which the report lists: h417)

    def say(line: str) -> None:
        said.append(" ".join(line.split()))
        study_warning(line, warned)

    base, points, folder = load_experiment(Path(path), overrides, say, via)
    check_destination(out, "rows.jsonl")  # before any work
    cfg0 = config_from_dict({**base, "mode": "pmap"}, str(path))
    configs = [config_from_dict({**apply_overrides(base, _override_strings(p)), "mode": "pmap"}, str(path))
               for p in points]
    programs = {}  # arch.programs -> table; a bad table fails before any render
    for cfg in configs:
        if cfg.arch.programs not in programs:
            programs[cfg.arch.programs] = programs_for(cfg, folder)
    frame0 = load_frame(cfg0, folder, str(path))
    scene, accel = frame0.scene, frame0.accel
    g = cast_image(frame0)
    # the frame's camera that faces nothing, as tlm run says it (why its reference is black: h417); not its other
    # lines (a camera inside a closed mesh, the furnace's by design: 'tlm run' of the base says them)
    for line in camera_warnings(g.origin.shape[0], int((g.triangle >= 0).sum()), 0):
        say(f"error-vs-cost: {line}")

    settings = ReferenceSettings.from_config(scene, cfg0)
    key = reference_key(scene, cfg0, settings)
    for point, cfg in zip(points, configs, strict=True):  # (before any work: the reference's too)
        if reference_key(scene, cfg, ReferenceSettings.from_config(scene, cfg)) != key:
            raise InputError("the point changes what the reference depends on (photons.max_bounces, the "
                             "render's specular depths and Fresnel settings, reference.photons, reference.k_nearest): "
                             "every point is measured against the base's reference; run one experiment per value",
                             source=str(path), key=f"points: {point}")
    reference, ref_meta, computed = study_reference(frame0, settings, key, note, say)
    converged = meets_tolerance(ref_meta, settings)
    if not converged:
        err = ref_meta.get("relative_standard_error")
        say(f"error-vs-cost: the photon-map reference {key} is NOT converged: relative standard error "
                      f"{'n/a' if err is None else f'{err:.4f}'} after {ref_meta.get('rounds')} rounds, above the "
                      f"base's reference.tolerance {settings.tolerance}; every row's rmse and rel_mse include its "
                      "noise (reference_converged: false in the rows and reference.json); raise the base's "
                      "reference.max_rounds (or reference.tolerance)")
    reference = reference.reshape(-1, 3)
    truth_image, truth_meta = truth.load(frame0, g, note)
    keep = None
    if truth_image is not None:
        from tlm.oracle.mitsuba import truth_mask

        keep = truth_mask(frame0, sees_a_light(frame0, g).reshape(truth_image.shape[:2]))  # (h472: a pixel's square)
        truth_meta["pixels_compared"] = float(keep.mean())
    if not truth_meta["available"] and note is not None:
        note(f"no ground truth: {truth_meta['reason']}; the truth_* columns are empty")
    elif truth_meta["available"] and truth_noise_words(truth.spp):  # (its noise in every truth_* error)
        words = truth_noise_words(truth.spp)
        say(f"error-vs-cost: {words[0].lower()}{words[1:]}")
    black = {"reference_black": not np.any(reference),  # (no rel_mse can be measured: the report says so, h417)
             "truth_black": truth_image is not None and not np.any(truth_image > 0)}
    for line in black_lines(reference, truth_image, key):  # (a column empty in every row: said, h394)
        say(f"error-vs-cost: {line}")

    maps: dict[tuple, tuple] = {}  # map key -> (the trace, its seconds without compilation)
    density_s: dict[tuple, float] = {}  # (id of a map in maps, k) -> seconds of its density radius
    others: dict[str, dict] = {}  # the non-photon passes' work, per setting they depend on
    geometry = TreeWork.of(accel.tree)
    clock = CompileClock()
    warm = WarmUp(frame0, g, clock)
    dominated: list[int] = []  # (the point whose truth error one pixel carried: said for the first alone)
    blur = StudyBlur(scene.photons, key, off=black["reference_black"])  # (its points' blur line, once: h483)

    def one(item: tuple[int, dict, RunConfig], _folder: Path) -> dict:
        i, point, cfg = item
        n = photon_count(scene, cfg)
        map_key = (n, cfg.seed, cfg.photons.max_bounces, cfg.photons.russian_roulette,
                   cfg.photons.caustic_fraction, cfg.photons.caustic_count, cfg.photons.aim,
                   cfg.photons.aim_triangles, cfg.estimate.final_gather > 0, cfg.photons.levels,
                   cfg.photons.leaf_photons,  # the whole cache section (pairs 2, 3 and 4: one trace)
                   replace(cfg.cache, pairs=same_frame_settings(cfg).get("cache.pairs", cfg.cache.pairs)))
        one_off = warm(cfg)  # (untimed: what the point's settings are the first to need, its one-off part)
        frame = Frame.create(scene, accel, cfg)
        if map_key not in maps:  # (the trace, and the maps in the leaf order every gather reads them in)
            t0 = time.perf_counter()
            traced = trace_photon_map(frame)
            for m in gathered_maps(frame, traced.photons).values():
                m.prepared()
            t1 = time.perf_counter()
            once = clock.within(t0, t1)
            one_off += once
            maps[map_key] = (traced, t1 - t0 - once)
        traced, trace_s = maps[map_key]
        blur.add(i, factors_text(point), cfg, traced.photons)
        for m, k in density_requests(frame, traced.photons, gathered_only=True):  # (each one its gathers use)
            if (id(m), k) not in density_s:  # (made once; counted by every point that asks for it)
                t0 = time.perf_counter()
                m.density_radius(k)
                t1 = time.perf_counter()
                once = clock.within(t0, t1)
                one_off += once
                density_s[(id(m), k)] = t1 - t0 - once
            trace_s += density_s[(id(m), k)]
        t0 = time.perf_counter()
        radiance, work = pmap_pass(frame, g, traced.photons)
        t1 = time.perf_counter()
        once = clock.within(t0, t1)
        one_off += once
        gather_s = t1 - t0 - once  # (with final gathering: its rays too)
        fg_work = g.memo.pop("fgather_work", None)
        fn = frame_functional(frame, g, geometry, others, traced, work, fg_work)
        rest = others[_others_key(frame.cfg, _own_passes(fn.passes))]
        composite = sum((rad for rad, _ in rest.values()), np.zeros_like(radiance)) + radiance
        if truth_image is not None and not dominated:  # (one pixel carrying the truth error: said once, h472)
            from tlm.oracle.mitsuba import dominant_pixel

            line = dominant_pixel(composite.reshape(truth_image.shape), truth_image, keep)
            if line is not None:
                dominated.append(i)
                say(f"error-vs-cost: point {i}: {line}")
        t0 = time.perf_counter()
        tm = simulate(fn, programs[cfg.arch.programs], replace(cfg.arch, trace=False))
        simulate_s = time.perf_counter() - t0
        est = cfg.estimate
        used = ESTIMATORS[est.filter].uses_radius  # (knn: no radius, so radius_fraction does nothing: null)
        radii = gathered_radii(frame, traced.photons) if used else {}
        indirect = next((m for m in ("global", "indirect", "photons") if m in radii), None)  # (the indirect light's)
        row = {
            "point": i, "factors": factors_text(point),
            "filter": est.filter, "photons": n, "stored": traced.photons.n,
            "radius": radii.get(indirect),
            "caustic_radius": radii.get("caustic"),
            # (an explicit estimate.radius comes first: the fraction does nothing then, as under knn)
            "radius_fraction": est.radius_fraction if used and est.radius is None else None,
            "k": est.k if est.filter == "kvoxel" else None,
            "k_nearest": est.k_nearest if est.filter == "knn" else None, "cone_k": est.cone_k,
            "final_gather": est.final_gather, "caustic_photons": _caustic_photons(cfg, n),
            "aim": cfg.photons.aim,
            **image_error(radiance, reference), "reference_converged": converged,
            **truth_error(composite, truth_image, keep, flip="flip_missing" not in truth_meta),
            "truth_spp": truth.spp if truth_image is not None else None,
            **{k: int(work[k].sum()) for k in GATHER_KEYS},
            "trace_seconds": round(trace_s, 4), "gather_seconds": round(gather_s, 4),
            "one_off_seconds": round(one_off, 4),
            **frame_time(tm.cycles, cfg.arch.clock_hz), "simulate_seconds": round(simulate_s, 4),
            **{f"{col}_rule": radius_rule_used(frame, traced.photons, name) if name in radii else None
               for col, name in (("radius", indirect), ("caustic_radius", "caustic"))},
            "cut_share": traced.photons.cut_share,  # (its trace's, as results.json's photons.cut_share: h529)
        }
        if progress is not None:
            progress(i, len(points), row)
        return row
    given = {i for i, c in enumerate(configs) if c.estimate.radius is not None}  # (estimate.radius: rows.csv)
    with clock.running():
        return run_study(str(path), out, "rows",
                         [(i, p, c) for i, (p, c) in enumerate(zip(points, configs, strict=True))],
                         one, columns=COLUMNS, config=cfg0, started=start, overrides=overrides,
                         finish=lambda rows, _tmp: blur.said(say, study_cut_said(  # (a black reference: no
                             say, rows, cfg0, key, measured=not black["reference_black"])),  # error measured)
                         files=lambda rows: {"reference.json": {"key": key, **ref_meta,  # (its resolution: h507)
                                                                "resolution": [scene.camera.width, scene.camera.height],
                                                                "reference_converged": converged,
                                                                "computed": computed, **black,
                                                                "warnings": list(dict.fromkeys(said))},
                                             "truth.json": truth_meta,
                                             # (over run_study's rows.csv: a setting's null as null)
                                             "rows.csv": csv_text(_csv_rows(rows, given), COLUMNS,
                                                                  SETTING_COLUMNS)})


def _csv_rows(rows: list[dict], given: set[int] | frozenset[int] = frozenset()) -> list[dict]:
    """``rows`` as rows.csv has them: the radius_fraction of a filter that uses no radius, or of a point whose
    config gives ``estimate.radius`` (scene units; the points ``given``), is of no meaning, an empty cell (NaN, as
    :func:`~tlm.experiments.sweep_rows.csv_cell` writes it), not ``null`` (the density rule). By the point's config,
    not its ``radius_rule``, which is empty where its indirect map is not gathered (``photons.count: 0``: h437)."""
    return [{**r, "radius_fraction": math.nan} if r.get("radius_fraction") is None and (
        not uses_radius(str(r["filter"])) or r.get("point") in given) else r for r in rows]


def radius_rule_used(frame: Frame, photons, name: str) -> str:
    """The rule that gave the radius the photon-map pass gathered the map ``name`` of
    :func:`~tlm.render.pmap.gathered_maps` with (a row's ``radius_rule``, ``caustic_radius_rule``),
    in the words of ``results.json``'s ``*_rule`` (:func:`tlm.render.pmap.radii`): ``radius`` (the
    scene units given), ``fraction`` (of the diagonal), ``density`` (holds about k photons), or
    ``fallback`` where the density rule's map was too small to measure. Its density radius is the
    one the row's gather made (a map keeps it): nothing is computed again. The photon map's own
    rule (:func:`~tlm.render.pmap.map_radius_used`, the one source of a radius and its rule)."""
    return map_radius_used(frame, photons, name)[1]


# the warm-up of a point's settings (:class:`WarmUp`): its photon trace of at most this many photons
# (and caustic photons), gathered at this many of the image's pixels, spread over it
WARM_PHOTONS = 1000
WARM_PIXELS = 64


def warm_key(cfg: RunConfig) -> str:
    """What a point's warm-up is keyed on (:class:`WarmUp`): what selects the kernels its trace
    and gather call and the code paths they take. That is its config less ``arch``,
    ``reference`` and ``seed``, with each number of its ``photons``, ``estimate`` and ``cache``
    sections told only as null, zero or more than zero (photon counts, radii, ``k``: the same
    kernels take every value; a zero or a null turns a map, final gathering or a density rule on
    or off). The filter, the aim and every other named or true/false setting are kept, and the
    ``render`` section whole."""
    keep = {k: v for k, v in to_dict(cfg).items() if k not in ("arch", "reference", "seed")}
    for section in ("photons", "estimate", "cache"):
        keep[section] = {k: _sign(v) for k, v in keep.get(section, {}).items()}
    return json.dumps(keep, sort_keys=True, default=str)


def _sign(v: Any) -> Any:
    """A number as null, zero or more than zero (``"0"``, ``"+"``; the sections :func:`warm_key`
    reads hold none below zero); any other value as it is."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return v
    return "0" if v == 0 else "+"


class WarmUp:
    """Runs each distinct setting's one-off work before its first row is timed (a setting:
    :func:`warm_key`, so rows that differ only in photon counts, radii or seeds share one): a
    photon trace and photon-map pass at a small size (:data:`WARM_PHOTONS` photons, gathered at
    :data:`WARM_PIXELS` pixels of ``frame``'s image: numba compiles or loads the kernels they
    call, and the modules they import are imported) and the walks of the whole image's eye paths
    through mirrors and glass (``g``'s, kept in ``g.memo``, which every row's gather reads; once
    per ``render`` setting). Calling it with a config returns the one-off seconds it took: the
    compilation and first imports within it (``clock``, :meth:`CompileClock.within`) and the
    walks; 0 for a setting warmed up before. Its own small trace and gather are one-off for
    no one: their seconds are in no row's columns."""

    def __init__(self, frame: Frame, g: GBuffer, clock: CompileClock):
        self.frame, self.g, self.clock = frame, g, clock
        cam = frame.scene.camera
        pixels = np.unique(np.linspace(0, cam.width * cam.height - 1, min(WARM_PIXELS, cam.width * cam.height))
                           .astype(np.int64))
        self.pixels = pixels
        self.small: GBuffer | None = None  # (cast at the first warm-up)
        self.done: set[str] = set()  # the settings warmed up (warm_key)
        self.walked: set[str] = set()  # the render settings whose walks g.memo holds
        self.walk_seconds = 0.0  # the walks' seconds, less the compilation and imports within them

    def __call__(self, cfg: RunConfig) -> float:
        key = warm_key(cfg)
        if key in self.done:
            return 0.0
        t0 = time.perf_counter()
        walks = 0.0
        scene, accel = self.frame.scene, self.frame.accel
        if self.small is None:
            self.small = cast(self.frame, self.pixels)
        ph = cfg.photons
        small = replace(cfg, photons=replace(ph, count=min(photon_count(scene, cfg), WARM_PHOTONS),
                                             caustic_count=None if ph.caustic_count is None
                                             else min(ph.caustic_count, WARM_PHOTONS)))
        frame = Frame.create(scene, accel, small)
        pmap_pass(frame, self.small, trace_photon_map(frame).photons)
        self.small.memo.pop("fgather_work", None)
        render = json.dumps(to_dict(cfg)["render"], sort_keys=True, default=str)  # (what the walks depend on)
        if render not in self.walked:
            w0 = time.perf_counter()
            gather_points_full(Frame.create(scene, accel, cfg), self.g)  # (the walks, kept in g.memo)
            w1 = time.perf_counter()
            walks = w1 - w0 - self.clock.within(w0, w1)
            self.walk_seconds += walks
            self.walked.add(render)
        self.done.add(key)
        return self.clock.within(t0, time.perf_counter()) + walks


def study_reference(frame: Frame, settings: ReferenceSettings, key: str,
                    note=None, warned=None) -> tuple[np.ndarray, dict, bool]:
    """The reference the study measures against, as ``tlm reference`` gets it: the cached
    one when it meets the base's ``reference.tolerance`` (:func:`meets_tolerance`), else
    computed now with the base's settings and cached where it is better (``note`` says so before the
    rounds start: none cached, or the cached one computed again).
    A cached one that misses the tolerance is kept where computing it again with the base's settings
    would only repeat the same rounds (fixed seeds) to the same image
    (:func:`~tlm.experiments.reference_cache.repeats`: the base's own stopping rule,
    :data:`~tlm.experiments.reference_cache.RULE`, or one that stops it at the same round, as
    ``tlm reference`` keeps it); so is one with more rounds than the base's
    ``reference.max_rounds`` (:func:`~tlm.experiments.reference_cache.fewer_rounds`; ``note`` says so).
    One computed now replaces the cached one only where it is better, else the study uses the
    cached one and ``note`` says which and why
    (:func:`~tlm.experiments.reference_cache.store_reference`). One computed now that the cache cannot
    take is not lost (:func:`_uncached_reference`; ``warned`` gets its warning line too). Returns the
    image, its metadata and whether it was computed now (False: the cached one is used)."""
    found = load_reference(key)
    if found is None and note is not None:  # (as tlm run says it: the rounds may take minutes)
        note(computing_line(key, settings, "every study and run of this scene"))
    kind = "meets" if found is None else verdict(found[1], settings)
    if kind == "fewer" and note is not None:
        note(kept_back(key, found[1], settings, "the base's ", force=False))
    elif kind == "compute":
        if note is not None:
            note(f"reference {key} is cached but does not meet tolerance {settings.tolerance}: computing it "
                 "again with the base's reference settings")
        found = None
    if found is not None:
        return found[0], found[1], False
    cam = frame.scene.camera
    image, meta = compute_reference(frame, None, settings, key=key, say=note)  # (resumes an interrupted one)
    image = image.reshape(cam.height, cam.width, 3)
    try:
        stored = store_reference(key, image, meta, settings)
    except (EnvironmentFailure, OSError, InputError) as e:  # (a cache that cannot take it: the study goes on)
        return *_uncached_reference(key, image, meta, e, warned), True
    if not stored.replaced:
        if note is not None:
            note(f"{stored.line}; the study uses the cached one")
        return stored.image, stored.meta, False
    found = load_reference(key)
    return found[0], found[1], True


def _uncached_reference(key: str, image: np.ndarray, meta: dict, error: BaseException,
                        warned=None) -> tuple[np.ndarray, dict]:
    """The reference ``key`` the cache could not take (``error``), kept as ``tlm reference``
    keeps it (in :func:`~tlm.experiments.reference_cache.kept_root`, which ``TLM_CACHE`` set to it
    reads), with one warning line that says where (:func:`study_warning`); used by this study only,
    and said so, where that cannot be written either. The image as a cached one reads back
    (float32), and its metadata."""
    why = " ".join(str(error).split())
    root = kept_root()
    try:
        folder = save_reference(key, image, meta, root / "references")
    except (EnvironmentFailure, OSError, InputError) as e:
        study_warning(f"reference {key}: not cached ({why}), nor kept in {root} ({' '.join(str(e).split())}): "
                      "used by this study only", warned)
    else:
        study_warning(f"reference {key}: not cached ({why}): kept in {folder} instead, which later runs read with "
                      f"TLM_CACHE={shell_word(str(root))}", warned)
        kept = cached_image(folder, "reference.npy", key, "reference", "the next study computes it again")
        if kept is not None:  # (what a later run reads from there: reference.json the same as a cached one's)
            return kept
    return image.astype(np.float32), {"key": key, **meta}


def study_warning(message: str, warned=None) -> None:
    """A warning of the study: given to ``warned`` as one line, or where that is None said on stderr
    (:func:`tlm.storage.warn`, ``tlm: warning: ...``); not both (:func:`tlm.api.error_vs_cost` returns them,
    printing none, as :func:`tlm.api.granularity` does; ``tlm error-vs-cost`` prints each once)."""
    if warned is None:
        warn(message)
    else:
        warned(" ".join(message.split()))


def factors_text(point: dict[str, Any]) -> str:
    """A row's ``factors``: the point's own settings, ``key=value`` joined by ``; ``."""
    return "; ".join(f"{k}={v if isinstance(v, str) else json.dumps(v)}" for k, v in point.items())


def _caustic_photons(cfg: RunConfig, n: int) -> int:
    """The caustic group's photon budget: ``photons.caustic_count``, else ``caustic_fraction`` x the count
    (as the trace splits it; 0 in a scene without mirrors or glass, which has no caustic group)."""
    return cfg.photons.caustic_count if cfg.photons.caustic_count is not None else round(
        n * cfg.photons.caustic_fraction)
