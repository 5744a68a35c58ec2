"""A tlm file the report reads, read whole and checked (out of :mod:`tlm.report.collect`, which
imports these by their old names): a JSON or YAML file tlm writes whole (:func:`read_json`,
:func:`read_yaml`: a damaged copy is an :class:`~tlm.errors.InputError` naming it), the kinds of
value a check wants (:data:`PRESENT`, :data:`NUMBER`, ... :data:`COUNT`), :func:`check` of a
record's keys against them, and a run's ``results.json`` checked for what the sections read of it
(:func:`read_results`). The study tables' columns and keys, and the reading of a study folder,
stay in :mod:`tlm.report.collect`."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import yaml

from tlm.config import MODES
from tlm.config_words import MAX_EXPANDED, ExpansionError, listing, refuse_expansion, safe_load
from tlm.errors import InputError
from tlm.experiments.thesis import OURS_CYCLES


def read_json(path: Path) -> Any:
    """A JSON file tlm writes whole: an :class:`InputError` naming it where it cannot be read or
    is not JSON (empty, cut off, edited: a damaged copy)."""
    try:
        text = path.read_text(encoding="utf-8")  # (as tlm writes it, whatever the locale)
    except (OSError, ValueError) as e:  # (ValueError: not text, UnicodeDecodeError)
        raise InputError(f"cannot read: {getattr(e, 'strerror', None) or e}", source=str(path)) from None
    if not text.strip():
        raise InputError("is empty (cannot read it as JSON): a damaged copy (tlm writes it whole)", source=str(path))
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        cut = not text.rstrip().endswith(("}", "]"))  # (tlm's JSON files are an object or a list: it ends early)
        raise InputError(f"is {'cut off' if cut else 'not valid JSON'} (cannot read it as JSON: {e.msg}: line "
                         f"{e.lineno} column {e.colno}): a damaged copy (tlm writes it whole)",
                         source=str(path)) from None
    except ValueError as e:
        raise InputError(f"is not valid JSON (cannot read it as JSON: {e}): a damaged copy (tlm writes it whole)",
                         source=str(path)) from None


def number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


# a check: (test, what the value should be)
PRESENT = (lambda v: True, "present")
TEXT = (lambda v: isinstance(v, str), "text")
NUMBER = (number, "a number")
NUMBER_OR_NONE = (lambda v: v is None or number(v), "a number or empty")
POSITIVE = (lambda v: number(v) and v > 0, "a positive number")
BOOL = (lambda v: isinstance(v, bool), "true or false")
MAPPING = (lambda v: isinstance(v, dict), "a mapping")
MAPPING_OR_NONE = (lambda v: v is None or isinstance(v, dict), "a mapping")
LIST_OR_NONE = (lambda v: v is None or isinstance(v, list), "a list")
TEXTS = (lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v), "a list of texts")

FINITE = (lambda v: number(v) and math.isfinite(v), "a finite number")
FINITE_OR_NONE = (lambda v: v is None or FINITE[0](v), "a finite number or empty")


def check(record: Any, path: Path, where: str | None, what: str, required: dict, optional: dict | None = None) -> None:
    """An :class:`InputError` naming ``path`` (and ``where`` in it: a line, a key) unless
    ``record`` is a mapping with every ``required`` key and every key (of ``required`` and
    of ``optional`` where present) of the value its check wants."""
    if not isinstance(record, dict):
        raise InputError(f"is {type(record).__name__} {short(record)}, not {what}", source=str(path), key=where)
    missing = [k for k in required if k not in record]
    if missing:
        raise InputError(f"has no {', '.join(repr(k) for k in missing)}: not {what}", source=str(path), key=where)
    for k, (ok, want) in {**(optional or {}), **required}.items():
        if k in record and not ok(record[k]):
            raise InputError(f"{k!r} is {short(record[k])}, not {want} ({what})", source=str(path), key=where)


def short(v: Any) -> str:
    text = repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


def rows_checked(path: Path, rows: list[tuple[int, dict]], what: str, required: dict,
                 optional: dict | None = None) -> list[dict]:
    for n, row in rows:
        check(row, path, f"line {n}", what, required, optional)
    return [row for _, row in rows]


# libyaml's parser (``yaml.CSafeLoader``: 5-7 times faster on a point's config.resolved.yaml, the same values);
# None where PyYAML was built without libyaml. read_yaml's loaders check one thing a config's loader checks: a
# document whose aliases expand it past MAX_EXPANDED values (a damaged or hostile copy), refused; not duplicate keys
# (tlm writes these files whole; tlm.config reads a user's YAML with that check too).
# (Where they differ, in no file tlm writes: libyaml reads a tab after a key's colon, which PyYAML refuses, and a
# bare ``!`` tag as '', which PyYAML reads as null.)
# PyYAML's own parser: :func:`tlm.config_words.safe_load` (its SafeLoader with that check).
_C_LOADER = getattr(yaml, "CSafeLoader", None)
if _C_LOADER is not None:
    class _CSafe(_C_LOADER):
        """libyaml's SafeLoader with :func:`~tlm.config_words.safe_load`'s check of its aliases
        (:func:`~tlm.config_words.refuse_expansion`)."""

        def get_single_node(self):
            return refuse_expansion(super().get_single_node())

    _C_LOADER = _CSafe
# libyaml's composer recurses on the C stack: a file nested tens of thousands deep (a damaged one: 100 kB of "[")
# ends the process (SIGSEGV), where PyYAML's own parser raises RecursionError. A node is nested no deeper than the
# flow collections ("[", "{") around it and twice its column + 1 (a block node starts right of its parent's, or at
# its column for a sequence under a key): a file whose bound is over this is read by PyYAML's parser (which reads
# none nested more than a few hundred deep).
C_DEPTH = 1000


def _shallow(text: str) -> bool:
    """Whether ``text`` cannot be nested deeper than :data:`C_DEPTH` (lines split at "\\n" only: YAML's own are
    no longer)."""
    if len(text) <= C_DEPTH // 2 - 1:  # (n characters nest no deeper than n)
        return True
    return text.count("[") + text.count("{") + 2 * (max(map(len, text.split("\n"))) + 1) <= C_DEPTH


def read_yaml(path: Path) -> Any:
    """A YAML file tlm writes whole (a point's ``config.resolved.yaml``, a sweep's ``sweep.yaml``): an
    :class:`InputError` naming it where it cannot be read or is not YAML."""
    try:
        text = path.read_text(encoding="utf-8")  # (as tlm writes it, whatever the locale)
    except (OSError, ValueError) as e:
        raise InputError(f"cannot read: {getattr(e, 'strerror', None) or e}", source=str(path)) from None
    if _C_LOADER is not None and _shallow(text):
        try:
            return yaml.load(text, Loader=_C_LOADER)  # (a safe loader: libyaml's SafeLoader)
        except ExpansionError as e:
            raise _expansion(e, path) from None
        except yaml.YAMLError:  # (read again by PyYAML's own parser: its error, worded as tlm words it)
            pass
    try:
        return safe_load(text)  # (a safe loader: PyYAML's SafeLoader, with the check)
    except ExpansionError as e:
        raise _expansion(e, path) from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        at = f": line {mark.line + 1} column {mark.column + 1}" if mark is not None else ""
        raise InputError(f"is not valid YAML (cannot read: {str(getattr(e, 'problem', None) or e).splitlines()[0]}"
                         f"{at}): a damaged or edited copy (tlm writes it whole)", source=str(path)) from None
    except RecursionError:
        raise InputError("is nested too deeply to read (more than PyYAML's parser reads): a damaged or edited copy "
                         "(tlm writes it whole)", source=str(path)) from None


def _expansion(e: ExpansionError, path: Path) -> InputError:
    """:func:`read_yaml`'s refusal of a file whose aliases expand it past the limit, naming it."""
    return InputError(f"its aliases (*name) expand it to more than {MAX_EXPANDED:,} values: a damaged or edited "
                      "copy (tlm writes it whole, without aliases)", source=str(path))


