"""Tables I-III of the thesis: its figures, a cell of ours beside them, and the tables as ``tlm thesis``
prints them (out of :mod:`tlm.experiments.thesis`, which imports every name from here, :func:`ours` as ``_ours``).

* :data:`THESIS` — millions of cycles (FPS in frames per second) per scene, metric and mode;
  :func:`thesis_value` one cell; :data:`CALIBRATED` (of which a table's :func:`fitted_cells`),
  :data:`NOT_PREDICTIONS` (:func:`not_prediction`),
  :data:`FIT_PMS` and :data:`FIT_RECORDS` what the calibration fits and what is no prediction.
* :func:`ours` — a run's cycles as the tables' metrics; :func:`comparison_rows` and :func:`with_comparable`
  the rows of ``thesis_comparison.csv`` (:data:`COLUMNS`); :func:`describe_rows` the printout.
"""

from __future__ import annotations

from typing import Any

from tlm.arch.model import PM_TABLE_NAMES
from tlm.config import MODES
from tlm.experiments.thesis_text import fixed

# Tables I-III: millions of cycles (FPS in frames per second).
THESIS = {
    "ring": {
        "TVert": (0.378, 0.378, 0.378, 1.34), "TTrav": (24.4, 31.6, 68.6, 64.4),
        "Tisct": (10.8, 15.4, 26.1, 27.8), "TFrag": (4.12, 4.42, 6.28, 16.9),
        "TThru": (24.8, 32.0, 68.9, 64.9), "FPS": (24.2, 18.8, 8.71, 9.24),
    },
    "room": {
        "TVert": (4.57, 4.57, 4.57, 8.47), "TTrav": (41.2, 43.8, 91.4, 113),
        "Tisct": (47.7, 51.9, 110, 123), "TFrag": (5.96, 6.28, 79.0, 178),
        "TThru": (47.9, 52.1, 110.4, 178), "FPS": (12.5, 11.5, 5.43, 3.037),
    },
    "cornell": {
        "TVert": (1.52, 1.52, 1.52, 8.73), "TTrav": (42.7, 46.3, 75.8, 107),
        "Tisct": (37.9, 39.6, 64.3, 102), "TFrag": (8.14, 8.49, 10.3, 210),
        "TThru": (43.0, 46.7, 76.1, 210), "FPS": (14.0, 12.9, 7.88, 2.86),
    },
}
METRICS = ("TVert", "TTrav", "Tisct", "TFrag", "TThru", "FPS")
PM_METRICS = ("TVert", "TTrav", "Tisct", "TFrag")
# The cells a calibration may fit: the RCast column's (tlm calibrate); which scenes' were fitted is the
# table's own word, its calibration block's cells (:func:`fitted_cells`), not this set's
CALIBRATED = {("rcast", "TVert"), ("rcast", "TTrav"), ("rcast", "TFrag")}
# Held-out cells that are no prediction of their own, each another cell again (in the thesis's
# tables and in ours alike): the headline median leaves them out (:func:`tlm.experiments.thesis.summarize`),
# the CSV keeps them.
# Their kind (as the summary's ``not_predictions`` names it) -> why.
NOT_PREDICTIONS = {
    "TVert in Reflect and Refract": "the fitted RCast TVert again: one geometry BSP a frame, whatever the mode",
    "FPS": "clock / TThru, 600 MHz at the thesis's setting: the TThru cell again",
}
FIT_PMS = {"vertex": "TVert", "traversal": "TTrav", "fragment": "TFrag"}
# PMs whose record_cycles are fitted beside their scale: the thesis's TTrav is nearly the
# same per traced ray in its three scenes, and its TFrag has a per-pixel part as large as
# its per-hit part (docs/fidelity.md, "Cycles per record")
FIT_RECORDS = ("traversal", "fragment")
COLUMNS = ("scene", "mode", "metric", "thesis", "ours", "rel_error", "calibrated", "comparable", "not_comparable")


def not_prediction(mode: str, metric: str) -> str | None:
    """The kind of :data:`NOT_PREDICTIONS` a held-out cell is (None: a prediction of its own)."""
    if metric == "FPS":
        return "FPS"
    if metric == "TVert" and mode in ("reflect", "refract"):
        return "TVert in Reflect and Refract"
    return None


def thesis_value(scene: str, mode: str, metric: str) -> float | None:
    table = THESIS.get(scene)
    return None if table is None else table[metric][MODES.index(mode)]

