"""A config's YAML, both ways: how a text reads as values, and how a value is said back.

Reading: :func:`parse_yaml` is PyYAML's safe loader with YAML 1.2 floats (``1e6`` is a
number, not the string '1e6') that refuses a key given twice (:class:`DuplicateKeyError`).
Saying: the error messages of tlm name a value as a user writes it in YAML
(:func:`value_text`: ``two``, ``null``, ``1e9``, ``[64, 64]``), what a config field holds
in YAML's words (:func:`type_name`: ``an integer or null``), what to write instead
(:func:`type_hint`), what a file holds that is not a mapping (:func:`yaml_kind`) and a
config with overrides (:func:`with_overrides`). Writing: :class:`Dumper` (:func:`dump_yaml`; on one
line, :func:`flow_text`), YAML that :func:`parse_yaml` reads back the same. They live together because a
string is said and written bare only where :func:`parse_yaml` reads it back as that string. A value given for a
key over the value there (``--set render={spp: 1}``, a sweep's ``set:``): :func:`laid_over`, and why
an empty one there (``--set render={}``) sets nothing: :func:`sets_nothing`. Items listed in a line
(``a, b, c and 5 more``): :func:`listing`. Lines of one kind that differ only in their numbers (a warning
each run says with its own figures): :func:`number_form`.
"""

from __future__ import annotations

import decimal
import json
import math
import re
import types
import typing
from collections.abc import Collection, Iterable, Iterator, Mapping
from typing import Any

import yaml

from tlm.errors import InputError, did_you_mean


class DuplicateKeyError(yaml.constructor.ConstructorError):
    """A mapping names one key twice (YAML forbids it; PyYAML would keep the last silently)."""


class ExpansionError(yaml.composer.ComposerError):
    """A document whose aliases (``*name``) expand it to more values than :data:`MAX_EXPANDED` past
    its own (a "billion laughs": a few hundred bytes that every walk of the values, a check or a
    message, would take minutes over)."""


# values that a document's aliases may add to it, expanded (a config or a scene holds a few hundred)
MAX_EXPANDED = 1_000_000


def _expanded(node: yaml.Node, sizes: dict[int, int]) -> int:
    """The values that ``node`` holds once its aliases are expanded, each node counted once per
    place it appears (``sizes``: by node, those counted; a node inside itself, ``&a [*a]``, once)."""
    size = sizes.get(id(node))
    if size is not None:
        return size
    sizes[id(node)] = 1  # (a node met again inside itself: counted once)
    children = node.value if isinstance(node, yaml.SequenceNode) else \
        [n for pair in node.value for n in pair] if isinstance(node, yaml.MappingNode) else []
    size = 1
    for child in children:
        size += _expanded(child, sizes)
        if size > 4 * MAX_EXPANDED:  # (enough to refuse it: not counted to its billions)
            break
    sizes[id(node)] = size
    return size


def refuse_expansion(node: yaml.Node | None) -> yaml.Node | None:
    """``node``, a composed document, or an :class:`ExpansionError` where its aliases expand it to more
    than :data:`MAX_EXPANDED` values past its own: the check of every loader that reads a file tlm may
    walk (:func:`parse_yaml`'s; :func:`tlm.report.checks.read_yaml`'s, of a folder's YAML)."""
    sizes: dict[int, int] = {}
    if node is not None and _expanded(node, sizes) - len(sizes) > MAX_EXPANDED:
        raise ExpansionError(
            None, None, f"its aliases (*name) expand it to more than {MAX_EXPANDED:,} values: write each "
            "value out, or alias fewer", node.start_mark)
    return node