COUNT = (lambda v: FINITE[0](v) and v >= 0, "a finite number, not negative")
COUNT_OR_NONE = (lambda v: v is None or COUNT[0](v), "a finite number, not negative, or empty")
MODE_OR_NONE = (lambda v: v is None or v in MODES, f"a mode ({', '.join(MODES)})")
# what the sections read of a run's results.json (:func:`read_results`): its keys, then the counts in them
RESULTS_KEYS = {"scene": MAPPING, "timing": MAPPING_OR_NONE}
RESULTS_OPTIONAL = {"mode": MODE_OR_NONE, "fps": COUNT_OR_NONE, "cycles": MAPPING_OR_NONE, "work": MAPPING_OR_NONE,
                    "photons": MAPPING_OR_NONE, "plan": MAPPING_OR_NONE, "image": MAPPING_OR_NONE,
                    "error": MAPPING_OR_NONE, "host_seconds": MAPPING_OR_NONE, "factors": MAPPING_OR_NONE,
                    "warnings": LIST_OR_NONE, "overrides": LIST_OR_NONE}
SCENE_KEYS = {"name": (lambda v: isinstance(v, str | int | float) and not isinstance(v, bool), "a name")}
SCENE_OPTIONAL = {"source": (lambda v: v is None or isinstance(v, str), "a path or empty"),
                  "resolution": (lambda v: v is None or (isinstance(v, list) and len(v) == 2 and all(
                      isinstance(x, int) and not isinstance(x, bool) and x > 0 for x in v)), "[width, height]"),
                  "triangles": COUNT_OR_NONE, "bsp": MAPPING_OR_NONE}
