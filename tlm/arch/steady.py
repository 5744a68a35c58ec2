"""TThru, the steady state's cycles per frame, from the frames' completion cycles.

With ``k`` = ``arch.images_in_flight`` images, frames 0 .. k-1 arrive together at cycle 0
and frame f + k arrives when frame f is done. Between the sorted completions d[i] and
d[i+1] the model is in its steady state when a frame arrived at d[i], that is for
i >= k - 1 (the first k completions are the warm-up) and up to the last completion at
which a frame arrived (the last k - 1 completions drain with fewer images in flight).

Two kinds of stream (:func:`steady_throughput`):

* *Periodic from the warm-up*: one image in flight (every frame runs alone from the same
  state), and the static tiles with two where the asked frames' steady gaps repeat from the
  first (:func:`repeats_from_warmup`). The window spans whole periods of k gaps from d[k-1]
  (m = (F - 2k + 1) // k of them, which needs F >= 3k - 1 frames). A shorter stream has no
  window: TThru is then ``d[-1] / F`` (fill and drain included) and ``steady`` is false.
* *Settling*: two images in flight. With the dynamic queue which pipeline takes which
  of the low-priority image's tiles, and how far that image has got when the other
  completes, depend on the times the frames before left; the two images' relative phase
  is carried from frame to frame and settles only after a transient of several frames,
  into a period of one to dozens of gaps (Cornell at 32x32: 1 pipeline from the 3rd
  steady gap, period 1; 2 pipelines from the 10th, period 3; 8 pipelines with
  ``memory: copy`` from the 24th, period 15; 4 pipelines only after some 120 gaps, period 52).
  The static tiles mostly repeat from the first steady gap with a period of one or two gaps, but
  not always: Cornell PMap at 16x16 (4000 photons, one eye ray and light sample a pixel) with 3
  pipelines begins with a gap of 6,211,190 before its period of 2 (5,546,150, 5,691,037), and
  the window from d[k-1] read TThru 4.6% high at 5 frames. A static stream of at least 3k - 1
  frames whose steady gaps among the asked frames' completions do not repeat from the first
  (:func:`repeats_from_warmup`) is measured as the dynamic one is.
  The model runs such a stream past ``arch.frames`` until its steady gaps end in a
  confirmed period (:func:`periodic_tail`: the period held over at least two whole periods, at least
  :data:`MIN_REPEAT_GAPS` gaps, and at least as many gaps as came before it), at most :func:`frames_cap`
  frames (:func:`keep_going`; ``arch.settle_frames``, default :data:`SETTLE_FRAMES`, or ``arch.frames`` if
  more: ``settle_frames: 1`` runs ``arch.frames`` alone), and TThru is the mean gap over whole periods of it.
  The transient itself repeats for a while: Cornell refract at 32x32, 3 pipelines, ``swap``, begins with a
  period of 2 held over 7 gaps before its period of 3 (a rule of two periods over 4 gaps stopped it after 7 frames and
  read TThru 1.45% low), ring at 32x32 with 3 pipelines with a period of 1 over 6 gaps before its period
  of 15 (2.1% low). Against streams of 200 frames (Cornell refract, Cornell pmap, ring at 32x32, 1-8
  pipelines, both memories) no repeat inside a transient held over more than 7 gaps: 12 keeps a margin.
  Where it did not settle within the cap, TThru is the mean gap over the later half of the steady gaps
  (the first half left as the transient), ``spread`` is how far the running mean over that window moves
  over the window's last half (its largest less its smallest, a share of TThru: how much the estimate
  would change had the stream stopped anywhere there), and ``steady`` is whether that is at most
  :data:`STEADY_SPREAD` (1%; a run warns, and a scaling fit notes, only an unsettled stream that is not
  steady). Cornell refract at 32x32 with 4 pipelines, ``swap``: spread 0.49%, 0.78% and 0.85% at 64, 65
  and 80 frames, its estimate within 0.43% of the period of 52 it settles into after some 120 gaps.
"""

from __future__ import annotations

import math
from fractions import Fraction

SETTLE_FRAMES = 64  # arch.settle_frames' default: the frames a settling stream runs at most (or arch.frames, if more)
MIN_REPEAT_GAPS = 12  # a period is confirmed when held over at least these many gaps (two periods, its transient)
STEADY_SPREAD = 0.01  # an unsettled stream's window is steady where its running mean moves by at most this share


def frames_cap(frames: int, settle_frames: int = SETTLE_FRAMES) -> int:
    """The most frames a settling stream of ``arch.frames`` = ``frames`` runs: ``arch.settle_frames``, or
    ``frames`` if more (``settle_frames`` 1: ``frames`` alone, no run-on)."""
    return max(frames, settle_frames)


def runs_alike(ran: int, cap: int, other: int) -> bool:
    """Whether a settling stream that ran ``ran`` frames under its cap ``cap`` (:func:`frames_cap`) would run
    the same under the cap ``other``: the same cap, or it stopped below its own where its completions so far
    repeated, as at any cap from there on, and no later than ``other`` (each arrival decides alike up to there)."""
    return cap == other or (ran < cap and ran <= other)


