"""The thesis's setting, and whether a cell is in it: the one rule of comparability with Tables I-III.

Tables I-III were measured on three scenes (Scene With Ring, Room Scene, Cornell Box Scene)
at one setting: each scene's 320×240 or 320×320 pixels, 20,000 to 120,000 photons, one eye
ray and one light sample per pixel, one pipeline at 600 MHz (:data:`THESIS_SIZES`,
:data:`THESIS_SAMPLING`, :data:`THESIS_CLOCK_HZ`), and every other key at the value of the
built-in ``configs/thesis.yaml`` (:func:`thesis_setting`). Which table a scene is set beside
is its file (:data:`THESIS_SCENES`: the built-in ``thesis/ring``, ``thesis/room`` and
``cornell``, or a copy of one, by its bytes; :func:`table_of`), not its name: a study's
scenes by :func:`scene_keys`. :func:`mismatches` is the one rule: that scene, that
setting, and every other key of the cell's resolved config that changes the cycles or the
image at the thesis's value (:func:`setting_mismatches`); :func:`run_mismatches` applies it
to a run folder. The summary's medians (:func:`tlm.experiments.thesis.summarize`), the
report's tables and ``tlm calibrate``'s refusal to overwrite the packaged table all follow
it: a cell of another setting measures the setting, not the model.
"""

from __future__ import annotations

import functools
import json
import math
import re
from pathlib import Path

from tlm.arch.steady import frames_cap, runs_alike
from tlm.builtin import configs_dir
from tlm.config import MODES, config_from_dict, describe, to_dict
from tlm.errors import InputError, quoted
from tlm.experiments.provenance import identities_remembered, scene_identity, scene_label
from tlm.experiments.scaling import no_effect
from tlm.experiments.study import MANIFEST, read_study
from tlm.render.planner import inert_settings, inert_timing_settings, same_frame_settings
from tlm.scenes.loader import resolve_scene_path, scenes_dir
from tlm.storage import LISTING

# The thesis's scenes: the built-in scene file of each table (configs/thesis.yaml)
THESIS_SCENES = {"ring": "thesis/ring", "room": "thesis/room", "cornell": "cornell"}
# What a thesis study writes in its folder beside a scene's DIR/<key> (tlm.experiments.study.run_study, its report)
STUDY_FILES = ("report", "thesis_comparison.csv", "thesis_comparison.jsonl", "thesis_summary.json",
               "config.resolved.yaml", "provenance.json", MANIFEST, LISTING)
# The thesis's stated sizes (Tables I-III headings; the thesis scenes' defaults):
# width, height, photons, triangles.
THESIS_SIZES = {"ring": (320, 240, 20_000, 646), "room": (320, 240, 80_000, 7812),
                "cornell": (320, 320, 120_000, 2604)}
THESIS_CLOCK_HZ = 600e6
THESIS_SAMPLING = {"spp": (1, "eye rays per pixel"), "light_samples": (1, "light samples")}  # configs/thesis.yaml
# The keys of a cell's resolved config that setting_mismatches does not judge by value: those mismatches
# judges in its own words (the scene by its file; the resolution and the photons as the run resolved them,
# a null being the scene's own), the mode (each cell's is the thesis's column), the seed (another draw of
# the same setting: the thesis's figures are no seed's) and the instruction table (arch.programs: the
# calibrated model itself, which the comparison measures, not a setting of the thesis's)
# The keys judged by setting_mismatches whose value the thesis itself gives (the help of each cites it: the BSP and
# photon trees' floor(ln n) levels, §V; twenty times the triangle list's memory; 4 cache block pairs of 1024 words;
# 12 cycles a page miss, 4 a flush; two images in flight; no final gathering; the static per-quadrant split;
# "Russian roulette method is used to eliminate photons", §III; the memory controller "swaps" the modules by
# re-routing the top two address bits and copies blocks between them, §IV.B: arch.memory swap).
# Every other key's value is configs/thesis.yaml's (or tlm's default there), which the thesis does not fix: a
# mismatch of one says so, "(configs/thesis.yaml: 256; not in the thesis)"
THESIS_FIXED = frozenset({"bsp.levels", "bsp.memory_factor", "photons.levels", "photons.leaf_photons",
                          "estimate.final_gather", "cache.pairs", "cache.block_words", "arch.images_in_flight",
                          "arch.page_miss_cycles", "arch.flush_cycles", "arch.scheduler", "photons.russian_roulette",
                          "arch.memory"})
