"""The summary's sentences on what a sweep's factors do (:mod:`tlm.report.summary` says them): per sweep,
the factor that moves the frame rate most, like with like, and its fastest point (the best where no slower
point has a lower image error, else the point of the lowest error beside it: :func:`sweep_findings`); the
factors that change nothing, those that keep the frame rate but change the image error, and those that cannot
be compared; points within 1% of the highest frame rate tie with it (:data:`NEAR_TIE`), said so with the factors
that do not part them as "any" (:func:`_near`), and a factor whose values' mean frame rates are within 1% has no
best value (said by how much it moves them); the best of points tied in frame rate is the one of least image
error where each measured it, points that differ only in factors that change nothing counted and those factors
said as "any" (:func:`_span`); and per sweep whose points measured their image error, the factor that moves it
most (:func:`error_factor`, said under "What quality costs"). The k-NN reference's points (``estimate.filter:
knn`` in photon-map mode) are ranked by frame rate nowhere, their search not modelled (:func:`_ranked_points`, as
the error-vs-cost report);
errors measured against different references (a factor of the reference's key: ``photons.max_bounces``, one reference
per value) are compared nowhere, said so (:func:`_apart`, :func:`_keyed`: h531);
a factor's values are written as YAML writes them (``cone``, not ``'cone'``: :func:`_as_yaml`).
"""

from __future__ import annotations

import ast
from collections import defaultdict

import numpy as np

from tlm.arch.steady import STEADY_SPREAD
from tlm.config_words import flow_text, listing
from tlm.report.collect import Inputs, Sweep, with_set
from tlm.report.common import NAMED, some
from tlm.report.html import esc
from tlm.report.names import value_text
from tlm.report.numbers import sig
from tlm.report.summary_points import and_ as _and
from tlm.report.summary_points import number as _number
from tlm.report.sweep_lines import same_value
from tlm.report.sweeps import named_rows


def _moves_with(rows: list[dict], k: str, factors: list[str]) -> list[str]:
    """The other factors whose value each value of ``k`` fixes in ``rows`` (a sweep's rows,
    the failed ones too), and that take more than one value: they move together with ``k``
    (a ``zip:``), so that ``k``'s effect cannot be told from theirs."""
    out = []
    for j in factors:
        if j == k:
            continue
        seen: dict[str, set[str]] = defaultdict(set)
        for r in rows:
            seen[repr(r.get(k))].add(repr(r.get(j)))
        if all(len(v) == 1 for v in seen.values()) and len(set().union(*seen.values())) > 1:
            out.append(j)
    return out


ERROR = "error.rel_mse"  # a sweep point's measured image error (sweep.csv), which a factor may change


