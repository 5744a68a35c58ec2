"""The tables the commands print of what the API returns (out of :mod:`tlm.cli`, which imports
them by their old names): ``tlm thesis``'s Tables I-III and counts per work item
(:func:`print_thesis`), ``tlm scaling``'s eq. 5.2 fits (:func:`print_scaling`), and a default as
``tlm params`` writes it in its column (:func:`yaml_text`), and the warnings ``tlm sweep``'s points
recorded (:func:`print_point_warnings`), and ``tlm granularity``'s rows (:class:`GranularityProgress` as each
size is simulated, then :func:`print_granularity`)."""

from __future__ import annotations

import json
import math
import re
import sys
from collections import Counter
from pathlib import Path

from tlm import storage
from tlm.cli_report import say_err
from tlm.config_words import number_form
from tlm.errors import values_text


def print_thesis(done: dict, out: Path) -> None:
    """What ``tlm thesis`` prints of its study: its tables, then its warnings."""
    from tlm.experiments.thesis import describe_items, describe_rows, median_words, slowest_words

    print("ours (thesis), millions of cycles; FPS in frames per second")
    print(describe_rows(done["rows"], done.get("names")))
    sm = done["summary"]
    print(f"{median_words(sm)}; {slowest_words(sm)}")
    for line in (sm.get("no_table") or {}).values():  # (a scene without a table, by its file: bunny.yaml)
        print(line)
    print("per work item, ours (thesis's time over our count): cycles per traced ray, triangle tests "
          "per ray, cycles per pixel, cycles per triangle")
    print(describe_items(sm["per_item"], done.get("names")))
    print(f"wrote {out}/thesis_comparison.csv")
    sys.stdout.flush()  # (its table first, then its warnings on stderr, each once: api.thesis returns them)
    for line in done.get("warnings") or []:
        storage.warn(line)


def _two_n(fit: dict) -> str:
    """What ``tlm scaling`` adds after a fit's N where it has two (N = 1 and another): no test, and what each of
    its two fits is (the rule of :func:`tlm.report.scaling.untested_why`; h302: a slowest-pipeline error of 225%
    was said to be exact, B = 1 where the two points leave it undetermined; h309: an eq. 5.2 fit exact by
    construction was then said "not both determined" with its variant)."""
    if len(fit["pipelines"]) > 2:
        return ""
    # each fit judged alone by its own error, as tlm.report.scaling.untested_why judges it (the CLI reaches the
    # report only through tlm.api: tests/test_api.py; tests/test_lastread_h309.py holds the two to one rule)
    eq52, slowest = (("exact by construction" if e == 0 else "A and B not both determined")
                     for e in (fit["max_abs_rel_error"], fit["slowest"]["max_abs_rel_error"]))
    if eq52 == slowest == "exact by construction":
        return " alone: two points fit A and B exactly, a test of nothing"
    return f" alone, a test of nothing: eq. 5.2 {eq52}; slowest-pipeline variant: {slowest}"


def _error(fit: dict, whole: dict) -> str:
    """A fit's largest |error| on ``tlm scaling``'s line: ``untested`` where a fit of three or more N tests nothing
    (``tested`` false: every point Vertex-bound, h488; the note above says why), else the percentage."""
    flat = fit.get("tested") is False and len(whole["pipelines"]) > 2
    return "untested" if flat else f"{fit['max_abs_rel_error']:6.1%}"


