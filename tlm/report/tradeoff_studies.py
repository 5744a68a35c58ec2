"""What the error-against-run-time section (:mod:`tlm.report.tradeoff`) reads of a study and says of it without a
figure: an error-vs-cost study's reference, converged or not (:func:`reference_converged`, :func:`reference_words`),
named in one line (:func:`reference_line`),
and black or not with its ground truth (:func:`black_images`, :func:`black_words`), the studies' short names
(:func:`study_names`), what its host wall time holds (:func:`wall_time_caption`); a granularity study's label, its
frame counts (:func:`granularity_per_frame`), its own notes (:func:`granularity_same_rows`) and its points
(:func:`granularity_points`). Out of :mod:`tlm.report.tradeoff` (h487), which imports them all (``num`` and
``gran_label`` by their old names there, ``_num`` and ``_gran_label``), so each is still importable from there.
"""

from __future__ import annotations

import math

import numpy as np
import yaml

from tlm.config_words import listing, safe_load
from tlm.experiments.granularity import frames_differ
from tlm.report.collect import Study
from tlm.report.html import esc
from tlm.report.names import scene_label


def num(v) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return math.nan
    return f


def reference_converged(study: Study) -> bool | None:
    """Whether the study's reference met its tolerance: ``reference.json``'s ``reference_converged``
    (else its ``converged``), else the rows' ``reference_converged``; None where nothing says."""
    ref = study.meta.get("reference") if isinstance(study.meta, dict) else None
    for key in ("reference_converged", "converged"):
        if isinstance(ref, dict) and isinstance(ref.get(key), bool):
            return ref[key]
    said = {r.get("reference_converged") for r in study.rows if isinstance(r.get("reference_converged"), bool)}
    return None if not said else all(said)


def reference_words(study: Study) -> tuple[str, str]:
    """``(short, long)`` words for the reference a study's ``rmse`` is against: ``"the converged
    reference"``, or where it did not converge ``"the reference (NOT converged)"`` and a sentence
    with its relative standard error, rounds and tolerance (``reference.json``)."""
    if reference_converged(study) is not False:
        return "the converged reference", ""
    ref = study.meta.get("reference") if isinstance(study.meta.get("reference"), dict) else {}
    err, rounds, tol = (num(ref.get(k)) for k in ("relative_standard_error", "rounds", "tolerance"))
    how = ", ".join(w for w in (
        f"relative standard error {err:.3g}" if np.isfinite(err) else "",
        f"after {int(rounds)} rounds" if np.isfinite(rounds) else "",
        f"above its tolerance {tol:g}" if np.isfinite(tol) else "") if w)
    return ("the reference (NOT converged)",
            f"The reference did NOT converge ({how or 'reference.json'}): each RMSE against it includes the "
            "reference's own noise.")


def reference_line(study: Study) -> str:
    """The reference an error-vs-cost study's ``rmse`` and ``rel_mse`` are against, in one line (h507): its key,
    photons a round, k_nearest, rounds, relative standard error and resolution, from its ``reference.json``
    (:func:`~tlm.experiments.reference.reference_named`; a study written before its resolution was kept names
    fewer); "" where it has none."""
    from tlm.experiments.reference import reference_named

    ref = study.meta.get("reference") if isinstance(study.meta, dict) else None
    if not isinstance(ref, dict) or not isinstance(ref.get("key"), str):
        return ""
    return reference_named(ref["key"], *(ref.get(k) for k in ("photons", "k_nearest", "rounds", "resolution",
                                                                "relative_standard_error")))