NOT_SETTING = frozenset({"scene", "mode", "resolution", "photons.count", "render.spp", "render.light_samples",
                         "arch.pipelines", "arch.clock_hz", "seed", "arch.programs"})


def table_of(source: str | Path | None) -> str | None:
    """The table (``ring``, ``room``, ``cornell``) whose scene the scene file ``source`` is,
    judged by the file, not its name: a file with the bytes of a built-in file of
    :data:`THESIS_SCENES`, wherever it is (another checkout's, a copy; a user's
    ``cornell.yaml``, or the built-in caustic showcase ``ring``, is none). A file that is
    not on this machine (a folder written elsewhere) is judged by its place under a
    ``scenes`` folder. None: not one of the thesis's scenes."""
    if not source:
        return None
    p = Path(source)
    root = scenes_dir()
    mine = scene_identity(p) if p.is_file() else None  # (once, not once a table)
    for table, name in THESIS_SCENES.items():
        builtin = root / f"{name}.yaml"
        if mine is not None:
            if mine == scene_identity(builtin):
                return table
            continue
        tail = ("scenes", *f"{name}.yaml".split("/"))
        if p.parts[-len(tail):] == tail or p.parts[-len(tail):] == ("_scenes", *tail[1:]):
            return table
    return None


def scene_keys(scenes: list[str], folder: Path, source: str) -> dict[str, tuple[str, str | None]]:
    """Each scene of a thesis study, as listed, -> ``(key, table)``: ``table`` the thesis table whose
    scene its file is, by its bytes (:func:`table_of`: an unchanged copy ``myring.yaml`` of
    ``thesis/ring`` is ``ring``; a user's ``room.yaml``, or the built-in ``room``, none); ``key`` what
    its rows (the CSV's ``scene``), its folder ``DIR/<key>`` and the summary name it by: its table,
    else its file's stem (``bunny``), else, where another scene of the study has that, the stem and a
    number (``room-2``: a user's ``room.yaml`` beside ``thesis/room``; ``x-2``: ``b/x.yaml`` after
    ``a/x.yaml``; ``report-2``: a ``report.yaml``, whose ``DIR/report`` would be the study's report,
    :data:`STUDY_FILES`). Two scenes of one table (a copy beside the thesis's own file) are refused in one
    line (:class:`~tlm.errors.InputError`, naming ``source``'s ``scenes``)."""
    with identities_remembered():
        tables = {s: table_of(resolve_scene_path(s, folder, source, "scenes").resolve()) for s in scenes}
    first: dict[str, str] = {}
    for s, table in tables.items():
        if table is not None and table in first:
            raise InputError(f"{quoted(first[table])} and {quoted(s)} are both the thesis's {table} scene (by the "
                             "bytes of their files): list one of them", source=source, key="scenes")
        first.setdefault(table, s)
    # (DIR/<key>: one folder on a case-blind disk too, and none of the study's own files)
    taken = {t.casefold() for t in [*first, *STUDY_FILES] if t is not None}
    out = {}
    for s, table in tables.items():
        key, n = table or Path(s).stem, 1
        while table is None and key.casefold() in taken:
            n += 1
            key = f"{Path(s).stem}-{n}"
        taken.add(key.casefold())
        out[s] = (key, table)
    return out