def print_scaling(done: dict, out: Path) -> None:
    """What ``tlm scaling`` prints of its fits."""
    for note in done["notes"]:
        say_err(f"note: {note}")
    print("eq. 5.2, T_tot(N) = A * T_vert0 + B * sum_i max(T_t,i, T_r,i, T_f,i) / N, exact at N = 1:")
    fits = done["fits"]
    wide = {k: max([w, *(len(str(f[k])) for f in fits)]) for k, w in (("scene", 8), ("mode", 7), ("scheduler", 8))}
    # a sweep crossing N with other factors: a fit per combination of their values (its group)
    group = max((len(f.get("group") or "") for f in fits), default=0)
    for f in fits:
        combination = f"{f.get('group') or '':{group}s} " if group else ""
        print(f"  {f['scene']:{wide['scene']}s} {f['mode']:{wide['mode']}s} {f['scheduler']:{wide['scheduler']}s} "
              f"{combination}{f['target']:10s} A {f['A']:8.4g}  B {f['B']:8.4g}  "
              f"max |error| {_error(f, f)}; "
              f"slowest-pipeline variant: max |error| {_error(f['slowest'], f)} "
              f"(N = {values_text(f['pipelines'])}{_two_n(f)})")
    # (the latency is images in flight x TThru at every point of a group: its fit is the throughput fit scaled)
    lat = [f for f in fits if f["target"] == "latency"]
    times = {f.get("latency_multiple") for f in lat}
    if lat and None not in times:
        k = ", ".join(f"{x}" for x in sorted(times))
        print(f"latency = {k} x TThru at every point (images in flight x TThru: a closed loop, Little's law), so each "
              f"latency fit is its throughput fit x {k}, with the same errors: not a second test of eq. 5.2")
    elif times - {None}:
        scaled = sum(f.get("latency_multiple") is not None for f in lat)
        print(f"latency = images in flight x TThru at every point of {scaled} of the {len(lat)} latency fits "
              "(a closed loop, Little's law): those are their throughput fits scaled, not a second test of eq. 5.2")
    print(f"wrote {out}")


class GranularityProgress:
    """What ``tlm granularity`` prints as each packet size is simulated (``tm``: its Timing), the size as wide as
    the study's widest (told by :meth:`start`, before the first: :func:`tlm.api.granularity`'s ``start``), at
    least 8, as :func:`print_granularity`'s table has it: a size of 102400000 pushed its line's columns out of
    line (h407)."""

    def __init__(self) -> None:
        self.wide = 8

    def start(self, sizes: list[int]) -> None:
        self.wide = max([8, *(len(str(s)) for s in sizes)])

    def __call__(self, size: int, tm, secs: float) -> None:
        nf = len(tm.frames)  # (arch.frames, or more where the stream ran on until it settled: tlm/arch/steady.py)
        print(f"  packets of {size:>{self.wide}d}: throughput {tm.cycles['throughput'] / 1e6:10.4f} M cycles, "
              f"{tm.events:>9d} events, {nf:>3d} frame{'s' * (nf != 1)}, {secs:7.2f} s", flush=True)


def print_granularity(rows: list[dict], out: Path) -> None:
    """What ``tlm granularity`` prints of its rows: per packet size its error, the frames simulated and the host
    seconds, in all and per frame, each column but the line's last as wide as its widest cell (a packet size of
    any width, 2e12, keeps the table aligned: h397); under them, where the rows ran different frame counts, a line
    saying so (:func:`granularity_frames_line`), then the study's notes (its ``granularity_summary.json``: two or
    more sizes at or past the frame's largest phase, which run every phase as one packet: h400)."""
    cells = [(str(r["packet_size"]), f"{r['max_abs_rel_error']:.3%}", f"{r['simulate_seconds']:.2f}", str(r["frames"]),
              "frame" if r["frames"] == 1 else "frames", f"{r['simulate_seconds_per_frame']:.3g}") for r in rows]
    wide = [max([8 if i == 0 else 0, *(len(c[i]) for c in cells)]) for i in range(5)]  # (the last: line's end)
    for r, (size, err, secs, nf, word, per) in zip(rows, cells, strict=True):
        print(f"  packets of {size:>{wide[0]}}: max |cycle error| {err:>{wide[1]}} against packets of "
              f"{r['reference']}, {secs:>{wide[2]}} s, {nf:>{wide[3]}} {word:{wide[4]}} ({per} s a frame)")
    line = granularity_frames_line(rows)
    if line:
        print(line)
    notes = getattr(rows, "attrs", {}).get("notes")  # (tlm.api.granularity's; else the study's record: h407)
    for line in notes if isinstance(notes, list) else _granularity_notes(out):
        print(f"  {line}")
    print(f"wrote {out}/granularity.csv")


def _granularity_notes(out: Path) -> list[str]:
    """The ``notes`` of the granularity study in ``out`` (its ``granularity_summary.json``), [] where it has none."""
    try:
        notes = json.loads((Path(out) / "granularity_summary.json").read_text(encoding="utf-8")).get("notes")
    except (OSError, ValueError, AttributeError):
        return []
    return [str(n) for n in notes] if isinstance(notes, list) else []


