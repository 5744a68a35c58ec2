"""The experiment schema: every parameter declared once, with its default, unit and help.

A config is a YAML mapping; each section is a frozen dataclass whose fields carry their
help text in ``metadata``. Loading walks the dataclasses, so an unknown key, a wrong
type or a value out of range is reported with the file, the dotted key and the value
(``InputError``), and the fully resolved config (defaults included) can be written
next to the results. ``--set dotted.key=value`` overrides go through the same checks.
How a YAML text reads and how the messages say a value or a type: :mod:`tlm.config_words`.
The files a config names, made absolute where it is read: :mod:`tlm.config_paths`.
The functional model's sections (bsp, render, photons, estimate, cache, reference): :mod:`tlm.config_sections`.
"""

from __future__ import annotations

import contextlib
import contextvars
import copy
import dataclasses
import hashlib
import math
import os
import stat
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from tlm import config_words
from tlm.config_paths import (  # noqa: F401  (PATH_KEYS, builtin_scenes_dir, names_scene_file: re-exported)
    PATH_KEYS,
    builtin_scenes_dir,
    files_from,
    names_scene_file,
    paths_from,
    scene_from,
    sets_scene,
)
from tlm.config_read import TooLarge, decoded, yaml_text
from tlm.config_sections import (  # noqa: F401  (FILTERS and the functional model's sections: re-exported)
    FILTERS,
    BSPConfig,
    CacheConfig,
    EstimateConfig,
    PhotonConfig,
    ReferenceConfig,
    RenderConfig,
    _f,
)
from tlm.config_words import (
    DuplicateKeyError,
    ExpansionError,
    parse_yaml,
    type_hint,
    type_name,
    value_text,
    with_overrides,
    yaml_kind,
)
from tlm.config_words import check_bounds as _check_bounds
from tlm.config_words import check_range as _check_range
from tlm.config_words import whole_floats as _whole_floats
from tlm.errors import InputError, did_you_mean, quoted
from tlm.mesh_files import mesh_file_format, mesh_file_hint
from tlm.registry import SCHEDULERS

MODES = ("rcast", "reflect", "refract", "pmap")
FANOUTS = ("broadcast", "serial")
MEMORY_READINGS = ("swap", "copy")

# Maxima keep the model's cycles within int64. A frame is T_norm + misses x page_miss + flushes x flush + swaps,
# switches x theirs + words / copy_words_per_cycle (divides: <= 2**62); knobs <= 2**20, frames <= 10**4 keep all
# but T_norm below 2**63 to 2**29 events a frame (thesis Cornell PMap: 2.6e6). T_norm (arch.programs: its scale) is
# capped only at costs.MAX_CYCLES = 2**62 a job: the frames can pass int64 with it (units.within_int64 stops that). FIFO
# depth, packet size <= 2**31, max_events <= 2**53. clock_hz >= 1 Hz: a trace's us (cycles x 1e6 / clock) finite.
_CYC, _SIZE = {"max": 1 << 20}, {"min": 1, "max": 1 << 31}
MAX_TILES = 1 << 16  # tiles_per_pipeline x pipelines at most (docs/architecture.md, "Tiles": what more costs)