def judged_table(scene: str, table: str | None) -> str | None:
    """The table a study's ``scene`` is judged against (:func:`mismatches`): its own (``table``, by its
    file: :func:`scene_keys`), else the one its file's name claims (a user's ``room.yaml``, the
    built-in ``ring``: not comparable, 'the scene room.yaml (the thesis's is thesis/room)'), else None."""
    return table or (Path(scene).stem if Path(scene).stem in THESIS_SCENES else None)


def no_table(keys: dict[str, tuple[str, str | None]], names: dict[str, str]) -> dict[str, str]:
    """Each scene of a study without a thesis table (``keys``: :func:`scene_keys`; ``names``: the key ->
    its name as printed) -> a line saying so, and which thesis scene it is not where its name is one's."""
    out = {}
    for s, (key, table) in keys.items():
        judged = judged_table(s, table)
        if table is None:
            why = f" (not the thesis's {judged} scene, {THESIS_SCENES[judged]}: told by its file)" if judged else ""
            out[key] = f"{names.get(key, s)} has no table in the thesis{why}: its rows have no thesis value"
    return out


def mismatches(table: str, *, source: str | None = None, resolution: list[int] | None = None,
               photons: int | None = None, spp: int | None = None, light_samples: int | None = None,
               pipelines: int | None = None, clock_hz: float | None = None,
               config: dict | None = None, timing: dict | None = None) -> list[str]:
    """How a frame set beside ``table`` differs from the thesis's (empty: comparable).

    The one rule of comparability: the scene file ``source`` must be the thesis's scene
    of that table (:func:`table_of`), and the resolution, the photons emitted (None: no
    photon pass), the eye rays and light samples per pixel, the pipelines and the clock
    the thesis's, and every other key of the resolved ``config`` that changes the cycles
    or the image the thesis's setting's (:func:`setting_mismatches`; ``timing``, the run's
    ``results.json`` ``timing`` where there is one, says which keys its stream read). A value given as
    None is not judged. Each entry says what ours is, in a few words (``16×16 pixels
    (thesis 320×320)``, ``bsp.levels 3 (thesis: floor(ln n))``)."""
    w, h, n, _ = THESIS_SIZES[table]
    out = []
    if source is not None and table_of(source) != table:
        out.append(f"the scene {scene_label(source)} (the thesis's is {THESIS_SCENES[table]})")
    if resolution and [int(resolution[0]), int(resolution[1])] != [w, h]:
        out.append(f"{resolution[0]}×{resolution[1]} pixels (thesis {w}×{h})")
    if photons is not None and int(photons) != n:
        out.append(f"{int(photons):,} photons (thesis {n:,})")
    for key, value in (("spp", spp), ("light_samples", light_samples)):
        thesis, what = THESIS_SAMPLING[key]
        if value is not None and int(value) != thesis:
            out.append(f"{value} {what} (thesis {thesis})")
    if pipelines is not None and int(pipelines) != 1:
        out.append(f"{pipelines} pipelines (the tables are one pipeline)")
    if clock_hz is not None and not math.isclose(float(clock_hz), THESIS_CLOCK_HZ):
        out.append(f"clock {float(clock_hz) / 1e6:g} MHz (thesis 600 MHz)")
    return out + setting_mismatches(table, config, timing)


def thesis_setting(table: str, mode: str) -> dict:
    """The thesis's setting of a cell: the resolved config (:func:`~tlm.config.to_dict`) of
    the built-in ``configs/thesis.yaml``'s ``base`` with that table's scene and ``mode``
    (the committed study that reproduces Tables I-III; a null resolution or photon count
    is the scene's own, the thesis's sizes)."""
    return dict(_thesis_setting(table, mode))


@functools.cache
def _thesis_setting(table: str, mode: str) -> dict:
    path = configs_dir() / "thesis.yaml"
    _, base, src = read_study(path, ("scenes", "modes"))
    return to_dict(config_from_dict({**base, "scene": THESIS_SCENES[table], "mode": mode}, src))