def black_images(study: Study) -> tuple[bool, bool]:
    """Whether the study's photon-map reference, and its ground truth, are black (every pixel 0: a camera that
    sees nothing lit), so that no relative error can be measured against it: ``reference.json``'s
    ``reference_black`` and ``truth_black`` (h417), else, for a study written before them, its rows (an
    ``rmse`` in some row and a ``rel_mse`` of null in every row; a ``truth_rmse`` and no ``truth_rel_mse``)."""
    ref = study.meta.get("reference") if isinstance(study.meta, dict) else None
    ref = ref if isinstance(ref, dict) else {}

    def rows_say(err: str, rel: str) -> bool:
        return (any(np.isfinite(num(r.get(err))) for r in study.rows)
                and all(rel in r and r[rel] is None for r in study.rows))

    ref_black, truth_black = (ref[k] if isinstance(ref.get(k), bool) else rows_say(err, rel) for k, err, rel in
                              (("reference_black", "rmse", "rel_mse"), ("truth_black", "truth_rmse", "truth_rel_mse")))
    return ref_black, truth_black


def black_words(studies: list[Study], err: str) -> tuple[list[Study], str]:
    """The error-vs-cost studies of no ``err`` in any row whose image it is measured against, the reference
    (``rel_mse``) or the ground truth (``truth_rel_mse``), is black (:func:`black_images`), and an HTML sentence
    saying so (the summary's "What quality costs": not "written before the frame was simulated", h419)."""
    black = [st for st in studies if all(r.get(err) is None for r in st.rows) and black_images(st)[err != "rel_mse"]]
    names = [n for st, n in zip(studies, study_names(studies), strict=True) if any(st is b for b in black)]
    whose = "" if len(studies) == 1 else f" of {'each of ' * (len(names) > 1)}{listing(names)}"
    what = "ground truth" + whose if err != "rel_mse" else "photon-map reference" + whose + (
        " (and its ground truth)" if black and all(black_images(st)[1] for st in black) else "")
    return black, (f"The {esc(what)} is black (every pixel 0; 'tlm run' of the base says why, e.g. a camera "
                   "that faces nothing): no relative error can be measured against it, so its points have no "
                   "relative MSE." if black else "")


BLACK_REFERENCE = ("The photon-map reference is black (every pixel 0; 'tlm run' of the base says why, e.g. a camera "
                   "that faces nothing): no relative error can be measured (every row's rel_mse is empty), and each "
                   "RMSE against it is the point's own radiance, not its filter's error, so no point is ranked by it "
                   "(no Pareto front).")
BLACK_TRUTH = ("The ground truth is black (every pixel 0): no relative error against it can be measured (every row's "
               "truth_rel_mse and truth_flip are empty), and each RMSE against it is the composite's own radiance.")


def study_names(studies: list[Study]) -> list[str]:
    """Short names of studies: the folder's, with its parent's where two folders share one."""
    names = [s.path.name for s in studies]
    return [f"{s.path.parent.name}/{n}" if names.count(n) > 1 else n for s, n in zip(studies, names, strict=True)]


def wall_time_caption(rows: list[dict]) -> str:
    """What an error-vs-cost study's host wall time holds, and the one-off work it leaves out
    (numba compiling or loading kernels and first imports while the points were warmed up and
    timed, and the eye paths' walks: :class:`tlm.experiments.error_cost.WarmUp`): how many seconds
    in all (the rows' ``one_off_seconds``) and which rows' settings needed the most of it; for a
    study written before that column, what its first rows may hold."""
    one_off = np.array([num(r.get("one_off_seconds")) for r in rows])
    if not np.isfinite(one_off).any():
        return ("Host wall time: the point's photon trace (a map shared by several points is counted in full by "
                "each: its cost if run alone) and its gather. This study was written before one-off work was kept "
                "apart: the first point to trace a photon map or run a filter may include numba compiling (or "
                "loading) the kernels and the first imports, paid once per process, and the first point to gather "
                "a map the making of its leaf order and density radii (seconds: such a point sits that much too "
                "far right); run 'tlm error-vs-cost' again.")
    total = float(np.nansum(one_off))
    order = [int(j) for j in np.argsort(-np.where(np.isfinite(one_off), one_off, -1.0), kind="stable")[:3]
             if np.isfinite(one_off[j]) and one_off[j] > 0]
    named = [f"{rows[j].get('point', j)} ({one_off[j]:.3g} s)" for j in order]
    most = (f"; most of it for the settings of row{'s' if len(named) > 1 else ''} "
            f"{listing(named)} of rows.csv" if named else "")
    return ("Host wall time: the point's photon maps (trace, leaf order, density radii) and its gather, with the "
            "kernels warm; a map shared by several points is counted in full by each (its cost if run alone). "
            "One-off work is charged to no point: the seconds in which numba compiled or loaded a kernel or a "
            "module was imported for the first time, while the points were warmed up and timed, and the eye "
            "paths' walks through mirrors and glass (once per render setting), paid by whichever point needed "
            f"them first: {total:.3g} s in all, left out of every point's time{most} (each row's one_off_seconds). "
            "The warm-ups' own small traces and gathers are in neither the points' times nor that total.")