@dataclass(frozen=True)
class ArchConfig:
    clock_hz: float = _f(600e6, "system clock in Hz (thesis: 600 MHz); FPS = clock_hz / throughput cycles "
                         "(1 Hz to 1e12, a terahertz)", min=1.0, max=1e12)
    frames: int = _f(5, "frames in the simulated stream (the same image, two in flight); TThru is measured over the "
                     "steady state (at least 5 frames with two images in flight, 1 with one)", min=1, max=10000)
    settle_frames: int = _f(64, "the most frames a stream of two images runs, on past frames until its completions "
                            "repeat (the dynamic scheduler; the static one where the asked frames' steady gaps do not "
                            "repeat from the first): max(frames, settle_frames); 1: frames alone", min=1, max=10000)
    images_in_flight: int = _f(2, "images in flight: 2 (thesis: modules 0&1 image 0, 2&3 image 1) or 1; memory "
                               "modules: 2 x images_in_flight x pipelines (+1 composer past 1 pipeline)", min=1, max=2)
    packet_size: int = _f(256, "rays, pixels or photons per packet: the TLM's granularity (1 = fine reference)",
                          **_SIZE)
    fifo_depth: int = _f(1024, "triangle addresses the Traversal PM's FIFO to the Intersection PM holds", **_SIZE)
    page_miss_cycles: int = _f(12, "T_ms cycles per page miss (thesis: 12, DDR row + column access), the same at "
                               "every cache.block_words: the block's transfer costs nothing", min=0, **_CYC)
    flush_cycles: int = _f(4, "T_ps cycles per pipeline flush (thesis: 4)", min=0, **_CYC)
    swap_cycles: int = _f(2, "cycles to re-route a PM to another module (top two address bits)", min=0, **_CYC)
    copy_words_per_cycle: int = _f(2, "128-bit words per cycle of a block copy between modules", min=1,
                                   max=1 << 62)  # (a divisor: any bandwidth keeps the copies' cycles small)
    context_switch_cycles: int = _f(16, "cycles to save or restore a PM's context at a preemption", min=0, **_CYC)
    memory: str = _f("swap", "swap: frames move down the chain by re-routing, data is copied only where two "
                     "stages need it | copy: every hand-over copies the working set", choices=MEMORY_READINGS)
    pipelines: int = _f(1, "duplicated pipelines (thesis §V.D): the image is cut into tiles, one Vertex PM "
                        "builds the shared structures, the crossbar copies them to every pipeline", min=1, max=4096)
    scheduler: str = _f("static", "static: one tile (quadrant for 4) per pipeline | dynamic: a shared queue of "
                        "tiles_per_pipeline x pipelines tiles, an idle pipeline takes the next", choices=SCHEDULERS)
    tiles_per_pipeline: int = _f(4, f"tiles per pipeline, dynamic queue (x pipelines <= {MAX_TILES})", min=1, max=4096)
    fanout: str = _f("broadcast", "copies of shared structures to the pipelines: broadcast (the crossbar writes "
                     "every pipeline's module at once) | serial (one copy per pipeline)", choices=FANOUTS)
    programs: str | None = _f(None, "instruction-cost table (YAML, relative to the file that names it; "
                              "--set: to the working folder); null = the calibrated default "
                              "tlm/arch/programs.yaml")
    max_events: int = _f(200_000_000, "SimPy events after which an unfinished run is a deadlock (a cap: a run "
                                      "also stops past 64 events per packet, job and tile of its program)", min=1,
                         max=1 << 53)
    trace: bool = _f(True, "write trace.json (Chrome trace events, opens in ui.perfetto.dev)")


@dataclass(frozen=True)
class RunConfig:
    scene: str = _f("cornell", "built-in scene name or path to a scene YAML (relative to the config)")
    mode: str = _f("refract", "rcast | reflect | refract | pmap (each adds passes to the previous)", choices=MODES)
    seed: int = _f(0, "seed of every random stream (SeedSequence); at most 2**64 - 1, the kernels' 64-bit hash key",
                   min=0, max=2**64 - 1)
    # (a list in YAML, held as a tuple, as every list-valued setting: a loaded config is immutable and hashable)
    resolution: tuple[int, ...] | None = _f(
        None, "[width, height] in pixels; null = the scene's", length=2, example="[64, 64]"
    )
    bsp: BSPConfig = field(default_factory=BSPConfig, metadata={"help": "geometry BSP"})
    render: RenderConfig = field(default_factory=RenderConfig, metadata={"help": "passes"})
    photons: PhotonConfig = field(default_factory=PhotonConfig, metadata={"help": "photon tracing"})
    estimate: EstimateConfig = field(default_factory=EstimateConfig, metadata={"help": "radiance estimate"})
    cache: CacheConfig = field(default_factory=CacheConfig,
                               metadata={"help": "the PMs' data cache (page misses of the work counts)"})
    reference: ReferenceConfig = field(default_factory=ReferenceConfig,
                                       metadata={"help": "converged reference of the photon-map frame"})
    arch: ArchConfig = field(default_factory=ArchConfig, metadata={"help": "the timing model (SimPy layer)"})


