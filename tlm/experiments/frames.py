"""The functional cache: a frame's work counts on disk, keyed by what determines them.

A render's :class:`~tlm.arch.functional.Functional` (what the timing model reads) is
saved as one ``.npz`` keyed by everything that determines it: the config without its
``arch`` section and the settings the run's mode never reads (:func:`functional_key`), the
scene's content and the code (:func:`tlm.fingerprint.code_fingerprint`, the whole package).
Re-simulating a frame under another architecture config then reruns only the SimPy layer.
Beside each ``.npz`` a JSON sidecar of the same key keeps what a result row needs and the
timing model does not (work totals, scene statistics), so a sweep point never has to render to
report them, with the size and sha256 of the ``.npz`` (``npz``), the code that wrote it (``code_fingerprint``:
:func:`~tlm.fingerprint.code_fingerprint`, which its key holds too, so ``tlm cache`` tells an entry of other code, never
read again, from a live one) and, last, a digest of the rest of it (``sidecar_sha256``: :func:`sealed`), checked as it
is read, so a value changed in it is a damaged entry. A photon-map frame keeps its
image too (``<key>.pmap.npy``, its size and sha256 in the sidecar's ``pmap``), so its error is
measured when the frame is read, against the reference cached then (:func:`cached_render`): a
reference computed after the frame was cached (``tlm reference``) is used, as ``tlm run`` would. The image
is read only where there is a reference, its bytes checked against the sidecar as they are read: one removed
meanwhile (another process) or changed renders the frame again, a changed one said as a damaged entry.
A damaged entry (a file cut short, zeroed or overwritten, a sidecar without a
key a result row reads or with one of another type (:func:`summary_problem`), one not as its digest says
(:func:`seal_problem`) or naming other code than its key's, a folder where either
file should be) is reported once as a warning naming the file, removed (a folder too, only inside
the cache) and rendered again; an entry whose file is removed under its reader (``tlm cache prune``,
another process) is a miss, rendered again quietly. A frame read marks its entry used, for ``tlm cache
prune``; a look (:func:`is_cached`: ``tlm sweep --dry-run``) is not a use, and leaves the files' times as they were.
A write that fails (a full disk) leaves no ``.npz`` without its sidecar.

A key needs the scene's content: :func:`~tlm.experiments.frame_keys.scene_key` loads the scene once in a process and
remembers its fingerprint while the files the load read are unchanged, so the points of a
sweep that differ only in ``arch`` do not load it again each; a scene with mesh files, on disk
too (``scenes/key-<hash>.json``), so that another process (a rerun of a sweep whose points are
done) parses no mesh for it; a frame not in the cache is rendered from the scene its key loaded
(:func:`cached_render`), not loaded again.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import threading
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from tlm.arch.functional import Functional
from tlm.caches import (
    cache_root,
    cache_write_failed,
    cache_written,
    digest_problem,
    fields_problem,
    file_digest,
    note_use,
    remove_entry,
)
from tlm.config import config_from_dict, to_dict
from tlm.experiments import run
from tlm.experiments.frame_keys import MEMO_SIZE as MEMO_SIZE  # (the scene's part of a key: out of here, h487)
from tlm.experiments.frame_keys import keep_key as _keep_key  # noqa: F401  (kept importable from here, by its old name)
from tlm.experiments.frame_keys import looked as _looked
from tlm.experiments.frame_keys import scene_key as scene_key
from tlm.experiments.frame_keys import scene_key_loaded as _scene_key
from tlm.experiments.frame_scenes import moved_line
from tlm.experiments.frame_scenes import scene_fingerprint as scene_fingerprint
from tlm.experiments.run_warnings import emitted_photons, reference_warnings, threads_warning
from tlm.fingerprint import code_fingerprint
from tlm.fingerprint import seal_problem as _seal_problem
from tlm.fingerprint import sealed as _sealed
from tlm.progress import Timer
from tlm.registry import plugins
from tlm.render.checks import note_warnings
from tlm.render.planner import inert_changes, inert_settings, recorded_inert_settings, same_frame_settings
from tlm.scenes.loader import load_scene, resolve_scene_path
from tlm.scenes.model import Scene
from tlm.storage import warn, write_atomic, write_file


@dataclass(frozen=True)
class CachedRender:
    """A frame's :class:`Functional` with the render's summary, and where it came from.

    ``summary`` holds what a result row needs that the timing model does not: the
    scene's statistics, the plan, the primary rays, the work totals per pass, the photon
    map's statistics and the photon-map frame's error, as ``results.json`` of ``tlm run``
    writes them (keys :data:`SUMMARY_KEYS`), and the render's host seconds per stage.
    The error is measured when the frame is read, from its image in the cache, against the
    reference cached now and judged by this config's ``reference`` settings (a reference
    computed after the frame was cached is used; the cached frame stays valid), as ``tlm run``
    of the config would measure it.
    """

    functional: Functional
    summary: dict
    cached: bool  # True when both came from the cache
    key: str  # the cache key (:func:`functional_key`)
    # the scene's inputs as the key read them (results.json scene_digest: provenance.scene_identity of the files of
    # the load that gave the key's fingerprint, remembered with it while they are unchanged); None: no scene file
    scene_digest: str | None = None


SUMMARY_KEYS = ("scene", "plan", "primary", "work", "photons", "error", "warnings")
SUMMARY_FORMAT = "functional-summary/7"  # /2: with the npz's size and sha256; /3: warnings without the settings unused;
# /4: a reference not converged is a warning, and an unread override is warned of once; /5: the photon-map
# frame's image kept (``pmap``), its error measured when read, the reference's lines not kept; /6: the line on
# render.threads past the CPUs not kept (the process's and machine's that runs a point, not the frame's); /7: the
# sidecar's own digest (``sidecar_sha256``: :func:`sealed`) and the code that wrote it (``code_fingerprint``)
SEAL = "sidecar_sha256"  # a sidecar's digest of the rest of it (:func:`sealed`, :func:`seal_problem`)


# what a sidecar of SUMMARY_FORMAT holds, by type (summary_problem): the keys a result row reads
# (and ``pmap``: the photon-map frame's image file, its size and sha256, and the reference it was keyed to
# with the reference settings of that key, ``reference``, ``photons``, ``k_nearest``; None without the pass)
SUMMARY_FIELDS = {"scene": dict, "plan": dict, "primary": dict, "work": dict, "photons": (dict, type(None)),
                  "error": (dict, type(None)), "warnings": list, "host_seconds": dict, "pmap": (dict, type(None))}
assert set(SUMMARY_FIELDS) == {*SUMMARY_KEYS, "host_seconds", "pmap"}
# (and, where it was written by a tlm that counts them, ``notes``: how many of its first warnings are the scene's
# notes, the lines whose paths :func:`_here` moves to a copy's folders; an entry without it has them all moved)
SUMMARY_OPTIONAL = {"notes": int}


def summary_problem(summary: dict) -> str | None:
    """Why a sidecar of :data:`SUMMARY_FORMAT` does not hold what a result row reads (each key of
    :data:`SUMMARY_FIELDS` of its type, its warnings lines, its host seconds numbers), or None."""
    why = fields_problem(summary, SUMMARY_FIELDS, SUMMARY_OPTIONAL)
    if why is None and not all(isinstance(w, str) for w in summary["warnings"]):
        why = "its 'warnings' are not all lines"
    if why is None and not 0 <= summary.get("notes", 0) <= len(summary["warnings"]):
        why = "its 'notes' are not a count of its warnings"
    if why is None and not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                               for v in summary["host_seconds"].values()):
        why = "its 'host_seconds' are not all numbers"
    if why is None and (summary["pmap"] is None) != (summary["error"] is None):
        why = "its 'pmap' and 'error' disagree on the photon-map frame"
    if why is None and summary["pmap"] is not None and not (
            isinstance(summary["pmap"].get("reference"), str)
            and all(isinstance(summary["pmap"].get(k), int) for k in ("photons", "k_nearest"))):
        why = "its 'pmap' has no reference key and settings"
    return why


def sealed(side: dict) -> dict:
    """``side`` (a sidecar's content) with its digest, :data:`SEAL`: the sha256 of the canonical JSON of the rest of it
    (:func:`tlm.fingerprint.sealed`, as a reference's ``meta.json`` is sealed), so that a value changed in the file (a
    byte of a count) is told from what was written, as the ``.npz``'s own sha256 tells its bytes."""
    return _sealed(side, SEAL)


def seal_problem(side: dict) -> str | None:
    """Why the sidecar ``side`` (of :data:`SUMMARY_FORMAT`, as read) is not what :func:`sealed` wrote (its digest
    missing, or not that of the rest of it), or None (:func:`tlm.fingerprint.seal_problem`)."""
    return _seal_problem(side, SEAL)


def render_key(cfg, base: Path | None = None, source: str | None = None) -> str:
    """The cache key of ``cfg``'s frame (loads the scene, or remembers it:
    :func:`~tlm.experiments.frame_keys.scene_key`; a bad scene is an InputError)."""
    return _keyed(cfg, base, source)[0]


def _keyed(cfg, base: Path | None, source: str | None, timer: Timer | None = None
           ) -> tuple[str, Scene | None, str | None]:
    """:func:`render_key` with the scene its key loaded (None where the fingerprint was
    remembered), so that a render on a cache miss does not load it again, and the scene's digest
    (:func:`~tlm.experiments.frame_keys.scene_key_loaded`); ``timer``: gets the stage ``load_scene`` of that
    load."""
    fingerprint, scene, digest = _scene_key(cfg.scene, base, cfg.resolution, source, timer)
    return functional_key(cfg, fingerprint, code_fingerprint()), scene, digest


def is_cached(key: str) -> bool:
    """Whether the cache holds a whole entry of ``key``: the functional result and its summary,
    of this format, with what a result row reads (:func:`summary_problem`), the ``.npz`` the file
    the summary describes (its size and sha256). An entry
    damaged or of an older format is not (:func:`cached_render` renders it again, as a miss):
    a sweep lets one point render it first, as for a frame not cached, and the others read it
    (:func:`tlm.experiments.sweep._dispatch`); nothing is said or removed here. A look, not a use (``tlm sweep
    --dry-run`` counts the frames it would read so): its files are read without changing their access times
    (:func:`~tlm.experiments.frame_keys.looked`), which ``tlm cache prune`` takes for their last use, nor their
    modification times."""
    d = cache_dir()
    path, side = d / f"{key}.npz", d / f"{key}.json"
    if not (path.is_file() and side.is_file()):
        return False
    try:
        summary = json.loads(_looked(side).decode("utf-8"))
    except (OSError, ValueError):
        return False
    return (isinstance(summary, dict) and summary.get("format") == SUMMARY_FORMAT
            and summary_problem(summary) is None and seal_problem(summary) is None
            and summary.get("code_fingerprint") == code_fingerprint()
            and _looked_digest(path) == summary.get("npz")
            and (summary["pmap"] is None or _looked_digest(_image_file(path)) == {
                k: summary["pmap"].get(k) for k in ("size", "sha256")}))


def _looked_digest(path: Path) -> dict | None:
    """``path``'s size and sha256 read as a look (:func:`~tlm.experiments.frame_keys.looked`), or None where it
    cannot be read."""
    try:
        return _looked(path, digest=True)
    except OSError:
        return None


def _image_file(path: Path) -> Path:
    """The photon-map frame's image beside the entry's ``<key>.npz``: ``<key>.pmap.npy``."""
    return path.with_suffix(".pmap.npy")


def cached_render(cfg, base: Path | None = None, source: str | None = None, use_cache: bool = True
                  ) -> CachedRender:
    """The work and summary of ``cfg``'s frame: from the cache, or rendered and cached.

    An entry is the functional result (``<key>.npz``) and its summary (``<key>.json``,
    a sidecar); an entry missing either, unreadable or of an older format is rendered
    again, a damaged one (a folder where either file should be too) said and removed first.
    Both files are written atomically, so concurrent renders of one key (two processes of a
    sweep) leave one whole entry; a write that fails (a full disk, a read-only cache) costs
    speed only, and leaves no ``.npz`` without its sidecar. Its ``scene_digest`` is that of the scene
    files the key was computed from (:func:`~tlm.experiments.frame_keys.scene_key_loaded`), a frame read from the cache
    too: this config's files as this process read them, not those of whoever rendered the frame first.
    """
    timer = Timer()
    key, scene, digest = _keyed(cfg, base, source, timer)  # (the scene, when the key loaded it: rendered from it)
    path = cache_dir() / f"{key}.npz"
    side = path.with_suffix(".json")
    if use_cache:
        folder = next((f for f in (path, side) if f.is_dir()), None)  # (what would be read or written there)
        if folder is not None:
            _damaged(folder, side if folder == path else path, "a folder, not a file")
        elif path.exists() and side.exists():
            got = _load_entry(path, side, key)
            if got is not None:  # (the digest of the scene its key was computed from: this config's files now)
                got = _here(replace(got, scene_digest=digest), cfg, base, source, scene)
                measured = _measured(got, cfg, lambda: _image(path, side, got.summary["pmap"]), scene, base, source)
                if measured is not None:
                    return measured
                # (its image removed or changed since the entry was read: another process's; rendered again)
    res = run.render(cfg, base, source, scene=scene, timer=timer)
    fn = res.functional()
    full = run.results_dict(res, exposure=0.0, config_path=source)
    # the render's own warnings: not this config's unused settings, which another config of the
    # key (a sweep point of other arch or estimate settings) does not share (tlm.experiments.sweep), nor
    # the reference's (its error is measured when the frame is read: _measured), nor the line on render.threads
    # past the CPUs, which neither the key (the threads) nor the frame (the machine's CPUs) holds: the process
    # that runs a point says its own (tlm.experiments.sweep_point.run_point)
    inert = {*inert_changes(cfg), *reference_warnings(res.error, cfg, emitted_photons(res), res.scene.photons),
             *threads_warning(cfg)}
    # (the scene's notes come first, tlm.render.checks.file_warnings: the lines _here moves to a copy's folders, and
    # no other, a material's name that holds a path of the project is the copy's material's name too)
    notes = sum(w not in inert for w in full["warnings"][:len(note_warnings(res.scene))])
    full["warnings"] = [w for w in full["warnings"] if w not in inert]
    pmap = res.radiance["pmap"].reshape(-1, 3) if res.error is not None else None
    summary = {"format": SUMMARY_FORMAT, **{k: full[k] for k in SUMMARY_KEYS}, "notes": notes,
               "host_seconds": {k: round(v, 6) for k, v in res.timer.seconds.items()},
               "pmap": None if pmap is None else {"reference": res.error["reference"],
                                                  **_reference_settings(cfg, res.scene.photons)}}
    if use_cache:
        saved = []
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            fn.save(path)  # the npz (and the image) first: the sidecar holds their sizes and checksums
            saved.append(path)
            side_text = {**summary, "npz": file_digest(path)}
            if pmap is not None:
                saved.append(_image_file(path))
                with write_atomic(_image_file(path), "wb") as fh:  # (whole or not at all)
                    np.save(fh, pmap)
                side_text["pmap"] = {**summary["pmap"], **file_digest(_image_file(path))}
            # (the code that wrote it, for tlm cache: an entry of other code is never read again by this one, its
            # key holds the code; and the sidecar's own digest, last: checked as it is read, _load_entry)
            side_text["code_fingerprint"] = code_fingerprint()
            write_file(side, json.dumps(sealed(side_text), indent=1) + "\n")
        except OSError as e:  # a read-only (or full) cache only costs speed, said once (its folder's mkdir's too:
            # a file put in its place since this process first looked at it)
            cache_write_failed(path, e)
            for done in saved:  # (files without their sidecar: nothing reads them, so they would only fill the disk)
                remove_entry(done, cache_dir())
        else:
            cache_written(path)
    got = CachedRender(fn, summary, False, key, digest)
    return _measured(got, cfg, lambda: pmap, res.scene, base, source)


def _image(path: Path, side: Path, digest: dict) -> np.ndarray | None:
    """The cached photon-map frame's image beside ``path``, its bytes checked as they are read against
    ``digest`` (the sidecar ``side``'s ``pmap``: its size and sha256); None where it is not there now
    (another process removed the entry since it was read) or not that file (a damaged entry: said once
    and removed, as :func:`_load_entry` does). Its caller renders the frame again then."""
    file = _image_file(path)
    try:
        data = file.read_bytes()
    except (FileNotFoundError, NotADirectoryError):
        return None  # (gone: whoever removed it said why, where it was damaged)
    except OSError as e:
        _damaged(file, side, f"cannot read it ({e.strerror or e})")
        return None
    if len(data) != digest.get("size"):
        why = f"{len(data)} bytes, its sidecar says {digest.get('size')}"
    elif hashlib.sha256(data).hexdigest() != digest.get("sha256"):
        why = "its checksum differs from its sidecar's"
    else:
        try:
            image = np.load(io.BytesIO(data), allow_pickle=False)
            if image.dtype.kind != "f" or image.ndim != 2 or image.shape[-1] != 3:
                raise ValueError(f"an array of {image.dtype} {image.shape}, not (pixels, 3) floats")
            return image
        except (ValueError, EOFError, OSError) as e:
            why = f"{type(e).__name__}: {e}"
    _damaged(file, side, why)
    return None


def _reference_settings(cfg, scene_photons: int) -> dict:
    """What of ``cfg``'s reference settings its reference's key holds beside the frame's (which the
    functional key holds): the photons per round (null: the scene's) and ``k_nearest``."""
    r = cfg.reference
    return {"photons": int(scene_photons if r.photons is None else r.photons), "k_nearest": int(r.k_nearest)}


def _measured(got: CachedRender, cfg, pmap, scene: Scene | None, base: Path | None, source: str | None
              ) -> CachedRender | None:
    """``got`` with its photon-map frame's ``error`` measured now: the image (``pmap()``) against the
    reference of ``cfg`` cached now, as :func:`tlm.experiments.run.photon_error` measures it (the
    reference's stopping rule ``cfg``'s), and the lines on a reference not converged or blurrier (h453) among its
    warnings. The reference's key is the one the frame was rendered with where ``cfg`` asks the same
    reference photons and ``k_nearest`` (the rest of that key is the frame's: scene, camera, the
    photons' bounces and the specular walks'), else computed from the scene (loaded where the key
    did not load it). None where the image is not there to measure (``pmap()`` gives None: a cached one
    removed or damaged since its entry was read, :func:`_image`): the frame is rendered again."""
    held = got.summary.get("pmap")
    if not isinstance(held, dict) or got.summary.get("error") is None:
        return got
    from tlm.experiments.reference import reference_key
    from tlm.experiments.reference_cache import ReferenceSettings, load_reference

    scene_photons = (got.summary.get("scene") or {}).get("photons")
    if scene is None and cfg.reference.photons is None and not isinstance(scene_photons, int):
        scene = load_scene(cfg.scene, base, cfg.resolution, source)
    mine = _reference_settings(cfg, scene_photons if scene is None else scene.photons)
    settings = ReferenceSettings(**mine, tolerance=cfg.reference.tolerance, min_rounds=cfg.reference.min_rounds,
                                 max_rounds=cfg.reference.max_rounds, spp=cfg.reference.spp)
    if mine == {k: held.get(k) for k in mine}:
        key = held["reference"]
    else:
        if scene is None:
            scene = load_scene(cfg.scene, base, cfg.resolution, source)
        key = reference_key(scene, cfg, settings)
    found = load_reference(key)
    image, meta = (None, None) if found is None else (found[0].reshape(-1, 3), found[1])
    frame = pmap() if image is not None else None  # (read only where there is a reference to measure it against)
    if image is not None and frame is None:
        return None
    shape = ([scene.camera.width, scene.camera.height] if scene is not None else  # (the reference's, its key's)
             (got.summary.get("scene") or {}).get("resolution"))
    error = run.error_against(key, settings, frame, image, meta, resolution=shape if isinstance(shape, list) else None)
    summary = {**got.summary, "error": error,
               "warnings": [*(got.summary.get("warnings") or []),
                            *reference_warnings(error, cfg, got.summary.get("photons"),
                                                scene_photons if scene is None else scene.photons)]}
    return replace(got, summary=summary)

def _here(got: CachedRender, cfg, base: Path | None, source: str | None, scene: Scene | None) -> CachedRender:
    """``got``, a cached frame, with its summary's ``scene.source`` the file this config names,
    and its warnings naming this copy's files: the key holds the scene's content, its file's
    name and its notes' paths relative to its folder (:func:`~tlm.experiments.frame_scenes.scene_fingerprint`), not
    where it lies, so the same project in another folder shares the frame (a mesh outside the scene's folder,
    ``../m/x.obj``, too), and its results name its own files (:func:`~tlm.experiments.frame_scenes.moved_line`)."""
    held = got.summary.get("scene")
    if not isinstance(held, dict) or not isinstance(held.get("source"), str):
        return got
    here = scene.source if scene is not None else str(resolve_scene_path(cfg.scene, base, source))
    if held["source"] != here:
        was, now = os.path.dirname(held["source"]), os.path.dirname(here)
        got.summary["scene"] = {**held, "source": here, **(_moved_from(held, was, now) if was else {})}
        if was and isinstance(got.summary.get("warnings"), list):
            # (the scene's notes, the first lines: the rest say what its content holds, the copy's too, as it is)
            notes = got.summary.get("notes", len(got.summary["warnings"]))
            got.summary["warnings"] = [moved_line(w, was, now) if isinstance(w, str) and i < notes else w
                                       for i, w in enumerate(got.summary["warnings"])]
    return got


def _moved_from(scene: dict, was: str, now: str) -> dict:
    """A cached summary's ``scene`` ``materials`` and ``lights`` with each one's ``from`` (the MTL line, the scene
    file's key that gave it: :func:`tlm.experiments.run.scene_stats`) naming the copy's files in ``now``
    (:func:`moved_line`); {} where they hold none."""
    out = {}
    mats, lights = scene.get("materials"), scene.get("lights")
    if isinstance(mats, dict):
        out["materials"] = {k: {**m, "from": moved_line(m["from"], was, now)}
                            if isinstance(m, dict) and isinstance(m.get("from"), str) else m for k, m in mats.items()}
    if isinstance(lights, list):
        out["lights"] = [{**lt, "from": moved_line(lt["from"], was, now)}
                         if isinstance(lt, dict) and isinstance(lt.get("from"), str) else lt for lt in lights]
    return out


def _load_entry(path: Path, side: Path, key: str) -> CachedRender | None:
    """The cached entry, or None: outdated (an older format, rendered again quietly), gone
    (a file of it removed since it was found: a prune, another process; a miss, quietly) or damaged
    (a sidecar naming no format, ``{}``, too: a warning naming the file; both removed, said once). An entry read
    is marked used (its sidecar's time: :func:`tlm.caches.note_use`; no digest checks it), so that
    ``tlm cache prune`` removes frames by their last use where access times are not kept."""
    try:
        summary = json.loads(side.read_text(encoding="utf-8"))
        if not isinstance(summary, dict):
            raise ValueError("not a JSON object")
    except (FileNotFoundError, NotADirectoryError):
        return None
    except (OSError, ValueError) as e:  # (UnicodeDecodeError is a ValueError)
        _damaged(side, path, f"unreadable sidecar ({type(e).__name__})")
        return None
    fmt = summary.get("format")
    if fmt != SUMMARY_FORMAT:
        if isinstance(fmt, str) and fmt.startswith(SUMMARY_FORMAT.partition("/")[0] + "/"):
            return None  # an entry of an older tlm (every sidecar names its format): rendered again and replaced
        # (``{}``, or JSON of another shape: no sidecar tlm wrote, said as a damaged one is: h417)
        _damaged(side, path, "no format: not a functional-cache sidecar" if fmt is None
                 else f"format {json.dumps(fmt)[:60]}: not a functional-cache sidecar's")
        return None
    problem = summary_problem(summary)
    if problem is None:  # (its digest, then the code it names: its key's, whose code it is)
        problem = seal_problem(summary)
    if problem is None and summary.get("code_fingerprint") != code_fingerprint():
        problem = f"its 'code_fingerprint' {json.dumps(summary.get('code_fingerprint'))[:40]} is not this code's"
    if problem is not None:
        _damaged(side, path, problem)
        return None
    for held in (SEAL, "code_fingerprint"):  # (the sidecar's, not the summary's: as a frame rendered now gives it)
        summary.pop(held)
    npz = summary.pop("npz", None)
    problem = digest_problem(path, npz)
    if problem is not None:
        if not _gone(path):
            _damaged(path, side, problem)
        return None
    if summary["pmap"] is not None:
        problem = digest_problem(_image_file(path), summary["pmap"])
        if problem is not None:
            if not _gone(_image_file(path)):
                _damaged(_image_file(path), side, problem)
            return None
    try:
        got = CachedRender(_read_frame(path, key, npz), summary, True, key)
    except (FileNotFoundError, NotADirectoryError):
        return None
    except Exception as e:  # BadZipFile, EOFError, zlib.error, ValueError, KeyError: a damaged file
        _damaged(path, side, f"{type(e).__name__}: {e}")
        return None
    note_use(side)
    return got


_LAST_FRAME: tuple[str, str, int, str, Functional] | None = None  # (file, key, size, sha256, frame): the last read
_LAST_FRAME_LOCK = threading.Lock()


def _read_frame(path: Path, key: str, digest: dict) -> Functional:
    """:meth:`Functional.load` of the entry ``path`` of ``key``, or the frame this process read last where it is
    that file again: the same file and key, and the size and sha256 of ``digest`` (the sidecar's, which
    :func:`digest_problem` has just checked the file's bytes against), so that the points of a sweep, handed out
    grouped by frame (:func:`tlm.experiments.sweep._dispatch`), do not each decompress the same frame. Every
    check of the entry runs as before (its sidecar, its checksum, its image): an entry removed is a miss and
    one rendered again is another file (another sha256), read anew. One frame is kept (its memory); its arrays
    are read-only (:class:`~tlm.kernels.work.WorkArrays`), so no point changes the frame the next one gets."""
    global _LAST_FRAME
    held = (os.path.abspath(path), key, digest["size"], digest["sha256"])
    with _LAST_FRAME_LOCK:
        last = _LAST_FRAME
    if last is not None and last[:4] == held:
        return last[4]
    frame = Functional.load(path)
    with _LAST_FRAME_LOCK:
        _LAST_FRAME = (*held, frame)
    return frame


def forget_last_frame() -> None:
    """Drop the frame :func:`_read_frame` keeps (a sweep's end: a library caller's process does not hold it on)."""
    global _LAST_FRAME
    with _LAST_FRAME_LOCK:
        _LAST_FRAME = None


def _gone(file: Path) -> bool:
    """Whether an entry's ``file`` is not there now (removed under its reader: no damaged entry)."""
    return not os.path.lexists(file)


def _damaged(bad: Path, other: Path, why: str) -> None:  # (its callers return None)
    """Say the damaged entry (``bad``, and ``other``, its other file) once, and remove both (a folder
    too: :func:`~tlm.caches.remove_entry`, only inside the cache)."""
    npz = next(f for f in (bad, other) if f.suffix == ".json").with_suffix(".npz")
    files = dict.fromkeys((bad, other, npz, _image_file(npz)))  # (the entry's every file, once)
    left = [w for w in (remove_entry(f, cache_dir()) for f in files) if w is not None]
    done = "removed" if not left else f"not removed ({left[0]})"
    warn(f"damaged functional cache entry {bad} ({why}): {done}, rendering it again")


def cached_functional(cfg, base: Path | None = None, source: str | None = None, use_cache: bool = True
                      ) -> tuple[Functional, bool]:
    """The work of ``cfg``'s frame: from the cache when an identical render was cached.

    Returns the :class:`Functional` and whether it came from the cache. The key is the
    config without ``arch`` (and without what only changes pixels' brightness or what the
    mode never reads: :func:`functional_key`), the scene's content and the code.
    """
    got = cached_render(cfg, base, source, use_cache)
    return got.functional, got.cached


def cache_dir() -> Path:
    return cache_root("functional")


def functional_key(cfg, scene_fingerprint: str, code_version: str) -> str:
    """Hash of what the work counts depend on: the settings the render reads, the scene.

    ``cfg``: a :class:`~tlm.config.RunConfig` (or its :func:`~tlm.config.to_dict`). Left out:
    ``arch`` and ``reference`` (the timing model's; the reference the photon-map frame is
    measured against), what changes only brightness or speed (``render.exposure``,
    ``render.threads``), and the settings the run's mode never reads, as
    :func:`tlm.render.planner.inert_settings` names them (the one list the warnings use):
    every photon-map key in a mode without the pass, the specular walk's (``render.reflect_depth``,
    ``render.fresnel``, ...) in mode ``rcast``, ``estimate.k`` under another filter than
    ``kvoxel``, ... A sweep of such a setting renders its frame once; but for those the frame's
    summary records (:func:`~tlm.render.planner.recorded_inert_settings`: ``estimate.radius_photons``
    under final gathering, the indirect radius ``photons.radius``), kept so a frame's record is its own.
    A setting whose values give one frame (:func:`~tlm.render.planner.same_frame_settings`: ``cache.pairs``
    2, 3 and 4, each cached stream on a pair of its own) is keyed by the value that stands for them (4), so
    those render their frame once too (the entries cached under the keys 2 and 3 had before are read no more:
    ``tlm cache prune`` removes them in their turn).

    A scene file is keyed by its file's name alone (``box.yaml``), not by the absolute path
    the config holds (:func:`tlm.config.scene_from`): its content is ``scene_fingerprint``,
    so the same project in another folder (moved, copied, another user's checkout) finds the
    frames it rendered, and two files of one content but other names (which a result names
    by the file) stay two entries. A built-in scene's name is kept as it is.

    A class that a setting it keeps selects from outside tlm (``estimate.filter``, a plug-in:
    :func:`tlm.registry.plugins`) adds its record, its code's digest with it, under ``plugins``; a frame of
    tlm's own classes alone has the key it had before plug-ins were keyed."""
    if isinstance(cfg, dict):
        cfg = config_from_dict(cfg)
    unread = set(inert_settings(cfg)) - recorded_inert_settings(cfg)  # (less those its summary records)
    keep = {k: v for k, v in to_dict(cfg).items() if k not in ("arch", "reference")}
    if isinstance(keep.get("scene"), str) and os.path.isabs(keep["scene"]):
        keep["scene"] = os.path.basename(keep["scene"])  # (not where the project lies: its content is the scene)
    for section, values in keep.items():
        if isinstance(values, dict):
            keep[section] = {k: v for k, v in values.items() if f"{section}.{k}" not in unread}
    for setting, value in same_frame_settings(cfg).items():  # (cache.pairs 2, 3 and 4: one frame, keyed as 4)
        section, name = setting.split(".", 1)
        if name in keep.get(section, {}):
            keep[section][name] = value
    # (not what changes only brightness or speed: the exposure, the kernels' threads)
    keep["render"] = {k: v for k, v in keep["render"].items() if k not in ("exposure", "threads")}
    doc = {"cfg": keep, "scene": scene_fingerprint, "code": code_version}
    if chosen := plugins(keep):  # (a class from outside tlm that the frame reads: its code; none, as before)
        doc["plugins"] = chosen
    blob = json.dumps(doc, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:24]