def _effect(ok: list[dict], k: str, held: list[str], of: str = "fps") -> dict | None:
    """``k``'s effect on the frame rate (``of``: another column of ``ok``, the image error
    :data:`ERROR`) among the ``ok`` rows, like with like: a row belongs to
    the combination of its values of the factors ``held``; only the combinations that finished
    with every value ``k`` takes among ``ok`` count. Each value's mean is over those
    combinations (a combination's rows of one value: their mean). None where ``k`` takes one
    value; else ``values`` (repr -> that mean, in the order the values first come in ``ok``, the
    sweep's; {} where no combination is complete), ``used``
    (the rows counted), ``combos`` (the complete combinations), ``compared`` (the combinations that
    finished with two values of ``k`` or more) and ``same`` (whether some
    combination finished with two values of ``k`` or more, and every such combination has one
    value of ``of`` (to 1e-9: :func:`same_value`) across them: ``k`` does not change it between the
    points that differ only in it)."""
    values = list(dict.fromkeys(repr(r.get(k)) for r in ok))  # (an order of its own: not a set's, which varies)
    if len(values) < 2:
        return None
    combos: dict[tuple, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for r in ok:
        combos[tuple(repr(r.get(j)) for j in held)][repr(r.get(k))].append(float(r[of]))
    complete = [c for c in combos.values() if set(c) == set(values)]
    used = sum(len(fs) for c in complete for fs in c.values())
    per = {v: float(np.mean([np.mean(c[v]) for c in complete])) for v in values} if complete else {}
    pairs = [c for c in combos.values() if len(c) > 1]
    flat = [[f for fs in c.values() for f in fs] for c in pairs]
    same = bool(flat) and all(all(same_value(f, fs[0]) for f in fs) for fs in flat)
    return {"values": per, "used": used, "combos": len(complete), "compared": len(pairs), "same": same}


CYCLES = {"cycles.vertex": "TVert", "cycles.traversal": "TTrav", "cycles.intersection": "Tisct",
          "cycles.fragment": "TFrag", "cycles.throughput": "TThru", "cycles.latency": "the latency"}


def _cycles_moved(ok: list[dict], k: str, held: list[str]) -> tuple[str, float] | None:
    """Where ``k`` keeps the frame rate: whether it still moves a cycle count (sweep.csv's ``cycles.<pm>``,
    :data:`CYCLES`) between the ``ok`` rows that differ only in it (the combinations of the factors ``held``,
    as :func:`_effect`): the count it moves most, by name, and by how much (the largest of a combination's
    highest over its lowest, less one; infinite where a count is 0 in one point and not in another); None where
    every count is the same (to 1e-9) in each combination."""
    most: tuple[str, float] | None = None
    for col, name in CYCLES.items():
        combos: dict[tuple, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
        for r in ok:
            if _number(r.get(col)):
                combos[tuple(repr(r.get(j)) for j in held)][repr(r.get(k))].append(float(r[col]))
        for c in combos.values():
            vs = [v for vals in c.values() for v in vals] if len(c) > 1 else []
            if vs and not all(same_value(v, vs[0]) for v in vs):
                change = max(vs) / min(vs) - 1 if min(vs) > 0 else float("inf")  # (0 cycles in one point: moved)
                if most is None or change > most[1]:
                    most = (name, change)
    return most


def _measured(rows: list[dict]) -> list[dict]:
    """The rows that measured their image error (a number in :data:`ERROR`)."""
    return [r for r in rows if _number(r.get(ERROR))]


def _references(sw: Sweep, rows: list[dict]) -> dict[int, str]:
    """The reference each of ``rows`` that measured its image error measured it against, by the row's id: its
    ``results.json``'s ``error.reference``, the reference's key (sweep.csv has no column of it); a row whose
    results folder names none is left out (its error compared as before)."""
    out = {}
    for r in _measured(rows):
        run = sw.run_of(r)
        error = run.results.get("error") if run is not None else None
        if isinstance(error, dict) and isinstance(error.get("reference"), str) and error["reference"]:
            out[id(r)] = error["reference"]
    return out


def _apart(rows: list[dict], k: str, held: list[str], refs: dict[int, str]) -> bool:
    """Whether ``k``'s values are measured against different references (``refs``: :func:`_references`): some
    combination of the factors ``held`` whose rows name more than one (``k`` is part of the reference's key, or a
    factor that moves with it is), so that its effect on the image error compares errors that are not comparable."""
    seen: dict[tuple, set[str]] = defaultdict(set)
    for r in rows:
        if id(r) in refs:
            seen[tuple(repr(r.get(j)) for j in held)].add(refs[id(r)])
    return any(len(v) > 1 for v in seen.values())


def _keyed(keys: list[str], refs: dict[int, str]) -> str:
    """Why the image errors of a sweep's points against ``refs``' several references are not compared, in one
    clause (escaped): the factors ``keys`` that change the reference (:func:`_apart`), where known: a part of its
    key, or a factor of a ``zip:`` that moves with one (``photons.count`` zipped with ``photons.max_bounces``), so
    said as the reference changing with them, not as their being parts of its key (h541)."""
    why = f", the reference changing with {esc(_and(keys))}" if keys else ""
    return (f"the points measured it against {len(set(refs.values()))} references (results.json error.reference)"
            f"{why}, and errors against different references are not comparable")


def _error_range(k: str, eff: dict, most: bool = False) -> str:
    """How ``k`` changes the image error (:func:`_effect` of :data:`ERROR`, ``eff``), in words: its
    values' mean relative MSE from the worst to the best (tied values said so), or, where its values are
    numbers that the mean error is not monotone over (:func:`_not_monotone`), each value's in the values'
    order, said so (at most :data:`MAX_LISTED`: then the ends and the extremes, the rest left out);
    averaged over the other factors where it is compared in more than one of their combinations; with
    ``most``, the ratio too ("" where no combination finished with each of its values)."""
    means = eff["values"]
    if not means:
        return ""
    hi, lo = max(means.values()), min(means.values())
    ratio = f"{hi / lo:.2f}x, " if most and lo > 0 else ""
    order = _not_monotone(means)
    if order is None:
        said = (f"relative MSE {hi:.3g} at {_values(_extreme(k, means, hi), len(means))} → {lo:.3g} at "
                f"{_values(_extreme(k, means, lo), len(means))}")
    else:
        ends = {0, len(order) - 1, *(i for i, v in enumerate(order) if any(same_value(means[v], m) for m in (hi, lo)))}
        shown = list(range(len(order))) if len(order) <= MAX_LISTED else sorted(ends)
        said = f"not monotone{f' over its {len(order)} values' if len(shown) < len(order) else ''}: relative MSE "
        for n, i in enumerate(shown):
            said += ("" if n == 0 else ", " if i == shown[n - 1] + 1 else ", …, ")
            said += f"{means[order[i]]:.3g} at {esc(_as_yaml(k, order[i]))}"
    return f"{ratio}{said}{', averaged over the other factors' if eff['combos'] > 1 else ''}"


MAX_LISTED = 6  # the most values of a factor whose error is not monotone over them said each


def _not_monotone(means: dict[str, float]) -> list[str] | None:
    """The values (reprs, :func:`_effect`'s keys) in increasing order, where there are three or more,
    each a number, and the ``means`` over them both rise and fall (steps of 1e-9 or less not counted:
    :func:`same_value`); None else (a factor of names or of two values has no order to break)."""
    try:
        nums = {v: ast.literal_eval(v) for v in means}
    except (ValueError, SyntaxError, TypeError):  # (a name, nan)
        return None
    if len(nums) < 3 or not all(_number(x) for x in nums.values()):
        return None
    order = sorted(means, key=nums.__getitem__)
    steps = [b - a for a, b in zip((means[v] for v in order), (means[v] for v in order[1:])) if not same_value(a, b)]
    return order if any(d > 0 for d in steps) and any(d < 0 for d in steps) else None


def _as_yaml(k: str, text: str) -> str:
    """A factor's value as :func:`_effect` keys it (its repr) as YAML writes it: null, true and false, null
    with what it asks of ``k`` (:func:`~tlm.report.names.value_text`); a text unquoted (``cone``, not
    ``'cone'``) but where YAML would read it as another type (``'true'``, ``'1.5'``: :func:`_yaml_text`),
    in a list or a section's mapping too; another value as its repr."""
    if text in ("None", "True", "False"):
        return {"None": value_text(k, None), "True": "true", "False": "false"}[text]
    try:
        v = ast.literal_eval(text)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):  # (nan, inf: as they are)
        return text
    return _yaml_text(v) if isinstance(v, str | list | tuple | dict) else text


def _yaml_text(v) -> str:
    """A text as YAML writes it, quoted only where YAML would read it as another type or it needs quotes;
    a list's items and a mapping's keys and values alike (``[cone, 'true', 2]``, ``{filter: knn}``); on one
    line, and read back as the same text (one YAML would read otherwise, a line break of its own in it:
    double-quoted, escaped)."""
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_yaml_text(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_yaml_text(a)}: {_yaml_text(b)}" for a, b in v.items()) + "}"
    if isinstance(v, str):  # (one line: one of a line break double-quoted, escaped; '1e3', which tlm reads as 1000.0)
        return flow_text(v)
    return value_text("", v)


