"""How the report writes a number: one rule for its tables and its figures' labels, so that a value reads
alike in both (h545). Not yet its sentences: the summary's, the peers' and the comparison's still quote a rate
to three significant digits ("72.9 FPS" beside a table's 72.94; h549), a leftover.

- A measured value (cycles, frame rates, seconds): :func:`sig`, to a count of significant digits
  (four in a table), its significant trailing zeros kept and no trailing point: ``6.410``,
  ``93.60``, ``13.00``, ``110.0``, ``0.3929`` (not ``6.41``, ``93.6``, ``13``); from 1,000 up
  written whole with thousands separators, ``7,460`` and ``11,920`` (not ``1.192e+04``); under
  0.001 in scientific notation, ``1.230e-05``.
- A count (triangles, photons, a trace's slices and cycles, puts): :func:`whole`, exact, thousands
  separated: ``2,604``, ``44,778,358``.
- A recorded input (a light's power, a corner): :func:`exact`, the value as recorded, not rounded,
  thousands separated: ``1,100,000 950,000 750,000``, ``548.8``, ``13,650``.
- A thesis value: as the thesis prints it (:func:`printed`), its own digits: ``43.0``, ``110``,
  ``3.037``.

A setting's value quoted as a setting (``arch.fifo_depth = 1024``, ``packet_size=102400``) is
written as the config file writes it (:func:`tlm.report.names.value_text`), so that it can be copied back.
"""

from __future__ import annotations

import math
import numbers

SMALL = 1e-3  # a measured value under this in size is written in scientific notation (1.230e-05)
HUGE = 1e15  # a recorded value from this up too (its plain digits would be a row of zeros)


def _number(v) -> bool:
    """A real number, numpy's too (``np.float32``, ``np.int64``: a value read from an array), not a bool."""
    return isinstance(v, numbers.Real) and not isinstance(v, bool) and type(v).__name__ != "bool_"


def _plain(v):
    """``v`` (a :func:`_number`) as Python's int or float: numpy's ``repr`` is ``np.float64(6.41)``, and
    ``np.float32``'s digits are not those the value was written with."""
    if isinstance(v, numbers.Integral):
        return int(v)
    if isinstance(v, float):  # (float and np.float64)
        return float(v)
    try:  # (np.float32, np.float16: their str is the shortest text that reads back the same, 6.41)
        return float(str(v))
    except ValueError:
        return float(v)


def sig(v: float, digits: int = 4, zeros: bool = True) -> str:
    """``v`` to ``digits`` significant digits (module docstring): trailing zeros kept (``zeros``:
    ``6.410``; without, as ``.4g`` leaves them out: ``6.41``), values of ``10 ** (digits - 1)`` and more
    whole and thousands separated (``11,920``), under :data:`SMALL` in scientific notation; 0 is ``0``,
    NaN and infinities as Python writes them, anything else as ``str`` writes it."""
    if not _number(v) or not math.isfinite(v):
        return str(v)
    v = _plain(v)
    if v == 0:
        return "0"
    digits = max(1, int(digits))
    mantissa, _, power = f"{v:.{digits - 1}e}".partition("e")  # (after rounding: 9999.7 is 1.000e+04)
    exponent = int(power)
    if exponent >= digits - 1:  # (its rounded digits and zeros: not a float's, 10**30 is not 1,000,...,019,884,...)
        return f"{int(mantissa.replace('.', '')) * 10 ** (exponent - digits + 1):,}"
    if 10.0 ** exponent < SMALL:  # (under SMALL once rounded: 0.00099996 is 0.001000, as 0.001 is)
        text = f"{v:#.{digits - 1}e}"
        mantissa, _, power = text.partition("e")
        return f"{_strip(mantissa, zeros)}e{power}"
    return _strip(f"{v:,.{digits - 1 - exponent}f}", zeros)


def _strip(text: str, zeros: bool) -> str:
    """``text`` without its trailing point, and without its trailing zeros after the point unless ``zeros``."""
    if "." not in text:
        return text
    if not zeros:
        text = text.rstrip("0")
    return text.rstrip(".")


def whole(n: int | float) -> str:
    """A count, exact and thousands separated: ``2,604``, ``44,778,358``; a float that is whole as an int
    (``5.0``: ``5``); anything else as :func:`exact` writes it."""
    if _number(n) and math.isfinite(n) and float(n).is_integer() and (isinstance(_plain(n), int) or abs(n) < HUGE):
        return f"{int(_plain(n)):,}"  # (a float from HUGE up as exact writes it: its int's digits are not recorded)
    return exact(n)


def exact(v) -> str:
    """A recorded value as recorded, not rounded (the shortest text that reads back the same), in plain
    digits, thousands separated: ``1,100,000``, ``548.8``, ``0.065``, ``13,650``; from :data:`HUGE` up and
    under :data:`SMALL` (not 0) in scientific notation as Python writes it (``1e-07``); not a number:
    ``str``."""
    if not _number(v) or not math.isfinite(v):
        return str(v)
    v = _plain(v)
    if isinstance(v, int):
        return f"{v:,}"
    if v != 0 and not SMALL <= abs(v) < HUGE:
        return repr(v)
    if v.is_integer():
        return f"{int(v):,}"
    sign, text = ("-", repr(-v)) if v < 0 else ("", repr(v))
    head, _, tail = text.partition(".")
    return f"{sign}{int(head):,}.{tail}"


def printed(v) -> str:
    """A thesis value as the thesis prints it, from :data:`tlm.experiments.thesis.THESIS`'s literal: an int
    whole (``110``), a float to its own digits (``43.0``, ``3.037``), thousands separated; not a number: ``str``."""
    if not _number(v) or not math.isfinite(v):
        return str(v)
    v = _plain(v)
    if isinstance(v, int):
        return f"{v:,}"
    text = exact(v)
    return f"{text}.0" if float(v).is_integer() and "e" not in text else text