def granularity_frames_line(rows: list[dict]) -> str:
    """``tlm granularity``'s line under its rows where they ran different frame counts (h364: a stream of two
    images whose steady gaps do not repeat runs on past ``arch.frames`` until they do, at one packet size and
    not at another), so the totals (``simulate_seconds``, ``simpy_events``) are not compared; "" where every
    row ran the same. (The rows grouped as the report groups them, :func:`tlm.api.granularity_frames`.)"""
    from tlm import api

    ran = api.granularity_frames(rows)
    if not ran:
        return ""
    counts = "; ".join(f"{f} at packets of {values_text(sizes)}" for f, sizes in ran.items())
    return (f"  the rows ran different frame counts: {counts} (where the stream's completions did not repeat "
            "within arch.frames it ran on until they did, at most arch.settle_frames: tlm/arch/steady.py); "
            "simulate_seconds and simpy_events are totals over a row's frames: compare them per frame "
            "(simulate_seconds_per_frame, simpy_events_per_frame in granularity.csv)")


POINT_WARNINGS_SHOWN = 5  # the distinct warnings of a sweep's points said in the terminal; the rest counted


def print_point_warnings(rows: list[dict], out: Path, said: list[str]) -> None:
    """What ``tlm sweep`` says, after its summary line, of the warnings its points recorded (each ok point's
    ``results.json``, ``warnings``: a point of this run, of a run resumed, from any worker): on stderr, a
    line per distinct warning, ``tlm: warning: 3 of 4 points: ...``, the most recorded first (then the first
    met), at most :data:`POINT_WARNINGS_SHOWN` of them, then how many more there are. Warnings that differ in
    their numbers alone (``moved by 0.14%``, ``by 0.29%``) are one, said in the wording first met with how many
    wordings it had (:func:`tlm.config_words.number_form`; the report's warnings box folds them alike): one kind
    on every point is not a line per point. A line the sweep said already (``said``, its own warnings; a cache's,
    said once) is not said again, nor a point's line of a Dask machine's render.threads that the sweep said once
    for that machine (another count there, another worker's: :func:`tlm.api.machine_key`); a record that cannot
    be read is left to the report, which names it."""
    from tlm import api

    per_hash: dict[str, list[str]] = {}
    known = {" ".join(line.split()) for line in said} | storage.SAID
    covered = _covered_keys(said)  # (a point's "KEY = V has no effect in this run": the sweep said it of KEY)
    machines = {key for line in said if (key := api.machine_key(line)) is not None}  # (each machine said once)
    counts: Counter[str] = Counter()  # points per form (a warning, its numbers masked)
    wordings: dict[str, dict[str, None]] = {}  # each form's wordings, in the order met
    for row in rows:
        h = row.get("hash")
        if row.get("status") != "ok" or not isinstance(h, str):
            continue
        if h not in per_hash:
            per_hash[h] = [line for line in _recorded(Path(out) / "points" / h / "results.json")
                           if line not in known and _NO_EFFECT.sub(r"\1", line, count=1) not in covered
                           and api.machine_key(line) not in machines]
        forms = list(dict.fromkeys(number_form(line) for line in per_hash[h]))
        for line in per_hash[h]:
            wordings.setdefault(number_form(line), {})[line] = None
        counts.update(forms)
    lines = counts.most_common()  # (ties: the first met first)
    if not lines:
        return
    sys.stdout.flush()  # (the summary line first)
    for form, n in lines[:POINT_WARNINGS_SHOWN]:
        first, k = next(iter(wordings[form])), len(wordings[form])
        how = f" (in {k} wordings that differ in their numbers; the first met)" if k > 1 else ""
        storage.warn(f"{n} of {len(rows)} points{how}: {first}")
    if len(lines) > POINT_WARNINGS_SHOWN:
        more = len(lines) - POINT_WARNINGS_SHOWN
        storage.warn(f"and {more} more warning{'s' if more > 1 else ''} of the points (each point's "
                     f"{Path(out) / 'points'}/HASH/results.json lists its own; the sweep's report shows them all)")


# a point's line of a key it set to no effect (tlm.render.planner, tlm.experiments.run_warnings), and the sweep's
# own line of a factor or --set key that changed nothing (tlm.experiments.sweep_file: inert and unread factors)
_NO_EFFECT = re.compile(r"^([A-Za-z_][A-Za-z0-9_.]*) = .* has no effect in this run: .*$", re.DOTALL)
_SWEEP_NOTHING = re.compile(r"(?:the factor|--set) ([A-Za-z_][A-Za-z0-9_.]*)[=: ].*?change[sd]? nothing in")