def _type_ok(value: Any, tp: Any) -> bool:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        return any(_type_ok(value, a) for a in typing.get_args(tp))
    if tp is type(None):
        return value is None
    if tp is bool:
        return isinstance(value, bool)
    if tp is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if tp is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if tp is str:
        return isinstance(value, str)
    if (inner := config_words.item_type(tp)) is not None:  # (a list-valued setting: YAML's list, held as a tuple)
        return isinstance(value, list) and all(_type_ok(v, inner) for v in value)
    return False


_SCHEMA: dict[type, tuple[dict[str, Any], dict[str, dataclasses.Field]]] = {}


def _schema(cls: type) -> tuple[dict[str, Any], dict[str, dataclasses.Field]]:
    """A section's type hints and fields by name, worked out once per class (resolving the
    string annotations is most of the cost of checking a config: a sweep checks one per point)."""
    got = _SCHEMA.get(cls)
    if got is None:
        got = _SCHEMA[cls] = typing.get_type_hints(cls), {f.name: f for f in dataclasses.fields(cls)}
    return got


_ABSENT = object()  # a plain key the raw mapping leaves out: the section's default
# a section given one value where its keys belong: the key that value most likely meant (the error's hint)
_MAIN_KEY: dict[str, tuple[str, type | tuple[type, ...]]] = {"photons": ("count", int), "estimate": ("filter", str)}


def _build(cls: type, raw: Any, source: str, prefix: str) -> Any:
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        main = _MAIN_KEY.get(prefix)  # (photons: 5000 meant photons: {count: 5000})
        hint = "" if main is None or not isinstance(raw, main[1]) or isinstance(raw, bool) else \
            f" (did you mean {prefix}: {{{main[0]}: {value_text(raw)}}}?)"
        raise InputError(f"must be a mapping of keys, got {value_text(raw)}{hint}", source=source,
                         key=prefix or "(top)")
    hints, fields = _schema(cls)
    for key in raw:
        if key not in fields:
            # (YAML's 1:, true:, null: as written, not Python's True, None; a date as it reads, 2026-01-01)
            name = value_text(key) if isinstance(key, (bool, int, float, type(None))) else str(key)
            where = f"{prefix}.{name}" if prefix else name
            hint = _placed_elsewhere(name, prefix) or did_you_mean(name, fields)
            raise InputError(f"unknown key{hint}", source=source, key=where)
    values = {}
    for name, f in fields.items():
        v = _field(f, hints[name], raw, source, f"{prefix}.{name}" if prefix else name)
        if v is not _ABSENT:
            values[name] = v
    out = cls(**values)
    _across(out, source, prefix)
    out.__dict__[_CHECKED] = True  # (checked whole: checked() takes it as it is)
    return out


def _placed_elsewhere(name: str, prefix: str) -> str:
    """`` (did you mean 'resolution'?)`` where ``name``, an unknown key of the section ``prefix`` (``""``: the top
    level), is a key of another section or of the top level, by its last part, those nearer the top first
    (``--set render.resolution=...``: the top-level ``resolution``; ``arch.spp``: ``'render.spp' or
    'reference.spp'``); else ``""``, for a hint among the section's own keys (h536: such a key was said
    unknown with no hint, and a top-level ``spp`` was asked whether it meant ``'bsp'``)."""
    keys = sorted((k for k in (*(k for k, _, _ in describe()), *sorted(SECTIONS))
                   if k.rpartition(".")[2] == name and k.rpartition(".")[0] != prefix), key=lambda k: k.count("."))
    return f" (did you mean {' or '.join(repr(k) for k in keys[:3])}?)" if keys else ""


def _across(out: Any, source: str, prefix: str) -> None:
    """The checks across a section's fields, once each field passed its own."""
    if isinstance(out, ReferenceConfig) and out.min_rounds > out.max_rounds:
        raise InputError(f"{out.min_rounds} is more than {prefix}.max_rounds ({out.max_rounds})", source=source,
                         key=f"{prefix}.min_rounds")
    if isinstance(out, ArchConfig) and out.scheduler == "dynamic" and (n := out.tiles_per_pipeline * out.pipelines) \
            > MAX_TILES:  # (the static scheduler's tiles are the pipelines, at most 4096)
        raise InputError(f"{out.tiles_per_pipeline} x {prefix}.pipelines ({out.pipelines}) = {n} tiles in the dynamic "
                         f"queue, more than {MAX_TILES}", source=source, key=f"{prefix}.tiles_per_pipeline")