def setting_mismatches(table: str, config: dict | None, timing: dict | None = None) -> list[str]:
    """How the resolved config ``config`` of a cell set beside ``table`` (a dict, as
    :func:`~tlm.config.to_dict` or ``config.resolved.yaml`` gives it; None: not judged)
    differs from the thesis's (:func:`thesis_setting` of its mode), key by key: every key
    whose value changes the simulated cycles or the image (``arch.*``, ``bsp.*``, ``cache.*``,
    the render depths, ``photons.*``, ``estimate.*``), one entry each, naming the key and
    both values, a null by what it stands for (``bsp.levels 3 (thesis: floor(ln n))``).
    Not judged: :data:`NOT_SETTING` (:func:`mismatches` judges its own), the keys that change
    neither (:func:`tlm.experiments.scaling.no_effect`: the threads, batches, exposure, event
    cap, trace, ``reference.*``), a key the cell never reads at its value
    (:func:`~tlm.render.planner.inert_settings`: the photon sections outside ``pmap``, the
    reflect depth in ``rcast``, ...; :func:`~tlm.render.planner.inert_timing_settings`), a timing
    key the thesis's stream never reads (``arch.fanout`` of its one pipeline: the thesis's value
    stands for none, and the key that makes ours read it, ``arch.pipelines``, is said) and a
    key ``config`` lacks (a folder written before the key existed).

    ``arch.settle_frames``: the thesis's static stream of two images *may* read it
    (:func:`tlm.arch.model.settling`: it runs on past ``arch.frames`` where the asked frames' steady gaps
    do not repeat), so from the config alone it is judged. ``timing``, the cell's ``results.json``
    ``timing`` section (the report's Table III and the thesis study have it; ``tlm calibrate``, which
    judges before it simulates, has not), decides it from the run instead (:func:`_bound_unread`): the
    key is no mismatch where this run's stream would have run the same at the thesis's value, that is
    where it ran the frames asked and was not measured as settling (no ``frames_cap``: its asked gaps
    repeat, at any bound), where both values give it the same cap, or where it settled before its own cap
    and within the thesis's; it is one where it ran on and was cut by its cap, or stopped there. What the
    results give is this cell's run, not a run of the thesis's setting: with the other keys the thesis's
    (any other is said itself) the two streams are the same but for the key, so this is the key's own
    effect."""
    if not isinstance(config, dict) or config.get("mode") not in MODES or table not in THESIS_SCENES:
        return []
    thesis = _thesis_setting(table, config["mode"])
    unread = _unread_keys(config) | _unread_keys(thesis, stream=True)
    if _bound_unread(timing, _lookup(config, SETTLE), _lookup(thesis, SETTLE)):
        unread.add(SETTLE)
    out = []
    for key, _, _ in describe():
        if key in NOT_SETTING or no_effect(key) or key in unread:
            continue
        ours, theirs = _lookup(config, key), _lookup(thesis, key)
        if ours is not _MISSING and ours != theirs:
            out.append(f"{key} {_value_text(key, ours)} (thesis: {_value_text(key, theirs)})" if key in THESIS_FIXED
                       else f"{key} {_value_text(key, ours)} (configs/thesis.yaml: {_value_text(key, theirs)}; "
                       "not in the thesis)")
    return out


SETTLE = "arch.settle_frames"


