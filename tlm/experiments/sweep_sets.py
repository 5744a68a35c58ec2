"""A sweep's ``--set`` strings (``tlm sweep --set``, :func:`tlm.experiments.sweep_file.load_sweep`):
the keys each sets (:func:`~tlm.experiments.study.set_leaves`, which the studies' refusal shares), the
one refused for setting a factor's key, which a point's error a ``--set``
gave; and the words of the warnings on what no point reads (:class:`~tlm.experiments.sweep_file.Sweep`'s
``inert_factors``, ``inert_sets``, ``unread_factors``).
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from tlm.config_words import flow_text, listing
from tlm.errors import InputError, shell_word
from tlm.experiments.study import override_key, refuse_set, set_leaves

_NUMBER = re.compile(r"(\d+(?:\.\d+)?)")  # (a split on it: the text between at even places, numbers at odd)


def said_once(whys) -> str:
    """The points' reasons for a factor that changed nothing, each said once: reasons that differ
    in one number only (each point's value: "alone at depth 1 and at 1024", "... depth 16 and at
    1024 ...") are one, that number listed ("alone at depth 1, 16 or 256 and at 1024"); others
    apart, all joined by "; "."""
    groups: dict[tuple, list[list[str]]] = {}
    for why in sorted(set(whys)):
        parts = _NUMBER.split(why)
        groups.setdefault(tuple(parts[::2]), []).append(parts)
    out = []
    for members in groups.values():
        varied = [i for i in range(1, len(members[0]), 2) if len({m[i] for m in members}) > 1]
        if len(varied) != 1:  # (the same text; or numbers that vary together: said apart, as they pair)
            out.extend("".join(m) for m in members)
            continue
        at = varied[0]
        values = sorted({m[at] for m in members}, key=float)
        listed = listing(values, last="or")
        out.append("".join(listed if i == at else part for i, part in enumerate(members[0])))
    return "; ".join(sorted(out))


def refuse_factor_sets(overrides: Iterable[str], factors: dict[str, str], src: str) -> None:
    """An InputError for the first ``--set`` string of ``overrides`` that sets a factor's key (``factors``:
    key -> where, ``grid``), or a section above or below one: the factor would win unsaid. A section given
    as a mapping (``bsp={memory_factor: 10}``) merges into the base's section, as ``tlm run --set`` does
    (:func:`~tlm.experiments.study.set_leaves`), and is taken where none of its keys is a factor's (each point
    then gets its factor's value in it); one that sets a factor's key is refused, naming its other keys in the
    dotted form that a sweep takes."""
    why = "which gives each point its value: change its values in the sweep file, not by --set"
    for item in overrides:
        key = override_key(item)
        leaves = set_leaves(item)
        touched = [(leaf, f) for leaf in leaves for f in factors if given_by(leaf, [f])]
        if not touched:
            continue
        if list(leaves) == [key] or not any(f.startswith(key + ".") for _, f in touched):
            refuse_set([item], {f: f"a factor of the sweep ({factors[f]}.{f}), {why}" for _, f in touched}, src)
        f = next(f for _, f in touched if f.startswith(key + "."))
        others = [f"--set {shell_word(f'{k}={flow_text(v)}')}" for k, v in leaves.items()
                  if not any(given_by(k, [g]) for g in factors)]
        rest = f"; give its other keys one by one: {' '.join(others)}" if others else ""
        raise InputError(f"{key} holds {f}, a factor of the sweep ({factors[f]}.{f}), {why}{rest}", source=src,
                         key=f"--set {item.strip()}")


def at_default(config: dict, defaults: dict, dotted: str) -> bool:
    """Whether the resolved ``config`` holds the key ``dotted`` at its default."""
    here, there = config, defaults
    for part in dotted.split("."):
        if not (isinstance(here, dict) and isinstance(there, dict) and part in here and part in there):
            return False
        here, there = here[part], there[part]
    return here == there


def given_by(key: str | None, keys) -> bool:
    """Whether the dotted ``key`` (an error's) is one of ``keys``, or a section above or below one."""
    return key is not None and any(key == k or key.startswith(k + ".") or k.startswith(key + ".") for k in keys)


def named(e: InputError, source: str) -> InputError:
    """``e`` with its source ``source`` (:meth:`~tlm.errors.InputError.replaced`)."""
    return e.replaced(source=source)