LIST = (lambda v: isinstance(v, list), "a list")
TIMING_OPTIONAL = {"units": MAPPING, "frame_times": LIST, "pipelines": LIST,
                   "images_in_flight": (lambda v: v is None or (isinstance(v, int) and not isinstance(v, bool)
                                                                and v > 0), "a positive whole number or empty")}
CYCLES_KEYS = dict.fromkeys(OURS_CYCLES, COUNT)  # (the cycles the thesis tables read of a run)
IMAGE_OPTIONAL = {"exposure": (lambda v: v is None or (FINITE[0](v) and v > 0), "a positive finite number or empty")}
ERROR_OPTIONAL = {"rel_mse": FINITE_OR_NONE}


def counts(value: Any, path: Path, where: str, none: bool = False) -> None:
    """An :class:`InputError` naming ``path`` and the key ``where`` unless every value in the mapping ``value``
    (at any depth) is a finite number, not negative (true or false allowed; empty where ``none``)."""
    if isinstance(value, dict):
        for k, v in value.items():
            counts(v, path, f"{where}.{k}", none)
    elif not (isinstance(value, bool) or COUNT[0](value) or (none and value is None)):
        raise InputError(f"is {short(value)}, not {COUNT[1]}: an edited or damaged copy (tlm writes its counts)",
                         source=str(path), key=where)


def read_results(path: Path) -> dict:
    """A run's ``results.json``, checked for what the sections read of it: an :class:`InputError`
    naming the file and the key for one of another type, a count that is not a finite number or is
    negative (``cycles``, ``fps``, ``work``, ``timing.units``), a ``cycles`` without one the thesis tables
    read (:data:`CYCLES_KEYS`), or a mode tlm does not know."""
    results = read_json(path)
    if not isinstance(results, dict) or "timing" not in results or "scene" not in results:
        raise InputError("is not a tlm results file (no 'timing' or 'scene')", source=str(path))
    what = "a tlm results file"
    check(results, path, None, what, RESULTS_KEYS, RESULTS_OPTIONAL)
    check(results["scene"], path, "scene", what, SCENE_KEYS, SCENE_OPTIONAL)
    if results["timing"] is not None:  # (tlm writes cycles, fps and timing together, or all three empty)
        empty = [k for k in ("cycles", "fps") if k in results and results[k] is None]
        if empty:
            raise InputError(f"{listing(repr(k) for k in empty)} {'is' if len(empty) == 1 else 'are'} empty "
                             "but 'timing' is not: an edited or damaged copy (tlm writes them together)",
                             source=str(path))
    for key, optional in (("timing", TIMING_OPTIONAL), ("image", IMAGE_OPTIONAL), ("error", ERROR_OPTIONAL)):
        if results.get(key) is not None:
            check(results[key], path, key, what, {}, optional)
    for key, none in (("cycles", False), ("work", True)):
        counts(results.get(key) or {}, path, key, none)
    counts(((results.get("photons") or {}).get("work")) or {}, path, "photons.work", True)
    if results.get("cycles") is not None:  # (tlm writes every PM's cycles and TThru: the thesis tables read them)
        check(results["cycles"], path, "cycles", what, CYCLES_KEYS)
    for name, unit in ((results.get("timing") or {}).get("units") or {}).items():
        if not isinstance(unit, dict):
            raise InputError(f"is {short(unit)}, not a mapping ({what})", source=str(path), key=f"timing.units.{name}")
        counts(unit, path, f"timing.units.{name}")
    return results
