"""The words and numbers of the thesis study's printout (out of :mod:`tlm.experiments.thesis`, which
re-exports them): the per-item table ``tlm thesis`` prints (:func:`describe_items`), a summary's held-out
median and slowest-PM count in words, as ``tlm thesis`` and the report quote them (:func:`median_words`,
:func:`slowest_words`), and a number in fixed notation (:func:`fixed`). Tables I-III themselves,
:func:`~tlm.experiments.thesis_tables.describe_rows`, stay beside the metrics they list."""

from __future__ import annotations

import math


def describe_items(items: dict[str, dict], scenes: dict[str, str] | None = None) -> str:
    """The per-item table `tlm thesis` prints: ours (thesis) for each scene-mode, in fixed
    notation (:func:`fixed`); ``scenes``: each scene's name in the printout
    (:func:`~tlm.experiments.thesis.scene_names`)."""
    names = (("trav_cycles_per_ray", "TTrav/ray"), ("tests_per_ray", "tests/ray"),
             ("frag_cycles_per_pixel", "TFrag/pixel"), ("vert_cycles_per_triangle", "TVert/tri"))
    keys = [(*key.rsplit("/", 1), it) for key, it in items.items()]
    shown = [(scenes or {}).get(scene, scene) for scene, _, _ in keys]
    wide = max([8, *map(len, shown)])
    lines = [f"{'scene':{wide}s} {'mode':8s} {'rays':>8s} " + " ".join(f"{h:>21s}" for _, h in names)
             + f" {'tests/leaf':>10s}"]
    for scene, (_, mode, it) in zip(shown, keys, strict=True):
        cells = []
        for k, _ in names:
            o, t = it["ours"][k], it["thesis"][k]
            cells.append(f"{'-' if o is None else fixed(o):>9s} ({'-' if t is None else fixed(t):>9s})")
        leaf = it["tests_per_leaf"]
        lines.append(f"{scene:{wide}s} {mode:8s} {it['rays']:>8d} " + " ".join(f"{c:>21s}" for c in cells)
                     + f" {'-' if leaf is None else fixed(leaf):>10s}")
    return "\n".join(lines)


def median_words(s: dict) -> str:
    """A :func:`~tlm.experiments.thesis.summarize`'s held-out median in words, as every place that quotes it says it:
    over how many cells, or why there is none (scenes not comparable, no thesis value). The median is over
    the held-out cells that are predictions of their own (``median_abs_rel_error_predicted``), saying which
    were left out as another cell again and the median over every held-out cell with them; a summary
    written before that key was added gives the held-out median alone, as it then said it."""
    med, why = s["median_abs_rel_error_held_out"], s.get("median_withheld")
    if med is None:
        return f"no median |relative error| ({why or 'no cell with a thesis value'})"
    tail = f" ({why})" if why else ""
    if "median_abs_rel_error_predicted" not in s:
        return f"median |relative error| over the {s['held_out_cells_compared']} held-out cells: {med:.1%}{tail}"
    left = s.get("not_predictions") or {}
    n_left = s.get("not_predictions_compared", 0)
    every = f"over all {s['held_out_cells_compared']} held-out cells {med:.1%}"
    if not left or not n_left:
        return f"median |relative error| over the {s['held_out_cells_compared']} held-out cells: {med:.1%}{tail}"
    which = "; ".join(f"{k} ({v})" for k, v in left.items())
    pred = s["median_abs_rel_error_predicted"]
    if pred is None:
        return f"no held-out cell is a prediction of its own (left out: {which}); {every}{tail}"
    repeat = "repeats" if n_left == 1 else "repeat"
    return (f"median |relative error| over the {s['predicted_cells_compared']} held-out cells that are "
            f"predictions of their own: {pred:.1%} (left out, {n_left} that {repeat} another cell: {which}; "
            f"{every}){tail}")


def slowest_words(s: dict) -> str:
    """A :func:`~tlm.experiments.thesis.summarize`'s slowest-PM count in words, qualified as
    :func:`median_words` qualifies the median: over the comparable scene-modes alone where some
    are not comparable, and said to be of a setting not the thesis's where none is (a count
    against another setting measures the setting, not the model)."""
    n, m = s["scene_modes"], s["slowest_pm_matches"]
    n_ok, m_ok = s.get("slowest_pm_comparable", n), s.get("slowest_pm_matches_comparable", m)
    if n_ok == n:
        return f"slowest PM as in the thesis in {m} of {n} scene-modes"
    if n_ok:
        return (f"slowest PM as in the thesis in {m_ok} of {n_ok} comparable scene-modes "
                f"({n - n_ok} not comparable left out)")
    return (f"slowest PM as in the thesis in {m} of {n} scene-modes, none comparable with the thesis "
            "(a count of the setting, not of the model)")


def fixed(x: float, digits: int = 4) -> str:
    """A number in fixed notation to ``digits`` significant figures, a large one whole: ``0.01234``,
    ``12.35``, ``21470`` (not ``2.147e+04``)."""
    if not math.isfinite(x) or x == 0:
        return f"{x:g}"
    return f"{x:.{max(0, digits - 1 - math.floor(math.log10(abs(x))))}f}"