def gran_label(study: Study, name: str) -> str:
    cfg = study.path / "config.resolved.yaml"
    try:
        # (aliases bounded: config_words.safe_load)
        c = safe_load(cfg.read_text(encoding="utf-8")) if cfg.is_file() else None
    except (OSError, yaml.YAMLError):
        c = None
    if isinstance(c, dict) and c.get("scene"):  # (a user's scene file as the report names it: scene_label)
        return f"{name} ({scene_label(str(c['scene']), str(c['scene']))}/{c.get('mode')})"
    return name


def granularity_per_frame(study: Study) -> str:
    """Where the study's packet sizes ran different frame counts (h364: a stream that ran on past
    ``arch.frames`` until it settled at some sizes and not at others), a note saying which ran how
    many, whose host seconds are then compared per frame; "" where they ran the same (or the rows
    hold no ``frames``: a study written before the column)."""
    ran = frames_differ(study.rows)
    if not ran:
        return ""
    # (the frame count of most sizes, the fewer frames on a tie: "the others", where they are two or more
    # sizes; where each count ran at one size, every size is named: "the others" would be one, unnamed)
    most = max(ran, key=lambda f: (len(ran[f]), -f))
    most = most if len(ran[most]) > 1 else None
    counts = "; ".join([*(f"{f} at packets of {', '.join(str(s) for s in sizes)}" for f, sizes in ran.items()
                          if f != most), *([f"{most} at the others"] if most is not None else [])])
    return (f"the packet sizes ran different frame counts ({counts}: a stream ran on until its completions "
            "repeated, arch.settle_frames), so host seconds are per frame")


def granularity_same_rows(study: Study) -> list[str]:
    """The study's own notes (its ``granularity_summary.json``'s ``notes``: two or more packet sizes at or past the
    items of the frame's largest phase, which run every phase as one packet and so give the same rows, as ``tlm
    granularity`` said under its table: h400, h407); [] for a study written before them, or a record without. Only
    its lines of text: a damaged record's ``null`` or number is no line (it was said, ``g: None.``: h410)."""
    record = study.meta.get("granularity_summary") if isinstance(study.meta, dict) else None
    notes = record.get("notes") if isinstance(record, dict) else None
    return [n for n in notes if isinstance(n, str) and n.strip()] if isinstance(notes, list) else []


def granularity_points(study: Study, per_frame: bool | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(packet sizes, host seconds, max |relative cycle error|), by packet size. The seconds are per frame
    (``simulate_seconds_per_frame``) where ``per_frame``, by default where the sizes ran different frame
    counts (:func:`granularity_per_frame`); otherwise the whole simulation's (``simulate_seconds``)."""
    per_frame = bool(granularity_per_frame(study)) if per_frame is None else per_frame
    rows = sorted(study.rows, key=lambda r: num(r.get("packet_size")))
    size = np.array([num(r.get("packet_size")) for r in rows])
    secs = np.array([num(r.get("simulate_seconds_per_frame" if per_frame else "simulate_seconds")) for r in rows])
    err = np.array([num(r.get("max_abs_rel_error")) for r in rows])
    return size, secs, err