MAX_TIED_POINTS = 4  # the best points named when more tie (the rest counted)
# Points whose frame rate is within this share of the highest are said as tied with it, "within 1%" (h509: a
# point named best at 102.03 FPS for its arch.swap_cycles = 50 beside its twin of swaps of 2 at 101.84, 0.18%
# apart). It is the model's own bound on a frame rate it reports as steady: an unsettled stream's estimate is
# steady where its running mean moves by at most this share (tlm.arch.steady.STEADY_SPREAD; each point's
# timing.throughput_estimate.spread), so a smaller difference between two points is not one the model tells.
# (timing.granularity's share, tens of percent, bounds what whole packets change against packets of one ray in
# every point at once: as a tolerance it would tie points the sweep does order; the warnings box says it.)
NEAR_TIE = STEADY_SPREAD


def _extreme(k: str, means: dict[str, float], m: float) -> list[str]:
    """The values of ``k`` whose mean is ``m`` (to 1e-9: :func:`same_value`), as YAML writes them."""
    return [_as_yaml(k, v) for v, mean in means.items() if same_value(mean, m)]


def _values(tied: list[str], of: int) -> str:
    """One value, or the values that tie, said so (``2 and 4, tied``); of more than
    :data:`~tlm.report.common.NAMED`, how many of the factor's ``of`` values and the first few
    (:func:`~tlm.report.common.some`: ``49 of its 50 values, tied: 2, 3, 4, 5 and 45 more``)."""
    if len(tied) == 1:
        return esc(tied[0])
    if len(tied) <= NAMED:
        return f"{esc(_and(tied))}, tied"
    return f"{len(tied)} of its {of} values, tied: {esc(some(tied))}"


