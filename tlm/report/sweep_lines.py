"""The lines of a sweep's figures, whatever they plot: which combinations of the other factors
draw one line (:func:`merge_groups`, to 1e-9: :func:`same_value`), a category's points side by
side (:func:`dodge`), the legend under a figure, its labels wrapped to the figure's width
(:func:`legend_under`), and the points of a factor of numbers whose value is null (``bsp.levels:
[null, 6, 8]``, null the thesis's depth) drawn apart on its axis of numbers: at the value they
resolved to where their results folder records it, else at a tick ``null`` beside the numbers
(:func:`null_points`, :func:`draw_nulls`); a factor of numbers' axis, log from 8x where its values are spaced by
ratios (not 1, 2, ... 10), of base 2 over powers of two, ticked at its values (:func:`factor_axis`). A factor's
values are ordered and compared as :func:`order_key` and :func:`hashable` make them.
"""

from __future__ import annotations

import itertools
import math
import textwrap
from collections import defaultdict
from collections.abc import Callable
from typing import Any

import numpy as np
from matplotlib.ticker import FuncFormatter, MaxNLocator, NullLocator

from tlm.report.collect import Sweep
from tlm.report.common import line_style, log_ticks
from tlm.report.names import null_meaning, value_text

LEVELS = "bsp.levels"
LEGEND_FONT = 7  # points
# the legend under a figure: characters of a label per inch of the figure's width (DejaVu Sans at
# LEGEND_FONT points, digits and lower case about 4.5 pt wide, less the marker and the padding), the
# height of a line of text and the gap between entries, and the legend's frame and the space above it
LEGEND_CHARS_PER_INCH = 14
LEGEND_LINE_IN = 0.125
LEGEND_GAP_IN = 0.05
LEGEND_PAD_IN = 0.3
# a point of a null factor value: a hollow star
NULL_STYLE = {"linestyle": "none", "marker": "*", "markersize": 13, "markerfacecolor": "none", "markeredgewidth": 1.3}


def fmt_value(v: Any) -> str:
    """A value as the report writes it: a float to 4 significant digits."""
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


# a table column of numbers is written in fixed notation where its smallest number (not 0) and its
# largest are within these bounds (4 significant digits each: 0.001234, 1381, 34530, 1234567), else
# each in scientific notation (3.4e+05, 1.2e+06, 5e+10)
FIXED_FROM, FIXED_BELOW = 1e-3, 1e7


def _fixed(v: float) -> str:
    """``v`` to 4 significant digits in fixed notation, trailing zeros left out (as ``.4g`` leaves
    them out): ``0.05``, ``1381``, ``34530``."""
    if v == 0:
        return "0"
    digits = max(0, 3 - math.floor(math.log10(abs(v))))
    text = f"{v:.{digits}f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def _scientific(v: float) -> str:
    """``v`` to 4 significant digits in scientific notation, the mantissa's trailing zeros left out:
    ``3.4e+05``, ``5e+10``; 0 is ``0``."""
    if v == 0:
        return "0"
    mantissa, _, exponent = f"{v:.3e}".partition("e")
    return f"{mantissa.rstrip('0').rstrip('.') if '.' in mantissa else mantissa}e{exponent}"


def column_texts(values: list, text: Callable[[Any], str] = fmt_value) -> list[str]:
    """The cells of one table column, its numbers in one notation, chosen for the column (``.4g``
    chose it for each number: ``340000`` beside ``1.2e+06``, ``1381`` beside ``3.453e+04``): whole
    numbers (ints) as they are where the column has no other number; else fixed notation where every
    number but 0 lies in [:data:`FIXED_FROM`, :data:`FIXED_BELOW`) in size, each to 4 significant
    digits (``0.2348``, ``34530``), else scientific notation for every number (``3.4e+05``,
    ``5e+10``). Any other value (null, a bool, text, NaN, a list) is ``text``'s."""
    def number(v: Any) -> bool:
        return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)

    nums = [v for v in values if number(v)]
    if all(isinstance(v, int) for v in nums):
        return [str(v) if number(v) else text(v) for v in values]
    sizes = [abs(v) for v in nums if v != 0]
    fixed = not sizes or (min(sizes) >= FIXED_FROM and max(sizes) < FIXED_BELOW)
    write = _fixed if fixed else _scientific
    return [write(v) if number(v) else text(v) for v in values]


