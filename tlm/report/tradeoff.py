"""Section: error against run time (the two curves of docs/design.md, "Error against run time").

(a) From ``tlm error-vs-cost`` folders: the photon-map frame's image RMSE against its
    converged reference, against the simulated frame time (TThru / clock, the
    ``frame_seconds`` column) and against host wall time (photon tracing + gathering,
    ``trace_seconds + gather_seconds``, with the kernels warm: the captions give the one-off
    work left out, the rows' ``one_off_seconds``, :func:`wall_time_caption`). One marker and
    colour per filter (and final-gather count: ``mvoxel + final gather (16 rays)`` is a series of its
    own, after ``mvoxel + final gather (4 rays)``; a point's name adds its caustic photon budget), the
    same in each of a study's figures and in the summary's (:func:`series_styles`); the marker's
    area grows with the photon count; the Pareto front (the points no other point beats
    on both error and time) is drawn as a step line and its points are named. The k-NN reference
    (``knn``) is drawn hollow on the simulated-frame-time figure and left off its front: the timing
    model charges its k photons per query but not its search (:func:`unmodelled_cost`); on the host
    wall time figure, measured time, it is a filter like the others. A reference
    that did not converge (``reference.json``'s ``reference_converged``, or the rows') is said so in
    the axis label, title and caption (:func:`reference_words`); each caption names the reference in one line,
    its key, photons a round, k_nearest, rounds and resolution (:func:`reference_line`, h507). Titles that the
    study's ``--set`` makes long are wrapped (:func:`~tlm.report.common.wrap_title`). An axis is log where its positive
    values span a decade (the RMSE against the ground truth: where one is positive); there a value of 0
    is drawn on a dotted line a decade below the least positive one (:func:`log_floor`), one below 0 is
    left off, and the caption names both by their ``point`` in rows.csv (:func:`off_log_words`). A black
    reference or ground truth (:func:`black_images`: no relative error can be measured) is said first in the
    section (its lead) and in the figures' captions; a black reference's RMSEs (each point's own radiance) draw
    no Pareto front.
(b) From ``tlm granularity`` folders: the TLM's cycle error against its fine reference
    (``max_abs_rel_error``, the largest relative error of any PM's cycles, TThru or the
    latency) against the host wall time of the simulation (``simulate_seconds``), each
    point labelled with its packet size. The reference's error is 0, which a log axis
    cannot show: it is drawn hollow at a floor below the smallest nonzero error, and the
    caption says so. Where a study's sizes ran different frame counts (``frames``: a stream
    that ran on until it settled at some sizes, arch.settle_frames), the host seconds are
    drawn per frame (``simulate_seconds_per_frame``), every study's on the one axis, and a
    note says which ran how many (:func:`granularity_per_frame`); a study written before the
    ``frames`` column cannot be put per frame, and is then left out of the figure, said.

What the section reads of a study and says of it without a figure (its reference's words, black images, the studies'
names, the wall time's caption, a granularity study's points and notes) is :mod:`tlm.report.tradeoff_studies`'s,
imported here.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from tlm.config_words import listing
from tlm.experiments.error_cost_truth import truth_noise_words
from tlm.report.collect import Inputs, Study, with_set
from tlm.report.common import (
    Section,
    colour,
    count,
    legend_below,
    linestyle,
    log_ticks,
    marker,
    new_figure,
    save,
    untangle,
    wrap_title,
)
from tlm.report.html import esc
from tlm.report.tradeoff_studies import (  # (what the section reads of a study and says of it: out of here, h487)
    BLACK_REFERENCE,
    BLACK_TRUTH,
    black_images,
    granularity_per_frame,
    granularity_points,
    granularity_same_rows,
    reference_line,
    reference_words,
    study_names,
    wall_time_caption,
)
from tlm.report.tradeoff_studies import black_words as black_words  # (kept importable from here)
from tlm.report.tradeoff_studies import gran_label as _gran_label
from tlm.report.tradeoff_studies import num as _num
from tlm.report.tradeoff_studies import reference_converged as reference_converged

TITLE_INCHES = 5.6  # the axes' width of an error-vs-cost figure (9 inches wide, its key to the right): its title's


KNN_REFERENCE = "k-NN reference: search not modelled"  # (its key's words on a simulated-frame-time figure)
KNN_WHY = ("the timing model charges its k photons per query but not its search (a scipy k-d tree, no memory "
           "layout of the thesis hardware), so its simulated frame time is not its cost")


def unmodelled_cost(r: dict) -> bool:
    """Whether a row's simulated frame time leaves out its filter's search: the k-NN filter (``knn``, the
    exact reference of :func:`tlm.kernels.estimate.knn_estimate`) is charged its k photons tested per
    query and no tree walk (node_visits and gather_misses 0). Such a row is drawn apart on a figure
    against simulated frame time and is ranked by it nowhere (no Pareto front, no summary's ranking)."""
    return str(r.get("filter")) == "knn"


def pareto_front(cost, error) -> np.ndarray:
    """Which points are on the Pareto front of (cost, error), both to be minimised.

    A point is on the front when no other point has cost <= and error <= with one of them
    strictly smaller (equal points are both on it). Points with a non-finite cost or
    error are never on it (and dominate nothing).
    """
    c = np.asarray(cost, dtype=float)
    e = np.asarray(error, dtype=float)
    on = np.zeros(c.shape[0], dtype=bool)
    ok = np.isfinite(c) & np.isfinite(e)
    idx = np.flatnonzero(ok)
    order = idx[np.lexsort((e[idx], c[idx]))]
    best_e, best_c = math.inf, math.nan
    for i in order:
        if e[i] < best_e:
            on[i] = True
            best_e, best_c = e[i], c[i]
        elif e[i] == best_e and c[i] == best_c:
            on[i] = True  # the same point again
    return on


# where a Pareto number may go around its point (offset points), tried in this order
PARETO_OFFSETS = ((6, 4), (-6, 4), (6, -4), (-6, -4), (0, 10), (0, -10), (12, 0), (-12, 0))


def _log_if_decades(ax, axis: str, values) -> None:
    if _spans_decades(values):
        (ax.set_xscale if axis == "x" else ax.set_yscale)("log")
        log_ticks(ax, axis)


def _spans_decades(values, always: bool = False) -> bool:
    """Whether an axis of ``values`` is drawn log: its positive finite values span a decade or more
    (``always``: where there is one)."""
    v = np.asarray([x for x in values if x is not None and np.isfinite(x) and x > 0], dtype=float)
    return bool(v.size) and (always or v.max() >= 10 * v.min())  # (not max / min: 1 / 5e-324 overflows)


def log_floor(values) -> float:
    """Where a log axis draws a value of 0: a decade below the smallest positive finite one of
    ``values`` (as the granularity figure draws its reference's error 0), at it where a tenth of it is
    0 in floating point (5e-324: not a floor of 0, which no log axis draws); NaN where there is none."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v) & (v > 0)]
    if not v.size:
        return math.nan
    least = float(v.min())
    return least / 10 if least / 10 > 0 else least


def named_off(values, other_drawn) -> np.ndarray:
    """``values`` of the points a caption names as off a log axis (:func:`off_log_words`): each whose other
    coordinate is drawn, and each below 0 (not drawn, whatever the other); NaN for the rest (a 0 whose other
    coordinate is left off is not "drawn at" the floor: its other value's words say it is not drawn)."""
    v = np.asarray(values, dtype=float)
    return np.where(np.asarray(other_drawn, dtype=bool) | (v < 0), v, math.nan)


def as_drawn(values, floor: float | None) -> np.ndarray:
    """``values`` as an axis draws them: as they are on a linear one (``floor`` None); on a log one each 0
    at ``floor`` (:func:`log_floor`) and each below 0 NaN, left off (said: :func:`off_log_words`)."""
    v = np.asarray(values, dtype=float)
    if floor is None:
        return v
    return np.where(v == 0, floor, np.where(v < 0, math.nan, v))


def off_log_words(rows: list[dict], values, floor: float | None, what: str) -> str:
    """Caption words for the points ``rows`` of which a log axis cannot show ``what`` (``values``) as it is
    (``floor`` None: a linear axis, which shows them: ""): each 0 drawn at ``floor`` (the dotted line),
    each below 0 not drawn; both named by their ``point`` in rows.csv."""
    if floor is None:
        return ""
    v = np.asarray(values, dtype=float)
    words = ""
    zero, below = v == 0, np.isfinite(v) & (v < 0)
    if zero.any():
        words += (f" {_points(rows, zero)} {'has' if zero.sum() == 1 else 'have'} {what} of 0, which a log axis cannot "
                  f"show: drawn at {floor:.2g} (the dotted line).")
    if below.any():
        shown = ", ".join(f"{x:.3g}" for x in v[below][:3]) + (", ..." if below.sum() > 3 else "")
        words += (f" {_points(rows, below)} {'has' if below.sum() == 1 else 'have'} {what} below 0 ({shown}), which "
                  "a log axis cannot show: not drawn.")
    return words


def _points(rows: list[dict], mask) -> str:
    """``Point 3`` or ``Points 3, 5 and 7`` of rows.csv (their ``point``; of more than 8, the first 7, then how
    many more: :func:`~tlm.config_words.listing`)."""
    ids = [str(r.get("point", j)) for j, (r, m) in enumerate(zip(rows, mask, strict=True)) if m]
    return f"{'Point' if len(ids) == 1 else 'Points'} {listing(ids, 7)} of rows.csv"


def floor_line(ax, axis: str, floor: float | None, values, what: str) -> None:
    """The dotted line a log axis draws its 0s of ``values`` on (:func:`as_drawn`), labelled in the key."""
    if floor is not None and (np.asarray(values, dtype=float) == 0).any():
        (ax.axvline if axis == "x" else ax.axhline)(floor, color="0.4", linestyle=":", linewidth=1.0, zorder=1,
                                                    label=f"{what} 0, drawn at {floor:.2g}")


def _sizes(photons: np.ndarray) -> np.ndarray:
    """Marker areas (points^2) growing with log photon count."""
    lp = np.log(np.maximum(photons, 1))
    lo, hi = float(lp.min()), float(lp.max())
    t = (lp - lo) / (hi - lo) if hi > lo else np.full(lp.shape, 0.5)
    return 25 + 175 * t


def gather_rays(r: dict) -> int:
    """The final-gather rays of an error-vs-cost row (0: none)."""
    fg = _num(r.get("final_gather"))
    return int(fg) if np.isfinite(fg) and fg > 0 else 0


def series_of(r: dict) -> str:
    """A row's series (marker and colour): its filter, and its final gathering when on
    (``mvoxel + final gather (16 rays)``, as the summary's figure names it)."""
    n = gather_rays(r)
    return f"{r.get('filter')}" + (f" + final gather ({n} rays)" if n else "")


_series = series_of


def series_order(rows: list[dict]) -> list[str]:
    """The series of ``rows`` in the order the report draws and styles them: by filter, then by
    final-gather rays as numbers (4 before 16; none first)."""
    keyed = {series_of(r): (str(r.get("filter")), gather_rays(r)) for r in rows}
    return sorted(keyed, key=lambda name: keyed[name])


def series_styles(rows: list[dict]) -> dict[str, int]:
    """Each series of a study's ``rows`` (all of them, drawn or not) -> its style index
    (:func:`~tlm.report.common.colour`, :func:`~tlm.report.common.marker`,
    :func:`~tlm.report.common.line_style`): one marker and colour per series in every figure of the
    study, whichever rows a figure draws, and the summary's for a single study."""
    return {name: i for i, name in enumerate(series_order(rows))}


def _point_name(r: dict) -> str:
    f = filt = str(r.get("filter"))
    if gather_rays(r):
        f = series_of(r)  # (the series' name: 'knn + final gather'; the settings below go by the filter itself)
    extra = ""
    if filt == "knn" and r.get("k_nearest") is not None:
        extra = f", k={int(r['k_nearest'])}"
    elif filt == "kvoxel" and r.get("k") is not None:
        extra = f", k={int(r['k'])}"
    if filt != "knn" and r.get("radius_fraction") is not None:  # (null: the density rule, or estimate.radius given)
        extra += f", r={_num(r.get('radius_fraction')):g}"
    caustic = _num(r.get("caustic_photons"))
    if np.isfinite(caustic) and caustic > 0:
        extra += f", {int(caustic):,} caustic ph"
    for item in str(r.get("factors") or "").split("; "):  # the point's other settings (render.light_samples=4)
        key = item.split("=", 1)[0]
        if item and key not in _NAMED and not item.endswith("=null"):  # (null: the default, nothing to tell)
            extra += f", {item}"
    return f"{f}, {int(_num(r.get('photons'))):,} ph{extra}"


# the point settings the name above gives already
_NAMED = ("estimate.filter", "photons.count", "estimate.radius_fraction", "estimate.k", "estimate.k_nearest",
          "photons.caustic_count", "estimate.final_gather")


def evc_truth_figure(study: Study, out: Path, name: str, notes: list[str], label: str | None = None):
    """Image RMSE (linear radiance, the same units for both) against host wall time, twice per
    point: the whole composite against the independent ground truth (Mitsuba's path tracer,
    over the pixels away from the lights seen directly: ``truth_rmse``) and the photon-map
    frame alone against our converged reference (the estimator's noise and blur: ``rmse``).
    The two are errors of different images, so their gap is not the model's bias alone.
    (Not their relative MSEs: each is over its own image's energy, and the composite's direct
    light makes its denominator larger, so the composite's could sit below the photon frame's
    while its error in radiance is larger.)"""
    rows = study.rows
    label = label or study.path.name
    own = np.array([_num(r.get("rmse")) for r in rows])
    truth = np.array([_num(r.get("truth_rmse")) for r in rows])
    cost = np.array([_num(r.get("trace_seconds")) + _num(r.get("gather_seconds")) for r in rows])
    ok = np.isfinite(truth) & np.isfinite(cost)
    if not ok.any():
        from tlm.oracle.mitsuba import INSTALL_HINT  # (the hint only: Mitsuba itself is not imported)

        notes.append(f"{label}: no row was measured against a ground truth ('tlm error-vs-cost' with Mitsuba "
                     f"installed, {INSTALL_HINT}): no error against the ground truth.")
        return None
    # a log RMSE axis where there is a positive RMSE (a log time axis where the times span a decade): its 0s
    # drawn at a floor below the least positive value, its values below 0 left off, the caption says which
    errors = np.concatenate([truth[ok], own[ok]])
    y_floor = log_floor(errors) if _spans_decades(errors, always=True) else None
    x_floor = log_floor(cost[ok]) if _spans_decades(cost[ok]) else None
    cx, ty, oy = as_drawn(cost, x_floor), as_drawn(truth, y_floor), as_drawn(own, y_floor)
    fig = new_figure(9, 5.5)
    ax = fig.subplots()
    styles = series_styles(rows)
    for f in [f for f in styles if any(series_of(r) == f for r, k in zip(rows, ok, strict=True) if k)]:
        i = styles[f]
        m = ok & np.isfinite(cx) & np.array([series_of(r) == f for r in rows])
        mt = m & np.isfinite(ty)
        ax.scatter(cx[mt], ty[mt], s=40, c=colour(i), marker=marker(i), edgecolors="black", linewidths=0.6,
                   label=f"{f}: composite vs ground truth", zorder=3)
        mo = m & np.isfinite(oy)
        ax.scatter(cx[mo], oy[mo], s=40, facecolors="none", edgecolors=colour(i), marker=marker(i),
                   linewidths=1.0, label=f"{f}: photon frame alone vs own reference", zorder=3)
        for x, a, b in zip(cx[mo & mt], oy[mo & mt], ty[mo & mt], strict=True):
            ax.plot([x, x], [a, b], color=colour(i), linewidth=0.6, alpha=0.5, zorder=2)
    on_x, on_t, on_o = ok & np.isfinite(cx), ok & np.isfinite(ty), ok & np.isfinite(oy)  # (drawn: x, filled, hollow)
    floor_line(ax, "x", x_floor, cost[on_x & (on_t | on_o)], "host wall time")
    floor_line(ax, "y", y_floor, np.concatenate([truth[on_x & on_t], own[on_x & on_o]]), "RMSE")
    for axis, floor in (("x", x_floor), ("y", y_floor)):
        if floor is not None:
            (ax.set_xscale if axis == "x" else ax.set_yscale)("log")
            log_ticks(ax, axis)
    ax.set(xlabel="host wall time: photon tracing + gathering (s)", ylabel="image RMSE (linear radiance)",
           title=wrap_title(f"{label}: RMSE vs the ground truth and vs our reference", TITLE_INCHES))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    spp = next((r.get("truth_spp") for r in rows if r.get("truth_spp")), None)
    _, unconverged = reference_words(study)
    caption = ("Image RMSE in linear radiance. Filled: the whole composite (every planned frame) against "
               "Mitsuba 3's path tracer" + (f" ({spp} spp)" if spp else "") + ", over the pixels away from the "
               "lights seen directly; hollow: the photon-map frame alone against our own "
               + ("converged k-NN " if not unconverged else "k-NN ") + (reference_line(study) or "reference")
               + (", NOT converged" if unconverged else "")  # (its key, photons a round, k, rounds, size: h507)
               + ", over every pixel; a vertical line joins a point's two errors. They are errors of "
               "different images: the gap holds the other frames' error and what the model leaves out or gets "
               "wrong, not the model's bias alone. " + (f"{unconverged} " if unconverged else "")
               + (f"{truth_noise_words(spp)} " if truth_noise_words(spp) else "")
               + "".join(f"{w} " for w, b in zip((BLACK_TRUTH, BLACK_REFERENCE), black_images(study)[::-1], strict=True)
                         if b)
               + wall_time_caption(rows))
    caption += (off_log_words(rows, named_off(np.where(ok, truth, math.nan), on_x), y_floor,
                              "an RMSE against the ground truth")
                + off_log_words(rows, named_off(np.where(ok, own, math.nan), on_x), y_floor,
                                "an RMSE against our reference")
                + off_log_words(rows, named_off(np.where(ok, cost, math.nan), on_t | on_o), x_floor,
                                "a host wall time"))
    return save(fig, out, name, f"{label}: error against the ground truth and against our reference, "
                "against wall time", caption)


def evc_figure(study: Study, out: Path, name: str, cost_key: str, notes: list[str], label: str | None = None):
    """RMSE against ``cost_key`` ("frame" or "wall") for one error-vs-cost study."""
    rows = study.rows
    if cost_key == "frame":
        cost = np.array([_num(r.get("frame_seconds")) * 1e3 for r in rows])
        xlabel = "simulated frame time TThru / clock (ms)"
        what = "simulated frame time"
    else:
        cost = np.array([_num(r.get("trace_seconds")) + _num(r.get("gather_seconds")) for r in rows])
        xlabel = "host wall time: photon tracing + gathering (s)"
        what = "host wall time"
    err = np.array([_num(r.get("rmse")) for r in rows])
    present = np.isfinite(cost) & np.isfinite(err)
    label = label or study.path.name
    if not present.any():
        if cost_key == "frame":
            notes.append(f"{label}: its rows have no simulated frame time (written before 'tlm error-vs-cost' "
                         f"simulated the frame; run it again): no RMSE against simulated frame time.")
        else:
            notes.append(f"{label}: no row has both an RMSE and host seconds: no RMSE against host wall time.")
        return None
    if not present.all():
        notes.append(f"{label}: {int((~present).sum())} of {len(rows)} rows have no RMSE or no {what} and are not "
                     "drawn.")
    # a log axis where its positive values span a decade: its 0s drawn at a floor below them, its values below 0
    # left off, and the caption says which (off_log_words)
    x_floor = log_floor(cost[present]) if _spans_decades(cost[present]) else None
    y_floor = log_floor(err[present]) if _spans_decades(err[present]) else None
    ok = present & np.isfinite(as_drawn(cost, x_floor)) & np.isfinite(as_drawn(err, y_floor))
    if not ok.any():  # (each point below 0 on one log axis or the other: both linear, every point drawn)
        x_floor = y_floor = None
        ok = present
    photons = np.array([_num(r.get("photons")) for r in rows])
    sizes = _sizes(np.where(np.isfinite(photons), photons, 1)[ok])
    sub = [r for r, k in zip(rows, ok, strict=True) if k]
    c, e = cost[ok], err[ok]
    apart = np.array([cost_key == "frame" and unmodelled_cost(r) for r in sub], dtype=bool)  # (knn: hollow)
    black = black_images(study)[0]  # (a black reference: every RMSE a point's own radiance, none ranked: h417)
    front = pareto_front(np.where(apart | black, math.nan, c), e)  # (of the values: a 0 is the least)
    cd, ed = as_drawn(c, x_floor), as_drawn(e, y_floor)  # (where the points are drawn)
    fig = new_figure(9, 5.5)
    ax = fig.subplots()
    styles = series_styles(rows)
    for f in [f for f in styles if any(series_of(r) == f for r in sub)]:
        i = styles[f]
        m = np.array([series_of(r) == f for r in sub])
        if (m & ~apart).any():
            ax.scatter(cd[m & ~apart], ed[m & ~apart], s=sizes[m & ~apart], c=colour(i), marker=marker(i),
                       edgecolors="black", linewidths=0.6, alpha=0.85, label=f"filter {f}", zorder=3)  # (and gathering)
        if (m & apart).any():
            ax.scatter(cd[m & apart], ed[m & apart], s=sizes[m & apart], facecolors="none", edgecolors=colour(i),
                       marker=marker(i), linewidths=1.2, label=f"filter {f} ({KNN_REFERENCE})", zorder=3)
    o = np.argsort(c[front], kind="stable")
    fc, fe = cd[front][o], ed[front][o]
    if front.any():
        ax.step(fc, fe, where="post", color="black", linestyle="--", linewidth=1.2, zorder=2,
                label="Pareto front (lowest RMSE for no more time)")
        ax.scatter(fc, fe, s=sizes[front][o] * 2.2 + 40, facecolors="none", edgecolors="black", linewidths=1.2,
                   zorder=4)
    front_rows = [sub[j] for j in np.flatnonzero(front)[o]]
    numbers = []
    for j, (x, y, r) in enumerate(zip(fc, fe, front_rows, strict=True)):  # numbered, named in the key:
        numbers.append(ax.annotate(str(j + 1), (x, y), xytext=(6, 4), textcoords="offset points", fontsize=7,
                                   fontweight="bold"))  # (names would overlap where the front's points crowd)
        ax.plot([], [], " ", label=f"{j + 1}: {_point_name(r)}")
    # the photon-count key: one grey marker per size shown
    counts = sorted({int(p) for p in photons[ok] if np.isfinite(p)})
    shown = counts if len(counts) <= 4 else [counts[0], counts[len(counts) // 2], counts[-1]]
    all_sizes = _sizes(np.array(counts, dtype=float)) if counts else np.array([])
    for p in shown:
        ax.scatter([], [], s=float(all_sizes[counts.index(p)]), facecolors="0.7", edgecolors="black",
                   label=f"{p:,} photons")
    for axis, floor, values, zero in (("x", x_floor, c, what), ("y", y_floor, e, "RMSE")):
        floor_line(ax, axis, floor, values, zero)
        if floor is not None:
            (ax.set_xscale if axis == "x" else ax.set_yscale)("log")
            log_ticks(ax, axis)
    against, unconverged = reference_words(study)
    ax.set(xlabel=xlabel, ylabel=f"image RMSE against {against} (linear radiance)",
           title=wrap_title(f"{label}: photon-map RMSE against {what}"
                            + (" (reference NOT converged)" if unconverged else "")
                            + (" (reference black: no error measured)" if black else ""), TITLE_INCHES))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    hidden = untangle(fig, numbers, PARETO_OFFSETS, hide=True)
    caption = (f"{count(int(ok.sum()), 'point')}; marker area grows with the photon count; "
               + (f"ringed and numbered (named in the key): the {count(int(front.sum()), 'point')} of the Pareto "
                  "front." if front.any() else "no Pareto front: the reference is black." if black
                  else "no Pareto front: no point's frame time is modelled in full."))
    if reference_line(study):  # (what the RMSEs are against: its key, photons a round, k, rounds, resolution, h507)
        caption += f" RMSE against {reference_line(study)}."
    if black:
        caption += " " + BLACK_REFERENCE
    if apart.any():
        caption += f" Hollow, and left off the front: the k-NN reference (knn), as {KNN_WHY}."
    # (a point is named by its value on one axis where it is drawn on the other, or that value is below 0: a 0 with
    # a time below 0 is not "drawn at" the floor; ``point``, else its place among all the rows, not the drawn)
    on_x, on_y = present & np.isfinite(as_drawn(cost, x_floor)), present & np.isfinite(as_drawn(err, y_floor))
    caption += off_log_words(rows, named_off(np.where(present, err, math.nan), on_x), y_floor, "an RMSE")
    caption += off_log_words(rows, named_off(np.where(present, cost, math.nan), on_y), x_floor, f"a {what}")
    if hidden:
        caption += (f" Front points {', '.join(t.get_text() for t in hidden)} are ringed but not numbered: "
                    "their number would cover another number or a marker (the key names them).")
    if unconverged:
        caption += " " + unconverged
    if cost_key == "wall":
        caption += " " + wall_time_caption(rows)
    else:
        caption += (" The frame is the whole photon-map frame (ray cast and the other planned passes, photon "
                    "tracing, the photon-map pass) through the timing model.")
    return save(fig, out, name, f"{label}: RMSE against {what}", caption)


def granularity_figure(studies: list[Study], out: Path, name: str, notes: list[str]):
    data = []
    per_frame = any(granularity_per_frame(st) for st in studies)  # (one axis: per frame for all, if for one)
    for st, label in zip(studies, study_names(studies), strict=True):
        size, secs, err = granularity_points(st, per_frame)
        if granularity_per_frame(st):
            notes.append(f"{label}: {granularity_per_frame(st)}.")
        for line in granularity_same_rows(st):  # (its points at those sizes are one row's, drawn at each: h407)
            notes.append(f"{label}: {line.rstrip('.')}.")
        if per_frame and not any(isinstance(r.get("frames"), int) for r in st.rows):
            # (h372: a study written before the frames column, beside one whose sizes ran different frame
            # counts: its seconds are whole simulations' of frames it does not say, not per frame)
            notes.append(f"{label}: written before granularity.csv's frames column, its rows say the host seconds "
                         "of the whole simulation but not the frames simulated, so they cannot be drawn per frame "
                         "beside the studies whose sizes ran different frame counts; not drawn (run the study "
                         "again to draw it).")
            continue
        ok = np.isfinite(size) & np.isfinite(secs) & np.isfinite(err)
        if not ok.all():
            notes.append(f"{label}: {int((~ok).sum())} rows lack a packet size, seconds or error; not drawn.")
        if ok.any():
            data.append((_gran_label(st, label), size[ok], secs[ok], np.abs(err[ok])))
    if not data:
        notes.append("The granularity studies have no complete rows: no cycle-error figure.")
        return None
    positive = np.concatenate([e[e > 0] for *_, e in data])
    log_y = positive.size > 0
    floor = float(positive.min()) / 10 if log_y else 0.0
    fig = new_figure(8.5, 5.2)
    ax = fig.subplots()
    sizes = []  # (each point's packet size, placed where it covers no other label or marker: untangle)
    for i, (label, size, secs, err) in enumerate(data):
        y = np.where(err > 0, err, floor)
        ax.plot(secs, y, color=colour(i), marker=marker(i), linestyle=linestyle(i), markersize=6, label=label,
                zorder=3)
        zero = err == 0
        ax.scatter(secs[zero], y[zero], s=80, facecolors="white", edgecolors=colour(i), marker=marker(i),
                   linewidths=1.5, zorder=4)
        for x, yy, p in zip(secs, y, size, strict=True):
            sizes.append(ax.annotate(f"{int(p)}", (x, yy), xytext=(5, 4), textcoords="offset points", fontsize=7))
    caption = ("Each point is one packet size (labelled; 1 = one ray or pixel per packet, the finest). Error: "
               "the largest |relative error| of any PM's cycles, TThru or the latency against the study's "
               "smallest packet size, its reference.")
    if per_frame:
        caption += (" Host time per frame: a study's packet sizes ran different frame counts (the notes say which: "
                    "a stream that ran on until it settled, arch.settle_frames), so the whole simulation's seconds "
                    "are not comparable.")
    if log_y:
        ax.set_yscale("log")
        ax.axhline(floor, color="0.4", linestyle=":", linewidth=1.0,
                   label=f"error 0 (the reference, hollow) drawn at {floor:.2g}")
        caption += f" Error 0 cannot be shown on the log axis: those points are drawn hollow at {floor:.2g}."
    else:
        notes.append("Every packet size gave exactly the reference's cycles (error 0): a linear error axis.")
    _log_if_decades(ax, "x", np.concatenate([s for _, _, s, _ in data]))
    ax.set(xlabel=f"host wall time of the simulation{' per frame' * per_frame} (s)",
           ylabel="TLM cycle error: max |relative error| vs. the finest packet",
           title="TLM timing error against host wall time, per packet size")
    ax.grid(True, which="both", alpha=0.3)
    legend_below(ax)
    untangle(fig, sizes, PARETO_OFFSETS)
    return save(fig, out, name, "TLM cycle error against host wall time", caption)


def tradeoff_section(inputs: Inputs, out: Path) -> Section:
    sec = Section("tradeoff", "Error against run time")
    evc = inputs.of_kind("error-vs-cost")
    gran = inputs.of_kind("granularity")
    if not evc and not gran:
        sec.absent = ("no error-vs-cost or granularity study among the inputs (written by 'tlm error-vs-cost' "
                      "and 'tlm granularity')")
        return sec
    if not evc:
        sec.notes.append("No error-vs-cost study among the inputs: no image error against run time "
                         "('tlm error-vs-cost' writes one).")
    if not gran:
        sec.notes.append("No granularity study among the inputs: no TLM cycle error against run time "
                         "('tlm granularity' writes one).")
    for i, (st, label) in enumerate(zip(evc, study_names(evc), strict=True)):
        if st.overrides:  # (what ran: the titles say the study's --set, which two studies may differ in alone)
            label = f"{label} ({with_set(st.overrides)})"
        if not st.rows:
            sec.notes.append(f"{label}: the error-vs-cost study has no rows.")
            continue
        for words, black in zip((BLACK_REFERENCE, BLACK_TRUTH), black_images(st), strict=True):
            if black:  # (said plainly, first, above its figures: h417)
                sec.lead += ("<br>" if sec.lead else "") + f"<b>{esc(label)}</b>: {esc(words)}"  # (in <p>)
        for key in ("frame", "wall"):
            fig = evc_figure(st, out, f"tradeoff_{i:02d}_rmse_vs_{key}_time.png", key, sec.notes, label)
            if fig is not None:
                sec.figures.append(fig)
        fig = evc_truth_figure(st, out, f"tradeoff_{i:02d}_bias_vs_wall_time.png", sec.notes, label)
        if fig is not None:
            sec.figures.append(fig)
    if gran:
        fig = granularity_figure(gran, out, "tradeoff_granularity.png", sec.notes)
        if fig is not None:
            sec.figures.append(fig)
    return sec