def _best_points(rows: list[dict], factors: list[str], inert: list[str], of: str = "", word: str = "best") -> str:
    """The point of the highest frame rate in words; where points that differ in more than the
    factors ``inert`` (which change nothing: the text says so) tie at it (to 1e-9), the one of
    the least image error where each of them measured it (the text says so where that error tells them apart;
    one error of them all is said as one point's), else each of them (those of the least error, tied), in sweep
    order (at most :data:`MAX_TIED_POINTS` named, the rest counted). Points that differ only in ``inert`` are
    not told apart but counted: "9 points tie as the best at 411 FPS: bsp.levels = 7, any arch.fifo_depth", the
    factors that vary among them said as :func:`_span` says them. Points within :data:`NEAR_TIE` of the highest
    frame rate and not at it tie with it as well, said so (:func:`_near`: "13 points tie within 1% as the best,
    at 101 to 102 FPS: arch.pipelines = 8, any arch.swap_cycles, ..."), the least image error deciding among
    them as among points at one frame rate. It is "the best point" where
    no point measured its image error or it has the lowest error of all (said so where not said as
    the least of the tied); else "the fastest point", with its error, and the point of the lowest
    error after it (:func:`_lowest`): a faster point of a larger error is not the best of all. ``of`` follows
    "the lowest image error" (`` of the points ranked``: the k-NN reference's left out, :func:`_ranked_points`);
    ``word`` is what a point is where no error ranks it ("fastest" where errors are not comparable: h531)."""
    top = max(r["fps"] for r in rows)
    at_top = [r for r in rows if same_value(r["fps"], top)]
    near = [r for r in rows if r["fps"] >= top * (1 - NEAR_TIE) or same_value(r["fps"], top)]
    within = len(near) > len(at_top)  # (points near the highest, not at it: a tie within the tolerance)
    if within:
        at_top = near
    best = _grouped(at_top, factors, inert)
    tied, low = len(best), None
    if tied > 1 and len(_measured([g[0] for g in best.values()])) == tied:  # (the least error of the tied decides)
        low = min(float(g[0][ERROR]) for g in best.values())
        kept = {key: g for key, g in best.items() if same_value(float(g[0][ERROR]), low)}
        if len(kept) < tied:  # (else the error tells none apart: each has it, said as one point's is)
            best = kept
        else:
            low = None
    firsts = [g[0] for g in best.values()]
    # (the frame rates near the best said apart, 101.8 and 102, and those of the points kept among them, 101.81 and
    # 101.84, not "101.8 to 101.8": h512)
    digits = max(_digits([r["fps"] for r in at_top]), _digits([r["fps"] for r in firsts]))
    least = ("" if low is None else
             f"the least image error (relative MSE {low:.3g}) of the {len(at_top)} points "
             + (f"within {NEAR_TIE:.0%} of the highest frame rate ({sig(top, digits, zeros=False)} FPS)" if within else
                "tied at that frame rate"))
    errs = [float(r[ERROR]) for r in _measured(rows)]
    lowest = min(errs) if errs else None
    fastest = lowest is not None and not all(_number(r.get(ERROR)) and same_value(float(r[ERROR]), lowest)
                                             for r in firsts)
    word = "fastest" if fastest else word
    where = [_where(r, factors) for r in firsts]
    r = firsts[0]
    one = all(_number(x.get(ERROR)) and same_value(float(x[ERROR]), float(r[ERROR])) for x in firsts)  # (one error)
    own = ("" if least or not one else
           f" (relative MSE {float(r[ERROR]):.3g})" if fastest else
           f", with the lowest image error{of} (relative MSE {lowest:.3g})" if lowest is not None else "")
    at = _fps_range([x["fps"] for x in firsts], digits)
    if within and len(best) > 1:  # (a tie within the tolerance: the factors that do not part them as "any")
        text = (f"{sum(map(len, best.values()))} points tie within {NEAR_TIE:.0%} as the {word}, at {at}{own}"
                f"{', ' + least if least else ''}: {_near(list(best.values()), rows, factors, digits)}")
    elif sum(map(len, best.values())) > len(best):  # (points that differ only in factors that change nothing)
        text = (f"{sum(map(len, best.values()))} points tie as the {word} at {at}{own}"
                f"{', ' + least if least else ''}: {_said(list(best.values()), rows, factors)}")
    elif len(where) == 1:
        text = f"the {word} point is {esc(where[0])} at {at}{own}{', ' + least if least else ''}"
    else:
        text = (f"the {word} points, tied at {at}{own}{' and at ' + least if least else ''}, "
                f"are {_named(where, factors)}")
    near = {id(r): digits for r in at_top} if within else None  # (a near point's rate as the range says it)
    return f"{text}; {_lowest(rows, factors, inert, lowest, of, near)}." if fastest else f"{text}."


def _digits(fps: list[float]) -> int:
    """The significant figures that say the frame rates ``fps`` apart: three, or as many more as part the lowest
    and the highest (``101.8`` and ``102.0``, not ``102`` and ``102``); three where they are one (to 1e-9)."""
    lo, hi = min(fps), max(fps)
    return 3 if same_value(lo, hi) else next((d for d in range(3, 10) if sig(lo, d) != sig(hi, d)), 10)


def _fps_range(fps: list[float], digits: int | None = None) -> str:
    """Frame rates said at once: one (to 1e-9) ``411 FPS``, else the lowest to the highest (``101.8 to 102.0 FPS``),
    to ``digits`` significant figures (:func:`_digits` of ``fps`` where not given): a range's ends with their
    trailing zeros, as the tables keep them, so that both show the digits that part them (``13.00 to 13.02 FPS``,
    not ``13 to 13.02``; :func:`~tlm.report.numbers.sig`); one rate as a sentence says it (``12 FPS``)."""
    lo, hi = min(fps), max(fps)
    d = _digits(fps) if digits is None else digits
    return f"{sig(hi, d, zeros=False)} FPS" if same_value(lo, hi) else f"{sig(lo, d)} to {sig(hi, d)} FPS"