def _field(f: dataclasses.Field, tp: Any, raw: dict, source: str, key: str) -> Any:
    """The checked value of field ``f`` (type ``tp``, dotted ``key``) of the mapping ``raw``;
    _ABSENT where ``raw`` leaves a plain field out."""
    name = f.name
    if dataclasses.is_dataclass(tp):
        return _build(tp, raw.get(name), source, key)
    if name not in raw:
        return _ABSENT
    v = raw[name]
    if not _type_ok(v, tp):
        if typed := _whole_floats(v):  # (1e20 for an integer: its range first, not "write 100000000000000000000")
            _check_bounds(v, f.metadata, source, key, typed)
        kind = type_name(tp, f.metadata)
        raise InputError(f"{value_text(v)} is not {kind}{type_hint(v, tp, f.metadata)}", source=source, key=key)
    if isinstance(v, float) and not math.isfinite(v):
        raise InputError(f"{value_text(v)} is not finite", source=source, key=key)
    _check_range(v, f.metadata, source, key)
    if isinstance(v, int) and not isinstance(v, bool) and float in typing.get_args(tp) + (tp,):
        v = float(v)
    return tuple(v) if isinstance(v, list) else v  # (immutable: to_dict, YAML and the keys give it as a list)


def run_config_field(name: str, raw: dict, source: str = "(dict)") -> Any:
    """RunConfig's top-level field ``name`` (a section, or ``scene``, ``mode``, ...) checked
    from ``raw[name]`` alone (:func:`plain` values), as :func:`config_from_dict` checks it,
    the same InputError included; its default where ``raw`` leaves it out.

    A RunConfig is the product of its fields: ``RunConfig(**{name: run_config_field(name,
    raw) for every field})`` is ``config_from_dict(raw)`` when every key of ``raw`` is a
    field (RunConfig has no check across its fields; :mod:`tlm.experiments.sweep` checks a
    sweep's points field by field, each field's values once).
    """
    hints, fields = _schema(RunConfig)
    f = fields[name]
    v = _field(f, hints[name], raw, source, name)
    if v is _ABSENT:
        v = f.default_factory() if f.default is dataclasses.MISSING else f.default
    return v


def is_leaf(key: str) -> bool:
    """Whether the dotted ``key`` is a plain field of one of RunConfig's sections
    (``arch.fifo_depth``; not ``seed``, ``arch`` or ``arch.nothing``)."""
    parts = key.split(".")
    if len(parts) != 2:
        return False
    hints, _ = _schema(RunConfig)
    section = hints.get(parts[0])
    if not dataclasses.is_dataclass(section):
        return False
    inner, fields = _schema(section)
    return parts[1] in fields and not dataclasses.is_dataclass(inner[parts[1]])


def check_leaf(key: str, value: Any, source: str = "(dict)") -> Any:
    """The section field ``key`` (:func:`is_leaf`) set to ``value`` (a :func:`plain` value),
    checked alone as :func:`config_from_dict` checks it (the same InputError): the value
    its section then holds."""
    section, name = key.split(".")
    inner, fields = _schema(_schema(RunConfig)[0][section])
    return _field(fields[name], inner[name], {name: value}, source, key)


def with_leaves(section: str, value: Any, changes: dict[str, Any], source: str = "(dict)") -> Any:
    """The section ``value`` (RunConfig's field ``section``) with ``changes``, field names to
    values from :func:`check_leaf`, after the checks across the section's fields (the same
    InputError as :func:`config_from_dict`'s): the section of a config that sets those fields."""
    out = dataclasses.replace(value, **changes)
    _across(out, source, section)
    return out


def read_yaml(path: Path) -> Any:
    """Read a YAML file; a missing file or a syntax error is an InputError naming it, and so
    is a mesh file (:func:`mesh_file_format`), with what to write to render it.

    Inside :func:`noting_reads`, the read is noted: ``("yaml", path, sha256 of the text,
    the mapping's ``extends``)`` (what a memo of a load that reads it checks)."""
    # (a regular file's first bytes alone: a pipe's or a FIFO's, once read, are gone; read_bytes' read is their one)
    format_ = mesh_file_format(path) if os.path.isfile(path) else None
    if format_ is not None:
        raise InputError(mesh_file_hint(str(path), format_), source=str(path))
    text = yaml_text(path, read_bytes)  # (one read; a mesh's bytes from a pipe told as a mesh file's are)
    data = yaml_from_text(text, path)
    if _READS.get() is not None:
        extends = data.get("extends") if isinstance(data, dict) else None
        note_read(("yaml", str(path), text_digest(text), extends if isinstance(extends, str) else None))
    return data