def periodic_tail(gaps: list[int]) -> tuple[int, int] | None:
    """(s, p): the smallest period p with which ``gaps`` end, held over at least two whole periods, at
    least :data:`MIN_REPEAT_GAPS` gaps and at least as many gaps as came before it (s: a repeat inside the
    transient is not taken for the steady state), and the first gap s of that periodic run (every gap from
    s on equals the one p later); None where the gaps end in no confirmed period."""
    n = len(gaps)
    for p in range(1, n // 2 + 1):
        need = max(2 * p, MIN_REPEAT_GAPS)
        if need > n or any(gaps[i] != gaps[i + p] for i in range(n - need, n - p)):
            continue
        s = n - need
        while s > 0 and gaps[s - 1] == gaps[s - 1 + p]:
            s -= 1
        if n - s >= s:  # (held over less than the transient before it: a longer period may still come)
            return s, p
    return None


def keep_going(done: list[int], in_flight: int) -> bool:
    """Whether a settling stream whose frames so far completed at ``done`` (a frame arrived
    at each of them) has not settled yet: its steady gaps end in no confirmed period."""
    d = sorted(done)
    return periodic_tail([d[i + 1] - d[i] for i in range(in_flight - 1, len(d) - 1)]) is None


def repeats_from_warmup(done: list[int], in_flight: int, frames: int) -> bool:
    """Whether the steady gaps among the completions at which the ``frames`` asked arrived
    (the first ``frames - in_flight + 1`` of ``done``: the same however far the stream ran on)
    repeat from the first with a period p dividing ``in_flight`` (1, or 2 with two images),
    held over at least two whole periods: 5 frames of two images give two steady gaps, equal
    or not; 7 give four, a period of 2 seen too. The old window, whole rounds of the images
    from d[k-1], is then whole periods of them: a static stream that passes keeps its TThru and
    runs the frames asked. Not a proof: a transient whose first gaps repeat would pass (none among
    140 static settings of Cornell at 16x16 and 24x24, nor 400 more of a review: ``docs/architecture.md``)."""
    k = in_flight
    d = sorted(done)[:frames - k + 1]
    gaps = [d[i + 1] - d[i] for i in range(k - 1, len(d) - 1)]
    return any(len(gaps) >= 2 * p and all(gaps[i] == gaps[i + p] for i in range(len(gaps) - p))
               for p in range(1, k + 1) if k % p == 0)


def steady_throughput(done: list[int], in_flight: int, settling: bool = False) -> tuple[int, dict]:
    """TThru from the completion cycles ``done`` of a stream with ``in_flight`` images (see the
    module's text): periodic from the warm-up (``settling`` false) or settling (two images in
    flight, run until periodic by the model: :func:`tlm.arch.model.settles`). Returns the value rounded to
    whole cycles (an exact rational mean) and how it was measured: ``steady``, ``frames``,
    ``window`` [a, b] (indices into the sorted completions), ``estimator``; a settling
    stream's ``settled``, ``period`` (gaps) or ``spread``, and ``latency_arrivals`` [lo, hi): the
    frames the latency is the mean over (those arriving in the window, whole periods of them,
    done before the drain); a short stream's ``min_frames``."""
    f, k = len(done), in_flight
    d = sorted(done)
    m = (f - 2 * k + 1) // k
    if m >= 1 and settling:
        gaps = [d[i + 1] - d[i] for i in range(k - 1, f - k)]
        tail = periodic_tail(gaps)
        if tail is not None:
            s, p = tail
            whole = math.lcm(p, k)  # whole periods that are whole rounds of the k images too, where they fit
            span = (len(gaps) - s) // whole * whole or (len(gaps) - s) // p * p
            a, b = k - 1 + s, k - 1 + s + span
            value = round(Fraction(d[b] - d[a], b - a))
            # the latency's frames: those that arrived at d[a], d[a+1], .. (frame k + i arrives at the i-th
            # completion), whole periods of them, each done by d[f - k] (before the drain)
            arrivals = (f - 2 * k + 1 - a) // p * p
            return value, {"steady": True, "frames": f, "window": [a, b], "settled": True, "period": p,
                           "latency_arrivals": [k + a, k + a + arrivals] if arrivals else None,
                           "estimator": f"periodic steady state (from completion {a}, a period of {p} "
                                        f"gap{'s' * (p != 1)})"}
        half = len(gaps) // 2
        a, b = k - 1 + half, f - k
        value = round(Fraction(d[b] - d[a], b - a))
        # the running mean over the window, from its middle on: how far the estimate moves there
        run = [Fraction(d[j] - d[a], j - a) for j in range((a + b) // 2, b + 1) if j > a]
        spread = float((max(run) - min(run)) / Fraction(d[b] - d[a], b - a)) if run and d[b] > d[a] else 0.0
        # the latency's frames: those that arrived in the window and were done before the drain; in a stream cut
        # short (arch.settle_frames) that has none, those that arrived after the warm-up
        lo = a if f - 2 * k + 1 - a > 0 else k - 1
        arrivals = f - 2 * k + 1 - lo
        return value, {"steady": spread <= STEADY_SPREAD and len(run) > 1,  # (one mean shows no movement)
                       "frames": f, "window": [a, b], "settled": False, "spread": spread,
                       "min_frames": None,  # (no length known: raise arch.settle_frames)
                       "latency_arrivals": [k + lo, k + lo + arrivals] if arrivals > 0 else None,
                       "estimator": (f"mean gap over the last {b - a} steady completions" if len(run) > 1 else
                                     "the last steady gap alone (too few completions to tell whether it moves)")
                                    + f": not periodic within {f} frames"}
    if m >= 1:
        a, b = k - 1, k - 1 + m * k
        value = round(Fraction(d[b] - d[a], b - a))
        return value, {"steady": True, "frames": f, "window": [a, b], "estimator": "steady-state window"}
    if k == 1 and f == 1:
        return d[0], {"steady": True, "frames": 1, "window": None,
                      "estimator": "the one frame (one image in flight: every frame takes the same cycles)"}
    value = round(Fraction(d[-1], f))
    return value, {"steady": False, "frames": f, "window": None, "min_frames": 3 * k - 1,
                   "estimator": "elapsed cycles per frame (stream too short for a steady-state window)"}