def _near(groups: list[list[dict]], rows: list[dict], factors: list[str], digits: int | None = None) -> str:
    """Points tied within :data:`NEAR_TIE` (``groups``: those that differ only in factors that change nothing),
    escaped: as :func:`_said` says tied points, each group with its frame rate where they are named one by one
    (not every combination of their values, at most :data:`MAX_TIED_POINTS` groups); of more groups at once
    (:func:`_span`: the factors that do not part them as ``any k``), with how many of the combinations of those
    values they are (one not among them ran more than :data:`NEAR_TIE` slower, or did not run). Their frame rates
    to ``digits`` significant figures (:func:`_digits` of the groups' where not given)."""
    points = [r for g in groups for r in g]
    whole, every = _span(points, rows, factors)
    if every:
        return esc(whole)
    if len(groups) <= MAX_TIED_POINTS:
        digits = _digits([g[0]["fps"] for g in groups]) if digits is None else digits
        return _said(groups, rows, factors, [f" at {_fps_range([g[0]['fps']], digits)}" for g in groups])
    combos = int(np.prod([len({repr(r.get(k)) for r in points}) for k in factors]))
    got = len({tuple(repr(r.get(k)) for k in factors) for r in points})
    return f"{esc(whole)} ({got} of the {combos} combinations of these values)"


def _grouped(points: list[dict], factors: list[str], inert: list[str]) -> dict[tuple, list[dict]]:
    """The ``points`` by their values of the factors not ``inert`` (those that change nothing), in sweep order."""
    out: dict[tuple, list[dict]] = {}
    for r in points:
        out.setdefault(tuple(repr(r.get(k)) for k in factors if k not in inert), []).append(r)
    return out


def _span(points: list[dict], rows: list[dict], factors: list[str]) -> tuple[str, bool]:
    """``points`` said at once (not escaped): a factor of one value among them ``k = v``, one that takes among
    them each value it takes among ``rows`` ``any k``, else its values among them ``k = 1 or 4`` (in the order
    they first come in ``rows``); and whether the points hold every combination of those values (a ``zip:``'s
    factors, which move together, or a point that failed: they do not, and the words would say more)."""
    parts, combos = [], 1
    for k in factors:
        seen = dict.fromkeys(repr(r.get(k)) for r in points)
        every = list(dict.fromkeys(repr(r.get(k)) for r in rows))
        combos *= len(seen)
        if len(seen) == 1:
            parts.append(f"{k} = {_as_yaml(k, next(iter(seen)))}")
        elif set(seen) >= set(every):
            parts.append(f"any {k}")
        else:
            parts.append(f"{k} = {listing([_as_yaml(k, v) for v in every if v in seen], last='or')}")
    return ", ".join(parts), combos == len({tuple(repr(r.get(k)) for k in factors) for r in points})


def _said(groups: list[list[dict]], rows: list[dict], factors: list[str], after: list[str] | None = None) -> str:
    """Tied points, each of the ``groups`` points that differ only in factors that change nothing, in words,
    escaped: where they hold every combination of their values, or are one group, and have no ``after``, at once
    (:func:`_span`: ``a = 1, any b``; one group not of every combination says so); else each group (its points
    counted) and its ``after``, as :func:`_named` names them."""
    whole, every = _span([r for g in groups for r in g], rows, factors)
    if (every or len(groups) == 1) and after is None:  # (a point failed, a zip: the words would say more, said so)
        return esc(whole) + ("" if every else " (not every combination of these)")
    said = [(f"{len(g)} points: " if len(g) > 1 else "") + _span(g, rows, factors)[0] for g in groups]
    return _named(said, factors, after)


KNN_APART = "the k-NN reference's frame rate is not ranked, its search not modelled"


def _ranked_points(rows: list[dict], out: list[bool | None], factors: list[str], inert: list[str],
                   word: str = "best") -> str:
    """:func:`_best_points` of the ``rows`` whose frame rate is their cost: not those of the k-NN reference
    (``out``: :func:`_unranked`), whose simulated frame time leaves out its search, as the error-vs-cost
    report ranks it by that time nowhere (:func:`~tlm.report.tradeoff.unmodelled_cost`); they are said to be
    left out (every point of the sweep one of them: no point is named); where knn points of another mode are
    ranked (``out`` None: their filter gathers nothing), the clause says those left out are photon-map mode's."""
    ranked = [r for r, o in zip(rows, out, strict=True) if not o]
    knn = "estimate.filter = knn" + (" in mode pmap" if None in out else "")
    if not any(out):
        return _best_points(rows, factors, inert, word=word)
    n = out.count(True)
    errs = [float(r[ERROR]) for r, o in zip(rows, out, strict=True) if o and _number(r.get(ERROR))]
    err = (f"relative MSE {min(errs):.3g}" if n == 1 else f"the lowest relative MSE {min(errs):.3g}") if errs else ""
    if not ranked:
        return f"{KNN_APART}: every point is of {knn}{f' ({err})' if err else ''}."
    said = _best_points(ranked, factors, inert, " of the points ranked", word).removesuffix(".")
    points = "the point" if n == 1 else f"the {n} points"
    return f"{said}; {KNN_APART} ({points} of {knn}{', ' * bool(err)}{err})."