def _covered_keys(said: list[str]) -> set[str]:
    """The keys of which the sweep's own lines (``said``) say that they changed nothing in its points (``the
    factor arch.swap_cycles changed nothing in any of the 4 points``): each point's line of that key says it
    again, so :func:`print_point_warnings` leaves those out."""
    return {m.group(1) for line in said for m in [_SWEEP_NOTHING.search(line)] if m}


def _recorded(path: Path) -> list[str]:
    """The distinct warnings (whitespace as :func:`tlm.storage.warn` says them) of a point's ``results.json``;
    none where it cannot be read or holds no list of them."""
    try:
        lines = json.loads(path.read_text(encoding="utf-8")).get("warnings")
    except (OSError, ValueError, AttributeError):
        return []
    return list(dict.fromkeys(" ".join(x.split()) for x in lines if isinstance(x, str))) if isinstance(lines, list) \
        else []


def yaml_text(value) -> str:
    """A default as a config file writes it, and as YAML reads it back: ``null``, ``true``,
    ``cornell``, ``[16, 16]``; a whole float of 10**6 or more as ``6.0e+08`` (YAML reads
    ``6e+08``, with no point, as text); a string as :func:`~tlm.config_words.flow_text` writes it."""
    import math

    from tlm.config_words import flow_text

    if isinstance(value, float) and math.isfinite(value) and value == int(value) and abs(value) >= 1e6:
        mantissa, exponent = f"{value:e}".split("e")
        mantissa = mantissa.rstrip("0")
        return f"{mantissa}{'0' if mantissa.endswith('.') else ''}e{exponent}"
    return flow_text(value)


# -- tlm calibrate: how well its fit is determined, and --leave-one-out (h539) ----------------------------------


def _g4(v: float | None) -> str:
    return "none" if v is None else f"{v:.4g}"


def fit_lines(stats: dict[str, dict]) -> list[str]:
    """``tlm calibrate``'s lines on the fit, one per PM (``stats``: PM -> calibrate_fit.fit_statistics)."""
    lines = []
    for pm, s in stats.items():
        n = len(s["parameters"])
        params = []
        for p, v in s["parameters"].items():
            se = s["standard_errors"][p]
            text = f"{p} {v:.4g} ± {_g4(se)}" if se is not None else f"{p} {v:.4g} (no standard error)"
            if p in s["on_bound"]:
                text += " (on its bound 0: the error is the unconstrained fit's)"
            params.append(text)
        dof = s["dof"]
        lines.append(f"  fit {pm}: {n} parameter{'s' if n > 1 else ''} on {s['cells']} cells, {dof} degree"
                     f"{'' if dof == 1 else 's'} of freedom; in-sample |rel error| median "
                     f"{s['median_abs_rel_error']:.1%}, max {s['max_abs_rel_error']:.1%}; " + ", ".join(params)
                     + "; condition number " + (f"{s['condition_number']:.3g}" if math.isfinite(s["condition_number"])
                                                else "infinite (a singular fit: its parameters are not determined)"))
    return lines


def held_out_lines(loo: dict) -> list[str]:
    """``tlm calibrate --leave-one-out``'s lines (``loo``: tlm.api.calibrate's ``held_out``)."""
    lines = ["leave-one-out: each scene's fitted RCast cells predicted by a fit to the other scenes (no table "
             "written):"]
    for scene, s in loo["scenes"].items():
        lines.append(f"  without {scene}: " + ", ".join(f"{k} {v:.4g}" for k, v in s["parameters"].items()))
        lines.append(f"    {scene:8s} " + "  ".join(f"{m} {c['rel_error']:+.1%} (in-sample {c['in_sample']:+.1%})"
                                                   for m, c in s["cells"].items()))
    h, i = loo["held_out"], loo["in_sample"]
    lines.append(f"  held out: |rel error| median {h['median']:.1%}, max {h['max']:.1%} over {h['cells']} cells; "
                 f"in-sample (the fit to all {len(loo['scenes'])} scenes): median {i['median']:.1%}, "
                 f"max {i['max']:.1%}")
    return lines