def _bound_unread(timing: dict | None, ours, theirs) -> bool:
    """Whether the run whose ``results.json`` ``timing`` section is ``timing`` would have run the same
    frames to the same cycles with ``arch.settle_frames`` at ``theirs`` as at ``ours`` (the stream of
    :mod:`tlm.arch.steady`: it runs on past ``frames_asked`` only where measured as settling, one arrival
    at a time until its completions repeat, at most ``frames_cap``): no ``frames_cap`` in its
    ``throughput_estimate`` and the frames asked run (no bound acts); the same cap at both values; or it
    settled at fewer frames than its cap and no more than the other value's cap (each arrival decides
    alike up to there). False where ``timing`` does not say (no run, a folder of another schema)."""
    if not isinstance(timing, dict) or not isinstance(ours, int) or not isinstance(theirs, int):
        return False
    est, ran, asked = timing.get("throughput_estimate"), timing.get("frames"), timing.get("frames_asked")
    if not isinstance(est, dict) or not isinstance(ran, int) or not isinstance(asked, int) or ran < asked:
        return False
    cap = est.get("frames_cap")
    if cap is None:
        return ran == asked and "window" in est  # (not measured as settling: ran the frames asked, at any bound)
    if cap != frames_cap(asked, ours):  # (a folder whose results and config disagree)
        return False
    # (below its cap it stopped where its completions so far repeated, whatever the estimate over the whole
    # stream says, est["settled"]: run_warnings.timing_inert judges it so too)
    return runs_alike(ran, cap, frames_cap(asked, theirs))


_MISSING = object()


def _lookup(config: dict, key: str):
    node = config
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return _MISSING
        node = node[part]
    return node


def _unread_keys(config: dict, stream: bool = False) -> set[str]:
    """The keys a run of ``config`` never reads at the values it gives them (its mode's passes,
    its filter, its scheduler, ...); none when ``config`` is no valid config of this schema.
    ``stream``: the timing keys its stream never reads alone (its scheduler's, its pipelines', its
    images in flight's), not those read at a value that gives what others do
    (:func:`~tlm.render.planner.same_frame_settings`: ``cache.pairs`` 4, read, gives what 2 does)."""
    known: dict = {}
    for key, _, _ in describe():  # (a key this schema lacks, of an older folder, is left out)
        value = _lookup(config, key)
        if value is not _MISSING:
            *parents, name = key.split(".")
            node = known
            for part in parents:
                node = node.setdefault(part, {})
            node[name] = value
    try:
        cfg = config_from_dict(known)
    except InputError:
        return set()
    if stream:
        return set(inert_timing_settings(cfg)) - set(same_frame_settings(cfg))
    return {*inert_settings(cfg), *inert_timing_settings(cfg)}


@functools.cache
def _null_words(key: str) -> str:
    """What a null value of ``key`` stands for, from its help (``floor(ln n)``), else ``null``."""
    helps = {k: h for k, _, h in describe()}
    found = re.search(r"null = (.+?)(?:, | \(|; |$)", helps.get(key, ""))
    return found.group(1) if found else "null"


def _value_text(key: str, value) -> str:
    if value is None:
        return _null_words(key)
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:g}"
    return json.dumps(value) if isinstance(value, (list, dict)) else str(value)


def photons_of(results: dict, config: dict) -> int | None:
    """The photons a run emitted (None when its photon pass did not run)."""
    if "pmap" not in (results.get("plan") or {}).get("run", []):
        return None
    emitted = (results.get("photons") or {}).get("emitted")
    if emitted is not None:
        return int(emitted)
    count = (config.get("photons") or {}).get("count")
    return int(count) if count is not None else (results.get("scene") or {}).get("photons")


def run_mismatches(table: str, results: dict, config: dict) -> list[str]:
    """:func:`mismatches` of a run folder: its ``results.json`` and resolved config, as dicts (its
    ``timing`` section says whether its stream read ``arch.settle_frames``: :func:`setting_mismatches`)."""
    scene = results.get("scene") or {}
    render = config.get("render") or {}
    photons = photons_of(results, config)
    ran = (results.get("plan") or {}).get("run")
    if photons is None and config.get("mode") == "pmap" and isinstance(ran, list):
        photons = 0  # (a PMap cell whose photon pass was left out, photons.count=0: it emitted none)
    timing = results.get("timing")
    return mismatches(table, source=scene.get("source"), resolution=scene.get("resolution"),
                      photons=photons, spp=render.get("spp"),
                      light_samples=render.get("light_samples"), pipelines=(config.get("arch") or {}).get("pipelines"),
                      clock_hz=(timing or {}).get("clock_hz"), config=config,
                      timing=timing if isinstance(timing, dict) else None)