# a column of measured numbers whose largest is under this many times its smallest (not 0) is written to one
# count of decimals (:func:`column_decimals`); a wider one keeps 4 significant digits a number
ONE_DECIMALS_SPAN = 100


def column_decimals(values: list, text: Callable[[Any], str] = fmt_value) -> list[str]:
    """The cells of a table column of measured numbers (cycles, frame rates, seconds, errors), each
    to the one count of decimals that writes its largest number to 4 significant digits and its
    smallest to 3 at least, trailing zeros kept, so that a row's digits line up with its
    neighbours' (``102.0`` beside ``101.6`` and ``64.3``, not ``102``; ``29.500`` above ``0.671``,
    not ``0.67``). A column whose numbers span :data:`ONE_DECIMALS_SPAN` times or more (one
    count of decimals would write its smallest with fewer than 2 significant digits), or that
    :func:`column_texts` writes in scientific notation or as whole numbers, is written as it writes it."""
    nums = [abs(v) for v in values if isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)]
    sizes = [v for v in nums if v != 0]
    if (all(isinstance(v, int) for v in nums) or not sizes or min(sizes) < FIXED_FROM
            or max(sizes) >= FIXED_BELOW or max(sizes) >= ONE_DECIMALS_SPAN * min(sizes)):
        return column_texts(values, text)
    places = max(0, 3 - math.floor(math.log10(max(sizes))), 2 - math.floor(math.log10(min(sizes))))
    return [("0" if v == 0 else f"{v:.{places}f}") if isinstance(v, int | float) and not isinstance(v, bool)
            and math.isfinite(v) else text(v) for v in values]


def all_numbers(values: list) -> bool:
    """Every value a number (not a bool)."""
    return all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)


def same_value(a, b) -> bool:
    """Two values of a line the same to 1e-9 (both missing, or both not a number: the same)."""
    if a is None or b is None:
        return a is None and b is None
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return math.isclose(a, b, rel_tol=1e-9)


def merge_groups(series: dict[tuple, dict], limit: int | None = None) -> list[tuple[list[tuple], dict]] | None:
    """The series in the order of their combinations, those with the same points (:func:`same_value`)
    together: each distinct line once, with every combination that draws it. None when there
    are more than ``limit`` distinct lines (found as soon as there are: a sweep of thousands
    of distinct combinations is not compared pair by pair)."""
    merged: list[tuple[list[tuple], dict]] = []
    for combo, pts in sorted(series.items(), key=lambda kv: [order_key(k) for k in kv[0]]):
        for combos, seen in merged:
            if seen.keys() == pts.keys() and all(same_value(seen[k], pts[k]) for k in pts):
                combos.append(combo)
                break
        else:
            if limit is not None and len(merged) >= limit:
                return None
            merged.append(([combo], pts))
    return merged


def legend_under(fig, ax, width: float, height: float) -> None:
    """The axes' legend under the plot, across the figure: labels wrapped to the figure's
    width, and the figure ``width`` x ``height`` inches made taller by the legend's height,
    so that the plot keeps about the size it has without a legend and no label, however long
    (many identical combinations), squeezes it (matplotlib's constrained layout gives up with
    a warning when the decorations leave the axes no room)."""
    handles, labels = ax.get_legend_handles_labels()
    wrapped = [textwrap.fill(label, max(20, int(width * LEGEND_CHARS_PER_INCH)), expand_tabs=False) for label in labels]
    lines = sum(w.count("\n") + 1 for w in wrapped)
    fig.set_size_inches(width, height + LEGEND_PAD_IN + lines * LEGEND_LINE_IN + len(wrapped) * LEGEND_GAP_IN)
    fig.legend(handles, wrapped, loc="outside lower center", fontsize=LEGEND_FONT)


