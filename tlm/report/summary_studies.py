"""What the report's summary (:mod:`tlm.report.summary`) says of the studies in words, without a figure: the
error-vs-cost studies' series told apart (:func:`study_labels`) and what their lowest error is a sample of, one seed's
or several (:func:`seeds_words`); the errors the page shows elsewhere where no error-vs-cost study is among the inputs
(:func:`other_errors`); the granularity and extreme studies' findings (:func:`study_findings`). Out of
:mod:`tlm.report.summary` (h487), which imports them by their old names there (``_study_labels``, ``_seeds_words``,
``_other_errors``, ``_base_seed``) and re-exports :func:`study_findings`.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

from tlm.config import ArchConfig
from tlm.report.collect import Inputs
from tlm.report.html import esc
from tlm.report.summary_effects import error_factor
from tlm.report.summary_points import count as _count
from tlm.report.summary_points import number as _number
from tlm.report.summary_points import points_error, references


def study_labels(studies: list) -> dict[int, str]:
    """Per error-vs-cost study (by ``id``), what tells its series apart from another study's in the
    summary's figure: "" for one study; else its name (:func:`~tlm.report.tradeoff.study_names`) and
    the ``--set`` overrides that not every study shares (two folders that differ only by ``--set``
    are two series, not one)."""
    from tlm.report.tradeoff import study_names

    if len(studies) < 2:
        return {id(st): "" for st in studies}
    common = set.intersection(*(set(st.overrides) for st in studies))
    out = {}
    for st, name in zip(studies, study_names(studies), strict=True):
        own = [o for o in st.overrides if o not in common]
        out[id(st)] = f"{name}: --set {', '.join(own)}" if own else name
    return out


def row_seed(r: dict) -> str:
    """The seed of an error-vs-cost row: its point's (``seed=1`` among its ``factors``), else its
    study's ``--set seed=``, else its study's base seed (named by the study's folder)."""
    for part in str(r.get("factors") or "").split("; "):
        if part.strip().startswith("seed="):
            return part.strip()[len("seed="):]
    study = r.get("_study")
    for o in getattr(study, "overrides", None) or []:
        if o.startswith("seed="):
            return o[len("seed="):]
    return base_seed(getattr(study, "path", None))


def base_seed(folder: Path | None) -> str:
    """An error-vs-cost study's base seed, from its ``config.resolved.yaml`` (its folder's name where
    that cannot be read: a seed of its own)."""
    import yaml

    from tlm.config_words import safe_load

    try:
        seed = (safe_load((Path(folder) / "config.resolved.yaml").read_text(encoding="utf-8")) or {}).get("seed")
    except (OSError, TypeError, AttributeError, yaml.YAMLError):
        seed = None
    return str(seed) if seed is not None else f"the base of {getattr(folder, 'name', '?')}"


def seeds_words(rows: list[dict], err: str, series_of) -> str:
    """What "the lowest error" of the error-vs-cost rows is a sample of, a sentence: that they are one
    seed's (one photon map per count: which filter wins by a small margin is the seed's as much as the
    filter's, and another seed can reorder them), else each series' lowest error per seed: in how many
    seeds it is the lowest (where there are two series or more to compare), its mean and range over the seeds."""
    by_seed: dict[str, list[dict]] = defaultdict(list)
    for r in rows:
        by_seed[row_seed(r)].append(r)
    if len(by_seed) < 2:
        only = next(iter(by_seed))
        only = f"seed {only}" if only.lstrip("-").isdigit() else only
        if len({series_of(r) for r in rows}) < 2:  # (one series: no other to reorder it with)
            return (f" These rows are of one seed ({only}): another seed's photon maps give other errors (a seed "
                    "key in the study's points gives the spread).")
        return (f" These rows are of one seed ({only}): where the filters' errors are close, another "
                "seed's photon maps can reorder them (a seed key in the study's points gives the spread).")
    names = list(dict.fromkeys(series_of(r) for r in rows))
    wins: dict[str, int] = defaultdict(int)
    per: dict[str, list[float]] = defaultdict(list)
    for rs in by_seed.values():
        best = {}
        for r in rs:
            k = series_of(r)
            if k not in best or r[err] < best[k]:
                best[k] = r[err]
        wins[min(best, key=best.get)] += 1
        for k, v in best.items():
            per[k].append(v)
    compared = len(names) > 1  # (a winner count of one series would be a comparison with nothing)
    parts = [f"{k}: " + (f"lowest in {wins[k]} of {len(by_seed)}, " if compared else "")
             + f"mean {np.mean(per[k]):.3g} ({min(per[k]):.3g}-{max(per[k]):.3g}) over {len(per[k])} seeds"
             for k in names if per[k]]
    whose = "each series'" if compared else "its one series'"
    return f" Over the rows' {len(by_seed)} seeds, {whose} lowest error per seed: {'; '.join(parts)}."


def other_errors(inputs: Inputs) -> str:
    """What "What quality costs" says with no error-against-cost rows to draw: the errors the page
    shows elsewhere (a run's photon-map error in §2, the granularity study's cycle error in §6), each as a
    relative MSE (as the error-against-cost figures and the sweep points' are)."""
    runs = [r for r in inputs.runs if r.images is not None and (r.results.get("error") or {}).get("available")
            and _number((r.results.get("error") or {}).get("rel_mse"))]
    shown = []
    if runs:
        rel = [r.results["error"]["rel_mse"] for r in runs]
        lo, hi = f"{min(rel):.3g}", f"{max(rel):.3g}"
        keys = [r.results["error"].get("reference") for r in runs]
        shown.append(f"§2 shows the photon-map error of {_count(len(runs), 'run')} against "
                     f"{references(keys).replace('their', 'its') if len(runs) == 1 else references(keys)} "
                     f"(relative MSE {lo if lo == hi else f'{lo}–{hi}'})")
    if inputs.of_kind("granularity"):
        shown.append("§6 shows the TLM cycle error of the granularity study against host time")
    points = points_error(inputs) + error_factor(inputs)
    if not shown and not points:
        return "No error-against-cost study among the inputs: no error to show."
    return ("<b>What quality costs:</b> no error-against-cost study among the inputs: no image error against run "
            f"time{'; ' if shown else ''}{'; '.join(shown)}." + points)


GRANULARITY_TOLERANCE = 0.01  # the cycle error against packets of one that the summary calls close


def granularity_finding(name: str, size: np.ndarray, secs: np.ndarray, err: np.ndarray, frames: str = "") -> str:
    """One granularity study in words (sizes increasing, the smallest the reference): the
    largest packet up to which EVERY size keeps within the tolerance (the error need not fall
    steadily with the size: a size that comes back within it past one that does not is said
    as such, not taken for the finding), then the default size's error (``arch.packet_size``).
    ``frames``: where the sizes ran different frame counts, the note that says so
    (:func:`~tlm.report.tradeoff.granularity_per_frame`); ``secs`` are then per frame."""
    per = " a frame" if frames else ""
    ref = int(np.argmin(size))
    coarse = np.flatnonzero(size > size[ref])  # (the reference itself is not a finding)
    off = np.flatnonzero(err[coarse] > GRANULARITY_TOLERANCE)
    steady = coarse[:off[0]] if off.size else coarse
    head = f"<b>Granularity {esc(name)}:</b> "
    if steady.size:
        i = int(steady[-1])
        text = (f"packets of {int(size[i]):,} stay within 1% of the cycles of packets of {int(size[ref]):,} "
                f"(error {err[i]:.2%})")
        if steady.size > 1:
            text += f", as every size below it does (at most {err[steady].max():.2%})"
        text += f", in {secs[i]:.3g} s of simulation{per} against {secs[ref]:.3g} s"
    elif off.size == coarse.size:
        i = None
        text = (f"every packet size above {int(size[ref]):,} is more than 1% off its cycles "
                f"(the least, {err[coarse].min():.2%})")
    else:
        i = int(coarse[0])
        text = (f"packets of {int(size[i]):,}, the next size above {int(size[ref]):,}, are already {err[i]:.2%} "
                f"off the cycles of packets of {int(size[ref]):,} (more than 1%)")
    back = coarse[off[0]:][err[coarse[off[0]:]] <= GRANULARITY_TOLERANCE] if off.size else coarse[:0]
    if back.size:
        sizes = ", ".join(f"{int(size[j]):,} ({err[j]:.2%})" for j in back)
        text += (f"; packets of {sizes} come back within 1% past a smaller size that does not: the error does "
                 "not fall steadily with the packet size, so such a size is luck, not a setting to trust")
    default = ArchConfig().packet_size
    d = np.flatnonzero(size == default)
    if d.size and default != size[ref] and d[0] != i:
        j = int(d[0])
        text += (f"; the default packets of {default:,} (arch.packet_size) are {err[j]:.2%} off, in "
                 f"{secs[j]:.3g} s of simulation{per} against {secs[ref]:.3g} s")
    return head + text + (f"; {esc(frames)}" if frames else "") + "."


def study_findings(inputs: Inputs) -> list[str]:
    """The granularity and extreme studies, in words: the largest packet up to which every size
    keeps within 1% of the reference and what it saves, and the default size's error
    (:func:`granularity_finding`); the cases not as expected."""
    from tlm.report.tradeoff import granularity_per_frame, granularity_points

    texts = []
    for st in inputs.of_kind("granularity"):
        size, secs, err = granularity_points(st)
        ok = np.isfinite(size) & np.isfinite(secs) & np.isfinite(err)
        if ok.sum() < 2:
            continue
        texts.append(granularity_finding(st.path.name, size[ok], secs[ok], np.abs(err[ok]), granularity_per_frame(st)))
    for st in inputs.of_kind("extreme"):
        failed = [str(r["case"]) for r in st.rows if not r["passed"]]
        texts.append(f"<b>Extreme cases {esc(st.path.name)}:</b> {len(st.rows) - len(failed)} of {len(st.rows)} as "
                     "expected" + (f"; <strong>not as expected: {esc(', '.join(failed))}</strong> (§8)." if failed
                                   else "."))
    return texts