def _unranked(sw: Sweep, rows: list[dict]) -> list[bool | None]:
    """Per row, whether it is a point of the k-NN reference whose frame time leaves out its search
    (:func:`~tlm.report.tradeoff.unmodelled_cost` of its filter) in photon-map mode (``pmap``: in another the
    filter gathers nothing): True; None for a knn point in another mode (ranked, as its filter gathers nothing);
    else False. Its filter is its factor ``estimate.filter`` where the sweep varies it, else its ``estimate``
    section's where that factor gives ``filter`` (a section given merges into the config's), else its point's
    ``config.resolved.yaml`` (a --set or the base config's), its mode its row's ``mode`` else that config's."""
    from tlm.report.tradeoff import unmodelled_cost  # (as summary.py: tradeoff's imports only where asked)

    out: list[bool | None] = []
    for r in rows:
        run = sw.run_of(r)
        config = (run.config if run is not None else None) or {}
        est = config.get("estimate") if isinstance(config.get("estimate"), dict) else {}
        if isinstance(r.get("estimate"), dict) and "filter" in r["estimate"]:
            est = r["estimate"]
        filt = r["estimate.filter"] if "estimate.filter" in r else est.get("filter")
        mode = r.get("mode") or config.get("mode")
        knn = unmodelled_cost({"filter": filt})
        out.append(True if knn and mode in (None, "pmap") else None if knn else False)
    return out


def _where(r: dict, factors: list[str]) -> str:
    """A point's factors, ``a = 1, b = 2`` (not escaped)."""
    return ", ".join(f"{k} = {_as_yaml(k, repr(r.get(k)))}" for k in factors)


def _named(where: list[str], factors: list[str], after: list[str] | None = None) -> str:
    """Points listed (:func:`_where`, each in parentheses where there are more factors than one, then its
    ``after``), escaped: at most :data:`MAX_TIED_POINTS` named, the rest counted
    (:func:`~tlm.config_words.listing`)."""
    return listing([esc(w if len(factors) == 1 else f"({w})") + (after[i] if after else "")
                    for i, w in enumerate(where)], MAX_TIED_POINTS)


def _lowest(rows: list[dict], factors: list[str], inert: list[str], low: float, of: str = "",
            near: dict[int, int] | None = None) -> str:
    """The point of the lowest image error ``low`` among ``rows`` and its frame rate, in words; those
    that tie (to 1e-9), each, as :func:`_best_points` names the tied (not escaped twice), points that differ only
    in the factors ``inert`` counted (:func:`_said`). A frame rate to three significant figures, that of a point
    tied within :data:`NEAR_TIE` to those ``near`` gives it by the point's ``id`` (as the tie's range said it)."""
    def rate(r: dict) -> str:
        return f"{r['fps']:.{(near or {}).get(id(r), 3)}g}"

    points = _grouped([r for r in _measured(rows) if same_value(float(r[ERROR]), low)], factors, inert)
    n = sum(map(len, points.values()))
    if n == 1:
        r = next(iter(points.values()))[0]
        return f"the point of the lowest image error{of} (relative MSE {low:.3g}) is {esc(_where(r, factors))} at " \
               f"{rate(r)} FPS"
    fps = [f" at {rate(g[0])} FPS" for g in points.values()]
    if n > len(points):  # (points that differ only in factors that change nothing: counted, said at once where one can)
        whole, every = _span([r for g in points.values() for r in g], rows, factors)
        if every and len(set(fps)) == 1:
            return f"{n} points tie at the lowest image error{of} (relative MSE {low:.3g}),{fps[0]}: {esc(whole)}"
        return (f"{n} points tie at the lowest image error{of} (relative MSE {low:.3g}): "
                f"{_said(list(points.values()), rows, factors, fps)}")
    named = _named([_where(g[0], factors) for g in points.values()], factors, fps)
    return f"the points of the lowest image error{of} (relative MSE {low:.3g}), tied, are {named}"


def error_factor(inputs: Inputs) -> str:
    """A sentence (after a space) per sweep whose points measured their image error: the factor that
    moves the mean error most, like with like (:func:`_effect` of :data:`ERROR`: the ratio of its
    worst value's mean to its best's; each value's mean where it is not monotone over them: :func:`_error_range`),
    where one factor does (none tied with it); "" else."""
    said = ""
    for sw in inputs.sweeps:
        every = named_rows(sw)
        rows = _measured([r for r in every if r.get("status") == "ok"])
        factors = [*(sw.spec.get("grid") or {}), *(sw.spec.get("zip") or {})]
        spread, refs, keyed = {}, _references(sw, rows), []
        for k in factors:
            along = _moves_with(every, k, factors)
            held = [j for j in factors if j != k and j not in along]
            if _apart(rows, k, held, refs):  # (each value's error against its own reference: not compared, h531)
                keyed.append(k)
                continue
            eff = _effect(rows, k, held, ERROR)
            means = (eff or {}).get("values")
            if means and min(means.values()) > 0 and not same_value(max(means.values()), min(means.values())):
                spread[k] = (max(means.values()) / min(means.values()), eff, along)
        if keyed:
            said += f" In {esc(sw.label)}, no image error is compared across {esc(_and(keyed))}: {_keyed(keyed, refs)}."
        if not spread:
            continue
        k = max(spread, key=lambda f: spread[f][0])
        if sum(same_value(v[0], spread[k][0]) for v in spread.values()) > 1:
            continue  # (two factors move it as much: neither is the one)
        _, eff, along = spread[k]
        said += (f" In {esc(sw.label)}, {esc(k)} moves the image error most"
                 + (f" (with {esc(', '.join(along))}, which {'moves' if len(along) == 1 else 'move'} with it)"
                    if along else "") + f": {_error_range(k, eff, most=True)}.")
    return said