# the keys of a run's results.json ``cycles`` that :func:`ours` reads (tlm report checks a run's file has them)
OURS_CYCLES = (*PM_TABLE_NAMES, "throughput")


def ours(cycles: dict, fps: float) -> dict[str, float]:
    out = {PM_TABLE_NAMES[pm]: cycles[pm] / 1e6 for pm in PM_TABLE_NAMES}
    out["TThru"] = cycles["throughput"] / 1e6
    out["FPS"] = fps
    return out


def fitted_cells(calibration: dict | None) -> frozenset[tuple[str, str]]:
    """The cells an instruction table was fitted to, ``(scene, metric)`` of the RCast column, as its
    ``calibration`` block's ``cells`` name them (``tlm calibrate`` writes one entry per scene it fitted);
    none for a table without the block (nothing it says was fitted)."""
    cells = (calibration or {}).get("cells") if isinstance(calibration, dict) else None
    if not isinstance(cells, dict):
        return frozenset()
    metrics = {m for _, m in CALIBRATED}
    return frozenset((str(s), str(m)) for s, c in cells.items() if isinstance(c, dict) for m in c if m in metrics)


def packaged_fitted() -> frozenset[tuple[str, str]]:
    """:func:`fitted_cells` of the packaged table (``tlm/arch/programs.yaml``)."""
    from tlm.arch.costs import load_programs

    return fitted_cells(load_programs().calibration)


def comparison_rows(scene: str, mode: str, ours: dict[str, float],
                    fitted: frozenset[tuple[str, str]] | None = None) -> list[dict]:
    """A scene-mode's rows (:data:`COLUMNS` but the last two): ``calibrated`` true only for a cell of
    :data:`CALIBRATED` with a thesis value that the table in use was fitted to (``fitted``, its
    :func:`fitted_cells`; None: the packaged table's). A scene with no table has nothing fitted to it."""
    fitted = packaged_fitted() if fitted is None else fitted
    rows = []
    for metric in METRICS:
        t = thesis_value(scene, mode, metric)
        o = ours[metric]
        rows.append({
            "scene": scene, "mode": mode, "metric": metric, "thesis": t, "ours": round(o, 6),
            "rel_error": None if t is None else round((o - t) / t, 6),
            "calibrated": t is not None and (mode, metric) in CALIBRATED and (scene, metric) in fitted,
        })
    return rows


def with_comparable(rows: list[dict], not_comparable: dict[str, list[str]]) -> list[dict]:
    """``rows`` (:func:`comparison_rows`) with whether each can be compared with the thesis:
    ``comparable`` false and ``not_comparable`` how ours differs (``"; "``-joined, as the
    summary's words join them) for a row whose scene is in ``not_comparable`` (its rows'
    name -> how, :func:`~tlm.experiments.thesis_setting.mismatches`), true and None for another; both None where
    the thesis has no value (nothing to compare). Its ``rel_error`` is kept, as the report keeps the
    value: a reader of the CSV is told, not left to join it with the summary."""
    out = []
    for r in rows:
        why = [] if r["thesis"] is None else list((not_comparable or {}).get(str(r["scene"])) or [])
        out.append({**r, "comparable": None if r["thesis"] is None else not why,
                    "not_comparable": "; ".join(why) if why else None})
    return out


def describe_rows(rows: list[dict[str, Any]], scenes: dict[str, str] | None = None) -> str:
    """Tables I-III as `tlm thesis` prints them: ours (thesis) per scene-mode and metric;
    ``scenes``: each scene's name in the printout (:func:`tlm.experiments.thesis.scene_names`)."""
    cells: dict[tuple[str, str], dict[str, dict]] = {}
    for r in rows:
        cells.setdefault(((scenes or {}).get(str(r["scene"]), str(r["scene"])), r["mode"]), {})[r["metric"]] = r
    wide = max([8, *(len(scene) for scene, _ in cells)])
    lines = [f"{'scene':{wide}s} {'mode':8s} " + " ".join(f"{m:>16s}" for m in METRICS)]
    for (scene, mode), m in cells.items():
        parts = []
        for metric in METRICS:
            r = m[metric]
            t = "-" if r["thesis"] is None else f"{r['thesis']:g}"
            parts.append(f"{fixed(r['ours'], 3):>7s} ({t:>6s})")
        lines.append(f"{scene:{wide}s} {mode:8s} " + " ".join(f"{p:>16s}" for p in parts))
    return "\n".join(lines)