def resolved_value(factor: str, run) -> float | None:
    """The value a point of ``factor`` null ran with, where its results folder records it: for
    ``bsp.levels`` the depth its BSP was asked to build (results.json ``scene.bsp.requested_levels``,
    floor(ln n)); for another key its resolved config's value, where that is a number. Else None."""
    if run is None:
        return None
    if factor == LEVELS:
        v = ((run.results.get("scene") or {}).get("bsp") or {}).get("requested_levels")
    else:
        v = run.config
        for part in factor.split("."):
            v = v.get(part) if isinstance(v, dict) else None
    return v if all_numbers([v]) and math.isfinite(v) else None


def null_points(sw: Sweep, factor: str, nulls: list[dict], others: list[str]) -> list[tuple[tuple, Any, float]]:
    """The finished points of ``factor`` null: ``(combination of the other factors, the value it
    resolved to or None, FPS)`` each, in point order."""
    return [(tuple(hashable(r.get(f)) for f in others), resolved_value(factor, sw.run_of(r)), r["fps"])
            for r in sorted(nulls, key=lambda r: order_key(r.get("point")))]


def draw_nulls(ax, factor: str, nulled: list[tuple[tuple, Any, float]], index: dict[tuple, int], band: bool,
                span: tuple[float, float], log: bool) -> str:
    """Draw the points of ``factor`` null (:func:`null_points`) as hollow stars, joined to no line: at
    the value each resolved to where its results folder records it, else at a tick "null" left of the
    numbers, off the axis's scale. Each star has the colour of its combination's line (``index``: a
    combination's line; black where it has none), or with ``band`` (the median and min-max band) the
    median of the points at its value and a bar over their range. Their legend entries say what null
    is; the returned sentence is the caption's."""
    meaning = null_meaning(factor) or "the default"  # (what its help says null is)
    lo, hi = span
    integer = all(float(x).is_integer() for x in span)
    if log:
        apart = lo / (hi / lo) ** 0.15
    else:
        gap = (hi - lo) * 0.15 or abs(lo) * 0.15 or 1.0
        apart = lo - (max(1, round(gap)) if integer else gap)
    at: dict[Any, list[tuple[tuple, float]]] = defaultdict(list)
    for combo, x, fps in nulled:
        at[apart if x is None else x].append((combo, fps))
    for x, pts in at.items():
        if band:
            ys = sorted(fps for _, fps in pts)
            med = float(np.median(ys))
            if len(ys) > 1:
                ax.errorbar([x], [med], yerr=[[med - ys[0]], [ys[-1] - med]], fmt="none", ecolor="0.35",
                            elinewidth=6, alpha=0.45)
            ax.plot([x], [med], color="black", **NULL_STYLE)
            continue
        by_line: dict[int | None, list[float]] = defaultdict(list)
        for combo, fps in pts:
            by_line[index.get(combo)].append(fps)
        for i, ys in sorted(by_line.items(), key=lambda kv: -1 if kv[0] is None else kv[0]):
            ax.plot([x] * len(ys), ys, color="black" if i is None else line_style(i)["color"], **NULL_STYLE)
    known = sorted({x for _, x, _ in nulled if x is not None})
    unknown = sum(x is None for _, x, _ in nulled)
    what = "depth" if factor == LEVELS else "value"
    text = ""
    if known:
        shown = ", ".join(fmt_value(x) for x in known)
        ax.plot([], [], color="black", label=f"{factor} null ({meaning}), at the {what} it resolved to: {shown}",
                **NULL_STYLE)
        source = ("the depth its BSP was asked to build, results.json scene.bsp.requested_levels" if factor == LEVELS
                  else "its config.resolved.yaml")
        text += (f" Hollow stars: the points of {factor} null ({meaning}), at the {what} each resolved to "
                 f"({source}: {shown}), joined to no line.")
    if unknown:
        ax.plot([], [], color="black", label=f"{factor} null ({meaning}), {what} not recorded: at \"null\"",
                **NULL_STYLE)
        ticks = [t for t in ax.get_xticks() if lo <= t <= hi]
        labels = ax.xaxis.get_major_formatter().format_ticks(ticks)
        minor = [t for t in ax.xaxis.get_minorticklocs() if lo <= t <= hi]  # (a log axis's: none by "null")
        ax.set_xticks([apart, *ticks], ["null", *labels])
        ax.set_xticks(minor, minor=True)
        many = unknown > 1
        text += (f" {unknown} point{'s' if many else ''} of {factor} null ({meaning}) record{'' if many else 's'} "
                 f"no {what} it resolved to: {'hollow stars' if many else 'a hollow star'} at \"null\", left of the "
                 "numbers and off their scale.")
    return text