def sweep_findings(inputs: Inputs) -> list[str]:
    """Per sweep, in words: the factor whose values move the mean frame rate most (the ratio
    of its best value's mean to its worst's) and the point of the highest frame rate. Values
    and points that tie (to 1e-9) are said as tied (a best value and a best point that would each
    be one of the tied at random could contradict each other), but for points that differ only in
    factors that change nothing (:func:`_best_points`); of many, the first few and how many more
    (:func:`_values`, :func:`_named`). Where every point runs at one frame rate, the text says what
    else no factor changes (every PM's cycles, the image error: each the same in every point), and
    where a factor moves a PM's cycles, names the factors that change nothing at all after it.

    A factor is judged like with like: its values are compared in the combinations of the
    other factors' values that finished (status ok) with every one of its values, so that a
    failed point does not weigh one value's mean with other points than another's. The text
    says how many ok points were left out for that, names the factors that move together with
    it (a ``zip:``: their effect cannot be told from its own), the factors that change nothing
    between points that differ only in them (neither the frame rate nor, where the points measured
    it, the image error :data:`ERROR`), those that change the image error but not the frame rate
    (from its worst value's mean error to its best's), and those that cannot be compared like with
    like (no combination finished with each of their values). The k-NN reference's points (:func:`_unranked`)
    weigh in no factor's frame rate ratio and are not among the points ranked by it (:func:`_ranked_points`)."""
    texts = []
    for sw in inputs.sweeps:
        every = named_rows(sw)
        rows = [r for r in every if r.get("status") == "ok" and isinstance(r.get("fps"), int | float)]
        factors = [*(sw.spec.get("grid") or {}), *(sw.spec.get("zip") or {})]
        if not rows or not factors:
            continue
        spread, nothing, apart, along, left, errs, unjudged, kept, keyed = {}, [], [], {}, {}, [], [], [], []
        measured = _measured(rows)  # (a factor that keeps the frame rate may still change the image error)
        refs = _references(sw, measured)  # (errors against different references are not compared: h531)
        kept_ref: list[str] = []  # (those of them that keep the frame rate)
        unranked = _unranked(sw, rows)  # (the k-NN reference's points: no factor's frame rate is ranked by them)
        ranked = [r for r, u in zip(rows, unranked, strict=True) if not u]
        for k in factors:
            along[k] = _moves_with(every, k, factors)
            held = [j for j in factors if j != k and j not in along[k]]
            eff = _effect(rows, k, held)
            if eff is None:
                continue
            means = eff["values"]
            if _apart(measured, k, held, refs):
                keyed.append(k)
            err = _effect(measured, k, held, ERROR) if eff["same"] and measured and k not in keyed else None
            if eff["same"] and measured and not (err or {}).get("same"):
                if k in keyed:
                    kept_ref.append(k)
                elif err is not None and err["compared"]:
                    span = _error_range(k, err)
                    errs.append(f"{esc(k)} changes the image error{f' ({span})' if span else ''}, not the frame rate, "
                                f"between points that differ only in it")
                else:
                    unjudged.append(k)
            elif eff["same"] and (moved := _cycles_moved(rows, k, held)) is not None:
                kept.append((k, *moved))  # (the frame rate kept, a PM's cycles not: it does not "change nothing")
                nothing.append(k)  # (its points tie in frame rate: the best point is said once, as of one)
            elif eff["same"]:
                nothing.append(k)
            elif not means:
                apart.append(k)
            elif any(unranked) and not (eff := _effect(ranked, k, held) or {}).get("values"):
                continue  # (it moves the frame rate only with the k-NN reference's points in: not ranked)
            elif min((means := eff["values"]).values()) > 0 and not same_value(max(means.values()),
                                                                               min(means.values())):
                top, bottom = max(means.values()), min(means.values())
                spread[k] = (top / bottom, _extreme(k, means, top), _extreme(k, means, bottom), len(means))
                left[k] = len(ranked) - eff["used"]
        several = len(set(refs.values())) > 1  # (the errors rank no point: each measured against its own reference)
        best = _ranked_points([{**r, ERROR: None} for r in rows] if several else rows, unranked, factors, nothing,
                              "fastest" if several else "best")
        if several:
            best = f"{best.removesuffix('.')}; no point is ranked by its image error: {_keyed(keyed, refs)}."
        text = (f"<b>Sweep {esc(sw.label)}</b> ({len(rows)} of {len(sw.rows)} points ok"
                f"{', ' + esc(with_set(sw.overrides)) if sw.overrides else ''}{esc(sw.unfinished)}): ")
        notes = ""
        inert = [k for k in nothing if k not in {f for f, *_ in kept}]  # (every cycle count the same)
        if inert:
            notes += (f"{esc(', '.join(inert))} {'changes' if len(inert) == 1 else 'change'} nothing "
                      f"{'(neither the frame rate nor the image error) ' if measured else ''}between "
                      f"points that differ only in {'it' if len(inert) == 1 else 'them'}; ")
        moved = "".join(f"{esc(k)} keeps the frame rate between points that differ only in it, but moves {name} "
                        f"({f'by up to {change:.1%}' if change != float('inf') else 'from none in some points'}); "
                        for k, name, change in kept)
        notes += moved
        notes += "".join(f"{e}; " for e in errs)
        if unjudged:
            notes += (f"{esc(', '.join(unjudged))} {'does' if len(unjudged) == 1 else 'do'} not change the frame rate "
                      f"between points that differ only in {'it' if len(unjudged) == 1 else 'them'} (the image error "
                      f"not measured at such points); ")
        if kept_ref and len({r["fps"] for r in rows}) > 1:  # (its errors apart: the closing clause says why)
            notes += (f"{esc(', '.join(kept_ref))} {'does' if len(kept_ref) == 1 else 'do'} not change the frame rate "
                      f"between points that differ only in {'it' if len(kept_ref) == 1 else 'them'}; ")
        if apart:
            notes += (f"{esc(', '.join(apart))} cannot be compared like with like (no values of the other factors "
                      f"finished with each of {'its' if len(apart) == 1 else 'their'} values); ")
        if spread:
            k = max(spread, key=lambda f: spread[f][0])
            ratio, hi, lo, n = spread[k]
            text += f"{esc(k)} moves the frame rate most"
            if along[k]:
                text += f" (with {esc(', '.join(along[k]))}, which {'moves' if len(along[k]) == 1 else 'move'} with it)"
            if ratio * (1 - NEAR_TIE) <= 1:  # (its values' means within NEAR_TIE: they tie, as points there do: h512)
                text += (f", by {1 - 1 / ratio:.2%} between its value{'s' if len(hi) > 1 else ''} of the highest "
                         f"mean ({_values(hi, n)}) and of the lowest ({_values(lo, n)}), within {NEAR_TIE:.0%} (a "
                         f"tie, no best value, as for points within {NEAR_TIE:.0%} of the best), averaged over ")
            else:
                text += (f", {ratio:.2f}x between its best value{'s' if len(hi) > 1 else ''} ({_values(hi, n)}) and "
                         f"its worst ({_values(lo, n)}), averaged over ")
            text += ("the other factors; " if not left[k] else
                     f"the other factors' values that finished with each of its values ({left[k]} of the {len(ranked)} "
                     f"ok points{' ranked' * any(unranked)} left out for that); ")
            text += notes + best
        elif len(rows) == 1:  # (one point ok compares no values: no factor is said to change nothing, h541)
            err = f" with a relative MSE of {float(rows[0][ERROR]):.3g}" if measured else ""
            text += (f"its one point ok runs at {rows[0]['fps']:.3g} FPS{err}; one point compares no factor's values, "
                     "so no factor's effect is measured.")
        elif len({r["fps"] for r in rows}) == 1 and not errs and not kept_ref:  # (a tie everywhere: no best point)
            low = [float(r[ERROR]) for r in measured]
            alike = bool(low) and all(same_value(e, low[0]) for e in low)  # (nor the image error: said so)
            said = ("" if not alike else f" with a relative MSE of {low[0]:.3g}" if len(low) == len(rows) else
                    f", and each of the {len(low)} that measured its image error has a relative MSE of {low[0]:.3g}")
            counts = [[r.get(c) for r in rows] for c in CYCLES]  # (each the same in every point: said so)
            same = not moved and all(all(_number(v) for v in vs) and all(same_value(v, vs[0]) for v in vs)
                                     for vs in counts)
            unchanged = ["the frame rate", *["any PM's cycles"] * same, *["the image error"] * alike]
            kept_said = listing(unchanged, last="or")
            # (where a factor moves a cycle count, it first, then those that change nothing at all and the rest)
            others = f"; {moved}{notes.replace(moved, '', 1)}".removesuffix("; ") if moved else ""
            text += f"no factor changes {kept_said}: every point runs at {rows[0]['fps']:.3g} FPS{said}{others}."
        elif len({r["fps"] for r in rows}) == 1:  # (the image error still tells the points apart)
            text += f"no factor changes the frame rate (every point runs at {rows[0]['fps']:.3g} FPS); " + notes + best
        else:
            text += notes + best
        texts.append(text)
    return texts
