"""Checks of the values read from scene files: each raises a one-line
:class:`~tlm.errors.InputError` naming the file (``src``), the key and the value.
Shared by the scene loader and the geometry composer."""

from __future__ import annotations

import datetime
import math
from typing import Any

from tlm.errors import InputError, did_you_mean

__all__ = ["MAX_MAGNITUDE", "digit_count", "digits", "keys", "mapping", "num", "shown", "vec"]

# the largest magnitude of a scene's numbers (coordinates, powers, emission, scales): far past
# any scene (a room scaled by 1e6 is 1e7), so that products of up to ten such numbers, which
# the float64 code forms (areas, powers, determinants, power x scale^2), stay finite. It is
# not where the kernels overflow: the float32 ray-triangle test's range is far narrower (a
# scene's extent cubed under ~3.4e38), and tlm.scenes.loader.check_float32_range checks the
# final geometry against it
MAX_MAGNITUDE = 1e30


def digits(n: int) -> int:
    """How many decimal digits ``abs(n)`` has (counted without ``str``, which Python refuses
    past 4300 digits: a YAML hexadecimal whole number has no such bound)."""
    n = abs(int(n))
    d = max(1, int(n.bit_length() * 0.30102999566398120))  # (log10 2: d is the count or one short)
    while n >= 10**d:
        d += 1
    return d


def digit_count(n: int) -> str:
    """``n`` named by its count of digits: 'a 401-digit number', 'an 802-digit number', 'a
    negative 401-digit number'."""
    d = digits(n)
    if n < 0:
        return f"a negative {d}-digit number"
    lead = str(d)[:(len(str(d)) - 1) % 3 + 1]  # (the part said before 'thousand')
    return f"{'an' if lead.startswith('8') or lead in ('11', '18') else 'a'} {d}-digit number"


SHOWN_CHARS = 200  # the most characters of a value an error line shows (the rest: "...")


def shown(v: Any, limit: int = SHOWN_CHARS) -> str:
    """``repr`` of a value as an error line names it, a date or time as YAML read it (``2020-01-01``, not
    ``datetime.date(2020, 1, 1)``), a whole number past 900 bits (float64
    holds none past 1024) by its count of digits, in a list too; cut to ``limit`` characters,
    a list's items taken only until then (a list of millions, aliases' too, said after a few)."""
    if isinstance(v, list):
        parts: list[str] = []
        size = 1
        for x in v:
            if size > limit:  # (more past the limit: said so, not shown as the whole)
                parts.append("...")
                break
            parts.append(shown(x, limit))
            size += len(parts[-1]) + 2
        text = f"[{', '.join(parts)}]"
    elif isinstance(v, int) and not isinstance(v, bool) and v.bit_length() > 900:
        return digit_count(v)
    elif isinstance(v, (datetime.date, datetime.time)):  # (a YAML date or time as written: 2020-01-01)
        text = v.isoformat()
    else:
        text = repr(v)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _beyond(x: Any) -> bool:
    """A whole number past the bound (checked before ``math.isfinite``, which a whole number
    past float64 makes raise OverflowError)."""
    return isinstance(x, int) and not isinstance(x, bool) and abs(x) > MAX_MAGNITUDE


def mapping(v: Any, src: str, key: str) -> dict:
    if not isinstance(v, dict):
        raise InputError(f"must be a mapping, got {v!r}", source=src, key=key)
    return v


def keys(d: dict, allowed: tuple[str, ...], src: str, key: str) -> None:
    for k in d:
        if k not in allowed:
            where = f"{key}.{k}" if key else str(k)
            raise InputError(f"unknown key{did_you_mean(str(k), allowed)}", source=src, key=where)


def vec(v: Any, src: str, key: str, n: int = 3, lo: float | None = None, hi: float | None = None):
    ok = isinstance(v, list) and len(v) == n and all(
        isinstance(x, (int, float)) and not isinstance(x, bool) for x in v
    )
    if not ok:
        raise InputError(f"{shown(v)} is not a list of {n} numbers", source=src, key=key)
    if not any(_beyond(x) for x in v) and not all(math.isfinite(x) for x in v):
        raise InputError(f"{v!r} is not finite", source=src, key=key)
    if any(abs(x) > MAX_MAGNITUDE for x in v):
        raise InputError(f"{shown(v)} is beyond +-{MAX_MAGNITUDE:g}, the bound that keeps products of the scene's "
                         "numbers finite in float64",
                         source=src, key=key)
    if lo is not None and any(x < lo for x in v):
        raise InputError(f"{v!r} must be >= {lo}", source=src, key=key)
    if hi is not None and any(x > hi for x in v):
        raise InputError(f"{v!r} must be <= {hi}", source=src, key=key)
    return tuple(float(x) for x in v)


def num(v: Any, src: str, key: str, lo: float | None = None, hi: float | None = None,
         lo_exclusive: bool = False) -> float:
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not (_beyond(v) or math.isfinite(v)):
        raise InputError(f"{shown(v)} is not a finite number", source=src, key=key)
    if abs(v) > MAX_MAGNITUDE:
        raise InputError(f"{shown(v)} is beyond +-{MAX_MAGNITUDE:g}, the bound that keeps products of the scene's "
                         "numbers finite in float64",
                         source=src, key=key)
    if lo is not None and (v <= lo if lo_exclusive else v < lo):
        raise InputError(f"{v!r} must be {'>' if lo_exclusive else '>='} {lo}", source=src, key=key)
    if hi is not None and v > hi:
        raise InputError(f"{v!r} must be <= {hi}", source=src, key=key)
    return float(v)
