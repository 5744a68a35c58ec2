"""tlm's Python API, its caches: what they hold (``tlm cache``), and their entries removed whole by
age or to a size (``tlm cache prune``, ``tlm cache clear``), as :mod:`tlm.cache_admin` finds and removes
them.

Read them from :mod:`tlm.api` (or ``tlm``), which re-exports them: ``tlm.cache_info is
tlm.api.cache_info``. Bad input raises :class:`~tlm.errors.InputError` naming the argument and the
value (``max_size: -1 is not a size: ...``), before anything is removed.
"""

from __future__ import annotations

import json
import math
import numbers
from collections.abc import Iterable
from typing import Any

from tlm import cache_admin as _ca
from tlm.api_common import checked as _checked
from tlm.api_common import shown as _shown
from tlm.caches import cache_home
from tlm.errors import InputError


def cache_info(caches: str | Iterable[str] | None = None) -> dict:
    """``tlm cache --json``: the ``folder``, its ``bytes`` and a dict per cache of ``caches`` (one name or
    several of :data:`tlm.cache_admin.NAMES`; None: all; an empty list: none): its ``entries``, ``bytes``
    (the apparent bytes of its entries' files, not ``du``'s blocks), ``oldest_use``, ... The folder a file
    (``$TLM_CACHE`` set to one): an :class:`~tlm.errors.InputError`; one that does not exist: empty caches."""
    home = cache_home()
    return json.loads(_ca.as_json(_ca.survey(_cache_names(caches), home), home))


def prune_cache(older_than: float | str | None = None, max_size: float | str | None = None,
                caches: str | Iterable[str] | None = None, dry_run: bool = False, stale: bool = False) -> dict:
    """``tlm cache prune``: the entries of ``caches`` (:func:`cache_info`'s) last used over ``older_than`` ago
    (seconds, ``"30d"``), then the least recently used until the rest take ``max_size`` (bytes, ``"500M"``),
    removed whole. Returns ``dry_run`` (True: ``removed`` lists what would be removed; nothing is),
    ``removed`` and ``not_removed`` (with ``why``: ``used meanwhile``, read, written or replaced since the
    survey, so kept), each ``{"entry", "bytes", "last_use"}``, and the ``kept`` entries and ``kept_bytes``
    (every entry not removed: those that could not be too). ``older_than`` at most 1000 years, ``max_size``
    1 EiB; ``caches=[]``: none, nothing removed. ``stale=True`` (``tlm cache prune --stale``): the stale frames
    too, written by other code than this (their sidecar's ``code_fingerprint``), alone or with the others. A
    Ctrl-C while entries are removed raises :class:`tlm.cache_admin.RemovalInterrupted` (a KeyboardInterrupt)
    whose ``removed`` lists those already removed (each whole)."""
    stale = _checked(stale, "stale", bool)
    if older_than is None and max_size is None and not stale:
        raise InputError("give older_than=, max_size= and/or stale=True (clear_cache() removes every entry)",
                         key="prune_cache")
    return _removed(caches, dry_run, _amount(older_than, "older_than"), _amount(max_size, "max_size"),
                    stale=stale)


def clear_cache(caches: str | Iterable[str] | None = None, dry_run: bool = False) -> dict:
    """``tlm cache clear``: every entry of ``caches`` (None: all; an empty list: none) removed; returns what
    :func:`prune_cache` does (and raises what it does on a Ctrl-C)."""
    return _removed(caches, dry_run, None, None, clear=True)


def _cache_names(caches: Any) -> list[str]:
    listed = [caches] if isinstance(caches, str) or not isinstance(caches, Iterable) else list(caches)
    return _ca.cache_names(None if caches is None else listed, key="caches")


def _amount(value: Any, key: str) -> float | None:
    """``older_than`` (seconds) or ``max_size`` (bytes): a number, not negative nor too large, or the flag's text."""
    duration = key == "older_than"
    if isinstance(value, str):
        return (_ca.duration if duration else _ca.size)(value, key=key)
    if value is None:
        return None
    if isinstance(value, numbers.Real) and not isinstance(value, bool) and value >= 0:
        try:
            number = float(value)
        except OverflowError:  # (an int past a float's range)
            number = math.inf
        return _ca.too_large(number, value, key, duration)
    what = "a duration: seconds (not negative) or text such as '30d'" if duration else \
        "a size: bytes (not negative) or text such as '500M'"
    raise InputError(f"{_shown(value)} is not {what}", key=key)


def _removed(caches: Any, dry_run: Any, older: float | None, most: float | None, clear: bool = False,
             stale: bool = False) -> dict:
    """:func:`prune_cache` (:func:`clear_cache`: ``clear``, every entry) as ``tlm cache`` does it."""
    dry_run = _checked(dry_run, "dry_run", bool)
    return _ca.prune(_cache_names(caches), older, None if most is None else int(most), clear=clear,
                     dry_run=dry_run, stale=stale).record()