# the most a text file tlm reads whole (a config, a scene file, a sweep or a table) may hold: more is no such file
# (``/dev/zero``, a mesh or an image named in its place), refused before it is read, not read until memory runs out
MAX_TEXT_BYTES = 64 * 2**20


def read_text(path: Path) -> str:
    """A UTF-8 text file's text, as :func:`read_yaml` reads it: :func:`read_bytes`'s bytes decoded
    (:func:`tlm.config_read.decoded`: universal newlines; a file that is no UTF-8 text an InputError naming it)."""
    return decoded(read_bytes(path), path)


def read_bytes(path: Path) -> bytes:
    """The bytes of a text file tlm reads whole, as they are (what a piped mesh is told by, before they are decoded:
    :func:`tlm.config_read.yaml_text`); a missing or unreadable file is an InputError naming it, and so is a folder,
    a device (``/dev/zero``: no file ends it) and a file of more than :data:`MAX_TEXT_BYTES` (a pipe's read no
    further than that)."""
    if "\0" in os.fspath(path):  # (which open refuses with a ValueError)
        raise InputError("file not found (a file name holds no NUL character)", source=str(path))
    try:
        with open(path, "rb") as f:  # (a folder: IsADirectoryError, below)
            mode = os.fstat(f.fileno())
            if stat.S_ISCHR(mode.st_mode) or stat.S_ISBLK(mode.st_mode):
                raise InputError("is a device, not a file to read: name a YAML file", source=str(path))
            if mode.st_size > MAX_TEXT_BYTES:  # (in bytes: 64 MiB and 1 byte is no "64 MiB, at most 64 MiB")
                raise TooLarge(_too_large(f"{mode.st_size:,} bytes, at most"), source=str(path))
            data = _read_bounded(f, mode.st_size)
    except FileNotFoundError:
        raise InputError("file not found", source=str(path)) from None
    except IsADirectoryError:
        raise InputError("is a folder, not a file: name a YAML file", source=str(path)) from None
    except OSError as e:
        raise InputError(f"cannot read ({e.strerror})", source=str(path)) from None
    if len(data) > MAX_TEXT_BYTES:
        raise TooLarge(_too_large("more than"), source=str(path))
    return data


def _read_bounded(f: typing.BinaryIO, size: int) -> bytes:
    """At most :data:`MAX_TEXT_BYTES` + 1 bytes of ``f``: its ``size`` (and one more, for a file that grew) at
    once, then a MiB at a time (a pipe's size is not known), so that a small file's read does not ask for the
    most a file may hold (``f.read(MAX_TEXT_BYTES + 1)`` takes 64 MiB of address space: under ``ulimit -v`` a
    300-byte config was out of memory). A read of fewer bytes than asked is the end (``f`` blocks)."""
    chunks, got = [], 0
    want = min(max(size, 0) + 1, MAX_TEXT_BYTES + 1)
    while want > 0:
        chunks.append(f.read(want))
        got += len(chunks[-1])
        if len(chunks[-1]) < want:
            break
        want = min(2**20, MAX_TEXT_BYTES + 1 - got)
    return b"".join(chunks)


def _too_large(size: str) -> str:  # (read_yaml adds where a mesh goes: config_read.yaml_text)
    return f"is too large to be a YAML file tlm reads ({size} {MAX_TEXT_BYTES // 2**20} MiB)"


def file_folder(path: Path) -> Path:
    """The folder the relative paths of the file ``path`` start at: its own (links resolved); the working
    folder for an anonymous pipe's (``tlm run <(...)``: ``/proc/PID/fd/pipe:[N]`` is in none), as they were typed."""
    resolved = Path(path).resolve()
    return resolved.parent if resolved.exists() else Path.cwd()


def text_digest(text: str) -> str:
    """The sha256 of a text (as :func:`read_text` gave it): what a memo keys a file's content by."""
    return hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()