LOG_SPAN = 8  # a factor of positive numbers whose largest is this many times its smallest or more: a log axis
VALUE_TICKS = 12  # the most values of a factor of numbers ticked each (more: a locator's ticks)
TICK_ROOM = 1 / 15  # the least gap between two values ticked each, of the axis's span (of their logs on a log axis)


def factor_axis(ax, factor: str, xs: list) -> bool:
    """The x axis of a factor of numbers whose points lie at ``xs`` (its values, and those its null points
    resolved to): log where each is positive, the largest is :data:`LOG_SPAN` times the smallest or more
    (``arch.pipelines`` 1 to 64: N = 1, 2 and 4 not crammed together at the left) and the values are spaced no
    less evenly by their ratios than by their differences (:func:`_geometric`: ``arch.page_miss_cycles`` 1 to 10
    in steps of 1 stays linear), of base 2 where each is a
    whole power of two, else of base 10; a log axis ticked at the values, as :func:`~tlm.report.names.value_text`
    writes them, where they are at most :data:`VALUE_TICKS` and no two are closer than :data:`TICK_ROOM` of the
    axis (its minor ticks then left out), else as :func:`~tlm.report.common.log_ticks` ticks it (base 10; base 2
    labelled in plain numbers, 1024, not 2^10); a
    linear axis of whole numbers ticked in whole numbers, one value alone too (``bsp.levels [null, 7]``: 7, not
    6.64 to 7.36). Returns whether it is log."""
    given = {float(x): x for x in sorted(xs, key=float)}
    vals = list(given)
    lo, hi = vals[0], vals[-1]
    log = lo > 0 and hi / lo >= LOG_SPAN and _geometric(vals)
    whole = all(v.is_integer() for v in vals)
    two = log and whole and all(math.log2(v).is_integer() for v in vals)
    if log:
        ax.set_xscale("log", base=2 if two else 10)
    at = [math.log(v) for v in vals] if log else []
    room = all(b - a >= TICK_ROOM * (at[-1] - at[0]) for a, b in itertools.pairwise(at))
    if log and len(vals) <= VALUE_TICKS and room:
        ax.set_xticks(vals, [value_text(factor, given[v]) for v in vals])
        ax.xaxis.set_minor_locator(NullLocator())
    elif log and not two:
        log_ticks(ax, "x")
    elif log:  # (base 2's own labels are 2^k: the numbers instead)
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:.0f}"))
    elif whole:  # (an integer factor: no 5.5 levels; one value alone ticked, not 6.64 to 7.36)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True, min_n_ticks=1))
    return log


def _geometric(vals: list[float]) -> bool:
    """Whether the sorted distinct positive ``vals`` are spaced at least as evenly by their ratios as by their
    differences (the coefficient of variation of their log gaps no more than that of their gaps): 1, 2, 4 ... 64
    and 16, 256, 4096 are, 1, 2, 3 ... 10 is not; two values are."""
    if len(vals) < 3:
        return True

    def spread(gaps: list[float]) -> float:
        mean = sum(gaps) / len(gaps)
        return math.sqrt(sum((g - mean) ** 2 for g in gaps) / len(gaps)) / mean

    return spread([math.log(b / a) for a, b in itertools.pairwise(vals)]) <= spread(
        [b - a for a, b in itertools.pairwise(vals)]) + 1e-9


def dodge(i: int, n: int) -> float:
    """The offset of series ``i`` of ``n`` at a category: side by side, within +-0.3 of it."""
    return 0.0 if n < 2 else (i - (n - 1) / 2) * min(0.6 / (n - 1), 0.15)


def hashable(v):
    """A factor's value as a key: a list (``[16, 16]``) as a tuple."""
    return tuple(v) if isinstance(v, list) else v


def order_key(v):
    """The order of a factor's values: null and bools, then numbers, then text."""
    if isinstance(v, bool) or v is None:
        return (0, str(v))
    if isinstance(v, int | float):
        return (1, v if math.isfinite(v) else float("inf"))
    return (2, str(v))