class _Loader(yaml.SafeLoader):
    """SafeLoader that reads ``1e6`` as a float (YAML 1.2), not as the string '1e6', and
    refuses a key given twice in one mapping (:class:`DuplicateKeyError`), which PyYAML
    would read as the last one, dropping the first (a second ``render:`` section would
    silently undo the first). Keys that a merge (``<<: *anchor``) brings in may be set
    again, as YAML allows."""

    def compose_document(self):
        return refuse_expansion(super().compose_document())

    def flatten_mapping(self, node):
        # (checked before PyYAML's flattening rewrites the node in place with its merged keys,
        # and once per node: a node merged twice is already flattened the second time)
        checked = self.__dict__.setdefault("_checked", set())
        if id(node) not in checked:
            checked.add(id(node))
            first: dict = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    mark = first.setdefault(key, key_node.start_mark)
                except TypeError:  # (an unhashable key: the constructor's own error names it)
                    continue
                if mark is not key_node.start_mark:
                    raise DuplicateKeyError(
                        None, None, f"duplicate key {key!r} (first at line {mark.line + 1}): give each key once",
                        key_node.start_mark)
        super().flatten_mapping(node)


_Loader.yaml_implicit_resolvers = {k: list(v) for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+][0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


class _CheckedSafeLoader(yaml.SafeLoader):
    """PyYAML's SafeLoader (YAML 1.1, as ``yaml.safe_load``) with :func:`refuse_expansion`'s check."""

    def compose_document(self):
        return refuse_expansion(super().compose_document())


def safe_load(text: str) -> Any:
    """``yaml.safe_load(text)``, but an :class:`ExpansionError` (a ``yaml.YAMLError``) where its aliases
    expand it past :data:`MAX_EXPANDED` values: for a file tlm wrote (a point's ``config.resolved.yaml``, a
    sweep's ``sweep.yaml``) that a damaged or hostile copy could make a few hundred bytes long and endless."""
    return yaml.load(text, Loader=_CheckedSafeLoader)


def parse_yaml(text: str) -> Any:
    """YAML text to data, with YAML 1.2 floats."""
    return yaml.load(text, Loader=_Loader)


class Dumper(yaml.SafeDumper):
    """PyYAML's safe dumper (``yaml.safe_dump``'s), but it writes a string bare only where :func:`parse_yaml`
    reads it back as that string: a string that YAML 1.1 holds as text and tlm's reader as a number
    (``1e3``, ``+1.0e-3``, ``.5e+3``: YAML 1.2 floats) is quoted, as a number, a date, a boolean or a null
    written as text already was (``'1e3'``). It tells them by the reader's own implicit resolvers: any other
    value is written as ``yaml.safe_dump`` writes it, byte for byte."""


Dumper.yaml_implicit_resolvers = {k: list(v) for k, v in _Loader.yaml_implicit_resolvers.items()}

if hasattr(yaml, "CSafeDumper"):
    class CDumper(yaml.CSafeDumper):
        """:class:`Dumper` with libyaml's emitter (a quarter of the time; the resolvers are Python's)."""

    CDumper.yaml_implicit_resolvers = Dumper.yaml_implicit_resolvers
else:  # (PyYAML built without libyaml)
    CDumper = None  # type: ignore[assignment,misc]


def dump_yaml(data: Any, **kwargs: Any) -> str:
    """``yaml.safe_dump(data, **kwargs)`` by :class:`Dumper`: the YAML text of a file tlm writes for itself or
    a user to read back (``config.resolved.yaml``, ``sweep.yaml``, an exported scene), read back the same by
    :func:`parse_yaml` and by ``yaml.safe_load``; ``kwargs``: ``yaml.dump``'s (``sort_keys=False``)."""
    return yaml.dump(data, Dumper=Dumper, **kwargs)


_BREAKS = ("\n", "\r", "\x85", "\u2028", "\u2029")  # (what YAML reads as a line break)


class _OneLine(Dumper):
    """:class:`Dumper` that writes a string of a line break double-quoted and escaped (``"a\\nb"``), in a list
    or a mapping too: YAML's flow style folds a quoted one onto more lines (``['a\\n\\n  b']``)."""


def _one_line_str(dumper: Dumper, data: str) -> yaml.ScalarNode:
    style = '"' if any(c in data for c in _BREAKS) else None
    return dumper.represent_scalar("tag:yaml.org,2002:str", data, style=style)


_OneLine.add_representer(str, _one_line_str)


def flow_text(value: Any) -> str:
    """``value`` on one line as YAML's flow style writes it (:class:`Dumper`'s, its characters as they are):
    ``[16, 16]``, ``{spp: 2}``, ``cornell``; a string quoted only where :func:`parse_yaml` would read it as
    another value or it needs quotes (``'1e3'``, ``'true'``); one of a line break, or that would not read
    back the same, double-quoted and escaped (``"a\\nb"``), in a list or a mapping too (:class:`_OneLine`).
    What a ``--set`` or a config file takes."""
    said = yaml.dump(value, Dumper=Dumper if isinstance(value, str) else _OneLine, default_flow_style=True,
                     allow_unicode=True, width=1 << 30)
    said = said.strip().removesuffix("...").strip()  # (a bare scalar's document end)
    if isinstance(value, str) and (any(c in said for c in _BREAKS) or _read(said) != value):
        said = yaml.dump(value, Dumper=Dumper, default_style='"', width=1 << 30).strip()
    return said


def _read(said: str) -> Any:
    """What :func:`parse_yaml` reads the text ``said`` as (None where it reads nothing)."""
    try:
        return parse_yaml(said)
    except yaml.YAMLError:
        return None


def value_text(v: Any, limit: int = 80) -> str:
    """A config value as a user writes it in YAML, for error messages: ``two`` (not ``'two'``),
    ``null``, ``true``, ``1e9`` (a float of a whole number from a million on by its exponent,
    not ``1000000000.0``), ``[64, 64]``, ``{spp: 2}``; a string quoted only where YAML would read
    it as something else (``'3'``, ``''``, ``'null'``). Cut to about ``limit`` characters."""
    if v is None:
        text = "null"
    elif isinstance(v, bool):
        text = "true" if v else "false"
    elif isinstance(v, float):
        text = _float_text(v)
    elif isinstance(v, int):
        text = str(v) if v.bit_length() <= 256 else f"a whole number of {len(str(abs(v)))} digits"
    elif isinstance(v, str):
        text = _string_text(v)
    elif isinstance(v, (list, tuple)):
        text = _joined("[", (value_text(x, limit) for x in v), "]", limit)
    elif isinstance(v, dict):
        text = _joined("{", (f"{value_text(k, limit)}: {value_text(x, limit)}" for k, x in v.items()), "}", limit)
    else:
        text = _string_text(str(v))
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _joined(opening: str, items: Iterator[str], closing: str, limit: int) -> str:
    """``items`` between ``opening`` and ``closing``, comma-separated, taken only until the text
    passes ``limit`` characters (:func:`value_text` cuts it there): a list of a million items, or
    one that YAML's aliases make of millions (``&a [*b, *b, ...]``), is said after a few."""
    parts: list[str] = []
    size = len(opening)
    for item in items:
        if size > limit:  # (more past the limit: said so, not shown as the whole)
            parts.append("...")
            break
        parts.append(item)
        size += len(item) + 2
    return opening + ", ".join(parts) + closing


def _float_text(v: float) -> str:
    """A float as a user writes it: ``0.5``, ``1e9``, ``1.5e-7``; ``nan``, ``inf`` and ``-inf``
    as the other messages of tlm name them (YAML's ``.nan``, ``.inf``)."""
    text = repr(v)
    if not math.isfinite(v):
        return text
    if "e" in text or (v.is_integer() and abs(v) >= 1e6):
        mantissa, _, exponent = f"{decimal.Decimal(text).normalize():e}".partition("e")
        return f"{mantissa}e{int(exponent)}"
    return text


def _string_text(v: str) -> str:
    """A string as YAML would need it written: bare where it reads back as that string on
    one line, else in quotes."""
    if v and v == v.strip() and "\n" not in v:
        try:
            if parse_yaml(v) == v and ": " not in v and " #" not in v:
                return v
        except yaml.YAMLError:
            pass
    return "'" + v.replace("'", "''") + "'" if "\n" not in v else json.dumps(v, ensure_ascii=False)


def type_name(tp: Any, meta: Mapping[str, Any] | None = None) -> str:
    """What a field of type ``tp`` (its ``metadata``: ``meta``) holds, in the words of YAML:
    ``an integer or null``, ``a list of 2 integers (e.g. [64, 64]) or null``."""
    meta = meta or {}
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(tp)
        names = [type_name(a, meta) for a in args if a is not type(None)]
        text = " or ".join(names)
        return f"{text} or null" if type(None) in args else text
    if tp is type(None):
        return "null"
    if tp is bool:
        return "true or false"
    if tp is int:
        return "an integer"
    if tp is float:
        return "a number"
    if tp is str:
        if "choices" in meta:
            return f"one of {', '.join(meta['choices'])}"
        return "a string"
    if (inner := item_type(tp)) is not None:  # (a list in YAML's words, though the config holds a tuple)
        plural = {int: "integers", float: "numbers", str: "strings", bool: "trues or falses"}.get(inner)
        if plural is None:
            plural = f"items each {type_name(inner)}"
        count = f"{meta['length']} " if "length" in meta else ""
        example = f" (e.g. {meta['example']})" if "example" in meta else ""
        return f"a list of {count}{plural}{example}"
    raise TypeError(f"no words for the config type {tp}")  # (tests/test_config_messages.py tries every field)


def item_type(tp: Any) -> Any:
    """The type of the items of a list-valued setting of type ``tp``, a list in YAML held as a tuple
    (``tuple[int, ...]``: ``int``; ``list[int]`` too); None for any other type."""
    return typing.get_args(tp)[0] if typing.get_origin(tp) in (list, tuple) else None


def type_hint(v: Any, tp: Any, meta: Mapping[str, Any]) -> str:
    """What to write instead, for a value of the wrong type: a float of a whole number where an
    integer goes (``1e9``: YAML reads a number with an exponent or a point as a float), a number
    or a bool where text goes."""
    wants = set(typing.get_args(tp)) | {tp}
    lists = [a for a in wants if item_type(a) is not None]
    items = v if isinstance(v, list) and lists else [v]
    whole_int = int in wants or any(item_type(a) is int for a in lists)
    floats = [x for x in items if isinstance(x, float) and math.isfinite(x) and x.is_integer()]
    if whole_int and floats and len(floats) == len([x for x in items if not isinstance(x, int)]):
        x = floats[0]
        whole = f"write {int(x)}" if abs(x) < 1e21 else "write it as a whole number"  # (not 300 digits)
        return f": {value_text(x)} reads as a float (a number written with an exponent or a decimal point); {whole}"
    if str in wants and "choices" not in meta and isinstance(v, (int, float)):  # (a bool too: YAML's true, yes)
        return f" (quote it, '{value_text(v)}', to give it as text)"
    return ""


def with_overrides(source: str, via: str = "--set") -> str:
    """What error messages call the config ``source`` with overrides applied: ``cornell.yaml,
    with --set`` (``via``: how they were given, ``--set`` on the command line, ``the
    overrides`` through the API)."""
    return f"{source}, with {via}"


def laid_over(old: Any, new: Any, key: str, sections: Collection[str]) -> Any:
    """``new``, given for the dotted ``key``, over the value ``old`` there: a mapping given for one of
    ``sections`` (the config's, :data:`tlm.config.SECTIONS`) merges into the section's mapping key by key,
    recursively, as its dotted leaves given one by one would (``render={spp: 1}`` is ``render.spp=1``: the
    section's other keys are kept, as OmegaConf merges); anything else replaces ``old`` (``render=null``: the
    section at its defaults; a setting's value, a mapping too: the config has no mapping-valued setting)."""
    if not (isinstance(new, dict) and isinstance(old, dict) and key in sections):
        return new
    return {**old, **{k: laid_over(old.get(k), v, f"{key}.{k}", sections) for k, v in new.items()}}


def sets_nothing(null: str, then: str = "") -> str:
    """Why a mapping that names no key, given for a section (``--set render={}``, a sweep's ``set:
    {render: {}}`` or a factor's value ``{}``), changes nothing: :func:`laid_over` merges it into the
    section key by key (before, it gave the section at its defaults); ``then``: what follows of that,
    where said (a sweep factor's points: the base's section); ``null``: what gives the section at its
    defaults, as it is given there (``--set render=null``)."""
    return (f"sets nothing (a mapping given for a section merges into it key by key, and this one names no key)"
            f"{f': {then}' if then else ''}; {null} gives the section at its defaults")


def yaml_kind(value: Any) -> str:
    """A YAML value's kind in words (``a list``), for a file that is not the mapping it should be."""
    if isinstance(value, bool):
        return "true or false"
    if isinstance(value, (int, float)):
        return f"the number {value_text(value)}"
    if isinstance(value, str):
        return f"the text {value_text(value)}"
    if isinstance(value, list):
        return "a list"
    return "something else"


# the checks of a config value against its field's metadata (tlm.config's, out of that module)
def whole_floats(v: Any) -> str:  # numbers, a finite whole float among them (1e20): v as typed (1e5, not 100000.0)
    xs = v if isinstance(v, list) else [v]
    t = f"{v:.3g}".replace("e+0", "e").replace("e+", "e") if type(v) is float and abs(v) >= 1e4 else ""
    ok = all(type(x) in (int, float) for x in xs) and any(type(x) is float and x.is_integer() for x in xs)
    return "" if not ok else t if "e" in t and float(t) == v else value_text(v)


def check_bounds(v: Any, meta: dict, source: str, key: str, text: str = "") -> None:  # (> 0.0 and >= 1.0 at once)
    lo_ex, lo, hi = meta.get("min_exclusive"), meta.get("min"), meta.get("max")
    for x in [x for x in (v if isinstance(v, list) else [v]) if isinstance(x, (int, float))]:
        if bound := (f"> {value_text(lo_ex)}" + (f" and >= {value_text(lo)}" if lo is not None else "")
                     if lo_ex is not None and x <= lo_ex else f">= {value_text(lo)}" if lo is not None and x < lo
                     else f"<= {value_text(hi)}" if hi is not None and x > hi else ""):
            raise InputError(f"{text or value_text(v)} must be {bound}", source=source, key=key)


def check_range(v: Any, meta: dict, source: str, key: str) -> None:
    if v is None:
        return
    if "choices" in meta and v not in meta["choices"]:
        raise InputError(
            f"{value_text(v)} is not one of {', '.join(meta['choices'])}{did_you_mean(str(v), meta['choices'])}",
            source=source, key=key,
        )
    if "length" in meta and len(v) != meta["length"]:
        raise InputError(f"{value_text(v)} must have {meta['length']} entries", source=source, key=key)
    items = v if isinstance(v, list) else [v]
    check_bounds(v, meta, source, key)
    if key == "resolution" and any(x <= 0 for x in items):
        raise InputError(f"{value_text(v)} must be positive", source=source, key=key)
    if key == "render.light_samples" and math.isqrt(v) ** 2 != v:
        raise InputError(f"{value_text(v)} must be a square number (1, 4, 9, 16, ...)", source=source, key=key)


def listing(items: Iterable[str], named: int | None = None, more: str = "more", whole: int | None = None,
            last: str = "and") -> str:
    """``items`` said in a line (each as ``str`` gives it), the last after ``last``: ``a``, ``a and b``, ``a, b and
    c`` (``a, b or c``; none: ``""``); of more than ``whole`` (``named`` + 1 unless given, and never less: one left
    over is named, never "and 1 more"), the first ``named`` and how many more: ``a, b, c and 5 more`` (``more``:
    the words after the count, ``more files``; ``a, b, c or 5 more`` of ``last`` "or"). ``named`` None: every
    item. The one way tlm's notes and messages list names, points and files."""
    items = [str(item) for item in items]  # (read once: a generator is consumed here, and only here)
    if named is not None and len(items) > max(named + 1, whole or 0):
        return f"{', '.join(items[:named])} {last} {len(items) - named} {more}" if named else f"{len(items)} {more}"
    return "".join(items) if len(items) < 2 else f"{', '.join(items[:-1])} {last} {items[-1]}"


_NUMBER = re.compile(r"[0-9]+(?:\.[0-9]+)?")


def number_form(line: str) -> str:
    """``line`` with each of its numbers masked as ``#`` (``moved by 0.14%`` and ``moved by 0.29%`` are both
    ``moved by #%``): the lines of one kind that ``tlm sweep``'s stderr and the report's warnings box say once,
    with how many wordings they had."""
    return _NUMBER.sub("#", line)