def yaml_from_text(text: str, path: Path) -> Any:
    """The data of the YAML text read from ``path``; a syntax error is an InputError naming it."""
    try:
        return parse_yaml(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        what = "YAML error" if isinstance(e, (DuplicateKeyError, ExpansionError)) else "YAML syntax error"
        raise InputError(f"{what}{where}: {problem}", source=str(path)) from None


# the files read inside noting_reads(), in their order (None: outside, none noted)
_READS: contextvars.ContextVar[list | None] = contextvars.ContextVar("tlm_reads", default=None)


@contextlib.contextmanager
def noting_reads():
    """Inside, :func:`read_yaml` and the mesh loads (:func:`tlm.scenes.cache.mesh`) note the
    files they read in the list this yields, each a tuple whose first item names its kind
    (``"yaml"``, ``"mesh"``; ``"side"``: a file a mesh's parse read beside it, with the sha256 of
    the bytes the read returned): what a memo of the load checks before it is used again
    (:func:`tlm.experiments.frames.render_key`). A scope inside another notes into its own
    list and the outer's."""
    outer = _READS.get()
    mine: list = []
    token = _READS.set(mine)
    try:
        yield mine
    finally:
        _READS.reset(token)
        if outer is not None:
            outer.extend(mine)


def note_read(record: tuple) -> None:
    """Note a file read (a tuple, its kind first) in the :func:`noting_reads` scope, if any."""
    reads = _READS.get()
    if reads is not None:
        reads.append(record)


def deep_merge(base: dict, over: dict) -> dict:
    """``over`` on top of ``base``: mappings merge key by key, anything else replaces."""
    out = dict(base)
    for k, v in over.items():
        out[k] = deep_merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


# a byte not UTF-8 in a --set value (U+DC80..U+DCFF, as the command line decodes it: ``scene=dir_\xff/x.yaml``),
# which YAML refuses, stands in as a character of plane 16's private use area while YAML reads the value
_STAND_IN = {c: c - 0xDC80 + 0x10F780 for c in range(0xDC80, 0xDD00)}
_BYTE_BACK = {s: c for c, s in _STAND_IN.items()}


def read_set_value(text: str) -> Any:
    """A ``--set`` value's text read as YAML (:func:`~tlm.config_words.parse_yaml`), a byte not UTF-8 in it
    (a surrogate: a path of a folder so named, ``scene=dir_\\xff/x.yaml``), which YAML refuses, kept as that
    surrogate in the strings it is read into (the path opens): it stands in as a character of the private use
    area while YAML reads the text, so YAML's syntax (a number, a list, a quoted string) reads as without it.
    A text that holds such a stand-in itself is read as it is."""
    if not any(ord(c) in _STAND_IN for c in text) or any(ord(c) in _BYTE_BACK for c in text):
        return parse_yaml(text)
    return _bytes_back(parse_yaml(text.translate(_STAND_IN)))


def _bytes_back(value: Any) -> Any:
    """``value`` (YAML's reading of a --set value, :func:`read_set_value`) with the stand-ins in its strings (a
    mapping's keys too) as the bytes they stand for."""
    if isinstance(value, str):
        return value.translate(_BYTE_BACK)
    if isinstance(value, list):
        return [_bytes_back(v) for v in value]
    if isinstance(value, dict):
        return {_bytes_back(k): _bytes_back(v) for k, v in value.items()}
    return value


def apply_overrides(raw: dict, overrides: list[str], source: str = "--set", cwd: Path | None = None,
                    warn: bool = True) -> dict:
    """Apply ``dotted.key=value`` strings (values parsed as YAML) to a raw mapping.
    ``cwd``: where the strings were given (the command line's working folder): a relative
    path they give to a key of :data:`PATH_KEYS` is made absolute from there
    (:func:`paths_from`), not left relative to the config's folder; so is a ``scene`` file
    found there (:func:`scene_from`). A mapping given for a section merges into it, as its dotted
    leaves would (``render={spp: 1}`` is ``render.spp=1``: :func:`~tlm.config_words.laid_over`). A ``scene``
    that a later one replaces is not warned of (:func:`~tlm.config_paths.shadowed_warning`: not the one used), nor
    any where ``warn`` is false (a ``--set scene`` that a study refuses after: h455)."""
    raw = dict(raw)
    overrides = list(overrides)
    last = max((i for i, item in enumerate(overrides) if warn and sets_scene([item])), default=-1)  # (the one used)
    for i, item in enumerate(overrides):
        if "=" not in item:
            raise InputError(f"{quoted(item)} is not of the form dotted.key=value", source=source)
        key, _, text = item.partition("=")
        if not all(part.strip() for part in key.split(".")):
            raise InputError(f"{quoted(item)}: the dotted key before '=' is empty or has an empty part", source=source)
        try:
            value = read_set_value(text)
        except yaml.YAMLError as e:  # (what is wrong with it: a key given twice, a syntax error)
            problem = (getattr(e, "problem", None) or str(e).splitlines()[0]).translate(_BYTE_BACK)
            if isinstance(e, DuplicateKeyError):
                problem = problem.replace(" (first at line 1)", "")  # (a value of one line)
            raise InputError(f"cannot parse value {quoted(text)}: {problem}", source=source, key=key) from None
        parts = key.strip().split(".")
        if cwd is not None:
            value = scene_from(value, [cwd], i == last) if parts == ["scene"] else \
                paths_from(".".join(parts), value, cwd)
        node = raw
        for p in parts[:-1]:
            child = node.get(p)
            child = dict(child) if isinstance(child, dict) else {}
            node[p] = child
            node = child
        node[parts[-1]] = config_words.laid_over(node.get(parts[-1]), value, ".".join(parts), SECTIONS)
    return raw


def load_config(path: Path | None, overrides: list[str] | None = None, via: str = "--set") -> tuple[RunConfig, Path]:
    """Load and check a run config; returns it and the folder relative paths start from.
    ``via``: how the ``overrides`` were given, as error messages name them
    (:func:`~tlm.config_words.with_overrides`)."""
    return config_from_yaml(None if path is None else read_yaml(Path(path)), path, overrides, via)


def config_from_yaml(raw: Any, path: Path | None, overrides: list[str] | None = None,
                     via: str = "--set") -> tuple[RunConfig, Path]:
    """:func:`load_config` of the file ``path`` whose YAML :func:`read_yaml` read already (``raw``): a file is
    read once, its text parsed from memory (a pipe's, ``tlm run <(...)``, has nothing left for a second read)."""
    source = "(defaults)"
    base = Path.cwd()
    overrides = None if overrides is None else list(overrides)  # (read twice: an iterator's, once; h455)
    if path is None:
        raw = {}
    else:
        source = str(path)
        base = file_folder(path)
        if raw is None or raw == {}:  # (an empty file, comments only or `{}`: not the defaults by mistake)
            what = "holds an empty mapping {}: nothing to run" if raw == {} else \
                "is empty (nothing but comments or blanks)"
            raise InputError(f"{what}: write the settings to change, e.g. `scene: cornell` (an empty config file is "
                             "not taken as the defaults: 'tlm params' lists them)", source=source)
        if not isinstance(raw, dict):
            raise InputError(f"must be a mapping of keys (key: value lines), got {yaml_kind(raw)}", source=source)
        # (the files it names: from the config's folder, once; its scene, which a --set replaces, unsaid)
        raw = files_from(raw, base, warn=not sets_scene(overrides or ()))
    if overrides:  # (command-line paths: relative to the working folder, not to the config's)
        raw = apply_overrides(raw, overrides, source=via, cwd=Path.cwd())
        source = with_overrides(source, via)
        if "scene" in raw:  # (a --set scene that is no file there: looked for beside the config, as before)
            raw = {**raw, "scene": scene_from(raw["scene"], [base])}
    return _build(RunConfig, raw, source, ""), base


def plain(value: Any) -> Any:
    """``value`` as YAML would give it: numpy scalars and arrays as Python numbers and lists,
    tuples as lists, paths as strings, throughout mappings and lists. What a notebook
    passes for a config's values (``np.int64(2)`` from ``np.arange``, ``(16, 16)``, a
    ``Path``) then reads as its plain equivalent; anything else is left to the checks."""
    if isinstance(value, dict):
        return {plain(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if hasattr(value, "dtype") and hasattr(value, "tolist"):  # (numpy, without importing it here)
        return plain(value.tolist())
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return value


def config_from_dict(raw: dict, source: str = "(dict)") -> RunConfig:
    """A run config from a mapping of its keys (:func:`plain` values), checked."""
    return _build(RunConfig, plain(raw), source, "")


# the mark, in its __dict__ (not a field: not compared, hashed nor written), of a RunConfig or a section the
# checks made (_build): frozen, of immutable values, it stays as checked (a copy or a pickle of it too); a new one
# (dataclasses.replace, RunConfig(...)) has none
_CHECKED = "_tlm_checked"


def checked(settings: RunConfig, source: str = "(RunConfig)") -> RunConfig:
    """``settings``, a RunConfig made anywhere (``dataclasses.replace`` of a loaded one, ``RunConfig(...)``),
    checked as the mapping of its values (:func:`to_dict`) is, by :func:`config_from_dict`'s rules: the same
    InputError names the key and the value (``(RunConfig): render.spp: 0 must be >= 1``); returns the RunConfig
    those checks make of it (its values as a loaded config holds them: a list as a tuple, a numpy number as
    Python's). What the checks made is not checked again: such a RunConfig is given back as it is, and such a
    section (``arch`` of ``dataclasses.replace(cfg.settings, seed=3)``) is kept (a RunConfig is the product of
    its fields: :func:`run_config_field`), so a config that changes a plain field costs microseconds."""
    if type(settings) is RunConfig and _CHECKED in settings.__dict__:
        return settings
    hints, fields = _schema(RunConfig)
    values = {}
    for name, f in fields.items():
        v = getattr(settings, name)
        if type(v) is hints[name] and _CHECKED in getattr(v, "__dict__", ()):  # (a section the checks made: as it is)
            values[name] = v
        else:  # (as config_from_dict checks the value's plain form)
            values[name] = _field(f, hints[name], {name: plain(_plain_copy(v))}, source, name)
    out = RunConfig(**values)
    out.__dict__[_CHECKED] = True
    return out


def to_dict(cfg: Any) -> dict:
    """The resolved config as plain data (every parameter, defaults included): what
    ``dataclasses.asdict`` gives (new dicts and lists throughout), without its deep copy of
    every number and string, and a list-valued setting (held as a tuple) as the list YAML writes."""
    return _plain_copy(cfg)


_ATOMS = (str, int, float, bool, type(None))  # (deepcopy gives them back as they are)
_NAMES: dict[type, tuple[str, ...]] = {}  # a dataclass's field names


def _plain_copy(obj: Any) -> Any:
    """dataclasses.asdict's walk (a dataclass instance to a dict of its fields, lists and dicts
    copied, a tuple as a list, anything else deep-copied), atoms returned as they are."""
    if type(obj) in _ATOMS:
        return obj
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        names = _NAMES.get(type(obj))
        if names is None:
            names = _NAMES[type(obj)] = tuple(f.name for f in dataclasses.fields(obj))
        return {name: _plain_copy(getattr(obj, name)) for name in names}
    if isinstance(obj, tuple) and hasattr(obj, "_fields"):  # a namedtuple
        return type(obj)(*[_plain_copy(v) for v in obj])
    if isinstance(obj, (list, tuple)):  # (a tuple too: a config's list-valued setting, which YAML writes as a list)
        return [_plain_copy(v) for v in obj]
    if isinstance(obj, dict):
        return type(obj)((_plain_copy(k), _plain_copy(v)) for k, v in obj.items())
    return copy.deepcopy(obj)


def describe(cls: type = RunConfig, prefix: str = "") -> list[tuple[str, Any, str]]:
    """(dotted key, default, help) for every parameter: the documentation of the schema."""
    out = []
    hints, fields = _schema(cls)
    for f in fields.values():
        key = f"{prefix}{f.name}"
        if dataclasses.is_dataclass(hints[f.name]):
            out.extend(describe(hints[f.name], key + "."))
        else:
            out.append((key, f.default, f.metadata.get("help", "")))
    return out


# the dotted keys of RunConfig's sections (render, arch, ...): a mapping given for one merges into it (laid_over)
SECTIONS = frozenset(k.rsplit(".", i)[0] for k, _, _ in describe() for i in range(1, k.count(".") + 1))
