"""Two or more ``tlm run`` folders of one scene and mode, compared (``tlm report A B``).

The first run given of a scene-mode is the baseline; each other run of it is said against it, B/A: the
throughput cycles' and the frame rate's ratios, each PM's cycles' ratio, the baseline's bottleneck PM's busy
share in both (and where the bottleneck moves), and what differs between the two (:func:`differs`: the resolved
config's keys with both values, the seed, the code's fingerprint, the scene's contents), and two photon-map
runs' image errors, B/A only against one reference (:func:`_error`, h541). A ratio within
:data:`~tlm.report.summary_effects.NEAR_TIE` of 1 is a tie, as a sweep's points are (its wording: "within
1%"); cycles alike to the cycle are said as identical. Simulated cycles are deterministic (one config, seed and
code give the same cycles on any machine), host seconds are not: they are said apart, as the machine's.
"""

from __future__ import annotations

from typing import Any

from tlm.arch.steady import STEADY_SPREAD as NEAR_TIE  # (summary_effects.NEAR_TIE: the sweeps' tie rule, 1%)
from tlm.report.collect import Inputs, Run
from tlm.report.html import esc
from tlm.report.names import scene_digest, value_text
from tlm.report.summary_points import PM_METRIC, PMS, busy_shares, number

MODE_NAMES = {"rcast": "RCast", "reflect": "Reflect", "refract": "Refract", "pmap": "PMap"}
# the versions that compute a run's numbers (provenance.VERSIONS less python): one differing is said as a difference
VERSIONS = ("tlm", "numpy", "numba", "simpy", "scipy", "trimesh", "kernels")
MAX_DIFFS = 6  # differing keys named in a comparison's line (the rest counted: §9 lists them all)
# (h541) a difference said but of no effect on what is compared: one scene file named two ways (a built-in scene's
# name and its file's path), or a setting of the photon-map reference alone, which no simulated cycle reads
SAME_SCENE = " (one scene file, the same contents)"
NO_CYCLES = " (the reference's: no cycles)"


def groups(inputs: Inputs) -> list[list[Run]]:
    """The ``tlm run`` folders among the inputs, by scene and mode, in the order given, of the scene-modes
    with more than one (the first of each is its baseline)."""
    by: dict[tuple[str, str], list[Run]] = {}
    for r in inputs.runs:
        if r.kind == "run":
            by.setdefault((r.scene_label, r.mode), []).append(r)
    return [g for g in by.values() if len(g) > 1]


def short(run: Run) -> str:
    """A run's name without its scene-mode (``cA_p4`` of ``cA_p4: cornell/rcast``), for a tick or a sentence
    that says the scene-mode once."""
    head, sep, _ = run.label.partition(": ")
    return head if sep and head else run.label


def _flat(d: Any, prefix: str = "") -> dict[str, Any]:
    """A nested config as ``{"arch.pipelines": 4, ...}`` (a list a value of its own)."""
    if not isinstance(d, dict):
        return {prefix: d} if prefix else {}
    out: dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}.{k}" if prefix else str(k)
        out.update(_flat(v, key) if isinstance(v, dict) and v else {key: v})
    return out


def differs(a: Run, b: Run) -> list[str]:
    """What differs between runs ``a`` and ``b``: each resolved-config key whose values differ, ``key a → b``
    (the seed and scene among them), then the code (results.json's ``code_fingerprint``) and the scene's
    contents (its ``scene_digest``) where they differ; [] for two runs of one config, code and scene."""
    fa, fb = _flat(a.config), _flat(b.config)
    out = []
    for k in [*fa, *(k for k in fb if k not in fa)]:
        va, vb = fa.get(k, "(none)"), fb.get(k, "(none)")
        if va != vb:
            same = k == "scene" and _one_scene(a, b)
            out.append(f"{k} {_value(k, va)} → {_value(k, vb)}"
                       + (SAME_SCENE if same else NO_CYCLES if k.startswith("reference.") else ""))
    if "seed" not in fa and "seed" not in fb and a.results.get("seed") != b.results.get("seed"):
        out.append(f"seed {a.results.get('seed')} → {b.results.get('seed')}")
    ca, cb = a.results.get("code_fingerprint"), b.results.get("code_fingerprint")
    if ca != cb:
        out.append(f"code {ca or 'not recorded'} → {cb or 'not recorded'}")
    va, vb = a.results.get("versions"), b.results.get("versions")
    if isinstance(va, dict) and isinstance(vb, dict):  # (the packages that compute: another numba, numpy kernels)
        out += [f"{k} {va.get(k)} → {vb.get(k)}" for k in VERSIONS if va.get(k) != vb.get(k)]
    (da, ra), (db, rb) = scene_digest(a), scene_digest(b)
    if ra and rb and da != db:
        out.append(f"scene contents {str(da).removeprefix('sha256 ')[:8]} → {str(db).removeprefix('sha256 ')[:8]}")
    return out


def _one_scene(a: Run, b: Run) -> bool:
    """Whether runs ``a`` and ``b`` read one scene file of one content, whatever their configs call it (``scene:
    cornell``, the built-in scene, and ``scene: .../scenes/cornell.yaml``, its file): the same ``scene.source`` and
    the same recorded ``scene_digest``."""
    sa, sb = (a.results.get("scene") or {}).get("source"), (b.results.get("scene") or {}).get("source")
    (da, ra), (db, rb) = scene_digest(a), scene_digest(b)
    return bool(sa) and sa == sb and ra and rb and da == db


def effective(diff: list[str]) -> list[str]:
    """The differences of :func:`differs` that may change what is compared (not a scene named two ways, not a
    setting of the reference alone)."""
    return [d for d in diff if not d.endswith((SAME_SCENE, NO_CYCLES))]


def _error(a: Run, b: Run) -> str:
    """The photon-map image errors of ``a`` and ``b`` (results.json ``error.rel_mse``), B/A where both measured
    it against one reference (``error.reference``), else said not comparable; "" where either has none."""
    ea, eb = a.results.get("error"), b.results.get("error")
    if not (isinstance(ea, dict) and isinstance(eb, dict) and number(ea.get("rel_mse")) and number(eb.get("rel_mse"))):
        return ""
    x, y = float(ea["rel_mse"]), float(eb["rel_mse"])
    ref = ea.get("reference")
    if isinstance(ref, str) and ref and ref == eb.get("reference") and x > 0:
        return f"image error (relative MSE) {_ratio(y, x)} ({x:.3g} → {y:.3g}, against one reference)"
    return (f"image error (relative MSE) {x:.3g} → {y:.3g}, against other references (results.json "
            "error.reference): not comparable")


def _value(key: str, v: Any) -> str:
    return v if isinstance(v, str) and v == "(none)" else value_text(key, v)


def _ratio(b: float, a: float) -> str:
    r = b / a
    return f"{r:.3f}x" if abs(r - 1) < 0.01 else f"{r:.3g}x"


def _cycles(r: Run, key: str) -> float | None:
    v = (r.results.get("cycles") or {}).get(key)
    return float(v) if number(v) and v > 0 else None


def _fps(r: Run) -> float | None:
    v = r.results.get("fps")
    return float(v) if number(v) and v > 0 else None


def _host(r: Run) -> float | None:
    host = r.results.get("host_seconds")
    if not isinstance(host, dict):
        return None
    return sum(v for k, v in host.items() if k != "one_off" and number(v)) or None


def pair_line(a: Run, b: Run) -> str:
    """One sentence (HTML, escaped): run ``b`` against the baseline ``a``, B/A."""
    parts = []
    ta, tb = _cycles(a, "throughput"), _cycles(b, "throughput")
    if ta and tb:
        parts.append(f"throughput cycles {_ratio(tb, ta)} ({ta:,.0f} → {tb:,.0f})")
    fa, fb = _fps(a), _fps(b)
    if fa and fb:
        parts.append(f"frame rate {_ratio(fb, fa)} ({fa:.3g} → {fb:.3g} FPS)")
    pms = [f"{PM_METRIC[pm]} {_ratio(y, x)}" for pm in PMS
           if (x := _cycles(a, pm)) and (y := _cycles(b, pm))]
    if pms:
        parts.append("per PM: " + ", ".join(pms))
    ba, bb = busy_shares(a.results), busy_shares(b.results)
    if ba and bb:
        top = max(PMS, key=lambda pm: ba[pm])
        new = max(PMS, key=lambda pm: bb[pm])
        moved = "" if new == top else f"; in B the bottleneck is {PM_METRIC[new]} ({100 * bb[new]:.0f}% busy)"
        was, now = round(100 * ba[top]), round(100 * bb[top])  # (the step as the two shares are said)
        parts.append(f"A's bottleneck, {PM_METRIC[top]}, busy {was}% → {now}%"
                     f" ({'within a point' if was == now else f'{now - was:+d} points'}){moved}")
    if err := _error(a, b):
        parts.append(err)
    same = (a.results.get("cycles") or None) == (b.results.get("cycles") or None) and fa == fb
    if same and a.results.get("cycles"):
        verdict = "identical cycles: a tie"
    elif ta and tb and ta == tb:
        verdict = "the same throughput cycles: a tie"
    elif ta and tb and abs(tb / ta - 1) <= NEAR_TIE:
        verdict = f"within {NEAR_TIE:.0%} in throughput cycles: a tie"
    else:
        verdict = ""
    if verdict and fa and fb and abs(fb / fa - 1) > NEAR_TIE:  # (h541: another arch.clock_hz, one cycle count)
        verdict = verdict.replace(": a tie", ": a tie in cycles") + f", not in frame rate ({_ratio(fb, fa)}: " \
            "another clock)"
    diff = differs(a, b)
    if not diff and same:
        what = "nothing (one config, seed, code and scene): the same run twice"
    elif not diff:  # (a folder whose config or code is not recorded: its numbers say it is not the same run)
        what = "nothing that their folders record (config, seed, code, scene), though their numbers differ"
    else:
        shown = diff if len(diff) <= MAX_DIFFS else [*diff[:MAX_DIFFS - 1], f"and {len(diff) - MAX_DIFFS + 1} more"]
        what = "; ".join(shown)
        if len(real := effective(diff)) > 1:
            what += f" ({len(real)} differences: the ratios are their joint effect, no one of them alone)"
        elif not real and same:
            what += ": the same run twice"
    text = (f"<b>{esc(short(b))} against {esc(short(a))}</b> (B/A): " + (esc("; ".join(parts)) or "no cycles")
            + (f"; {verdict}" if verdict else "") + f". What differs: {esc(what)}.")
    return text


def compare_lines(inputs: Inputs) -> list[str]:
    """The summary's lines comparing the runs of each scene-mode given more than once (none where no
    scene-mode is): one a run against its scene-mode's first, and a closing line on the tie rule and host
    seconds."""
    found = groups(inputs)
    if not found:
        return []
    lines = []
    for g in found:
        a = g[0]
        mode = MODE_NAMES.get(a.mode, a.mode)
        lines.append(f"<b>Compared:</b> {len(g)} runs of {esc(a.scene_label)} {mode}, each against the first "
                     f"given, {esc(short(a))} (the baseline, A; the order of the folders given decides it).")
        lines += [pair_line(a, b) for b in g[1:]]
    hosts = [(short(r), h) for g in found for r in g if (h := _host(r))]
    lines.append(f"Simulated cycles are deterministic (one config, seed and code give the same cycles on any "
                 f"machine): a ratio within {NEAR_TIE:.0%} of 1 is a tie, as a sweep's points are, and a larger one "
                 "is the effect of what differs. Host seconds are the machine's, "
                 "noisy, and measure no design"
                 + (": " + esc(", ".join(f"{n} {h:.3g} s" for n, h in hosts)) + " (less numba's one-off)"
                    if hosts else "") + ".")
    return lines


def differs_html(inputs: Inputs) -> list[str]:
    """§9's paragraphs: for each scene-mode run more than once, every difference of each other run from its first
    (:func:`differs`, none left out); for two runs alone of other scene-modes, the one's from the other (their
    resolved configs, listed whole below them, compared here)."""
    found = groups(inputs)
    runs = [r for r in inputs.runs if r.kind == "run"]
    if not found and len(runs) == 2 and len(inputs.runs) == 2:
        found = [runs]
    out = []
    for g in found:
        a = g[0]
        said = [f"{short(b)}: {'; '.join(differs(a, b)) or 'nothing (the same run twice)'}" for b in g[1:]]
        out.append(f"<p>What differs from {esc(a.label)} (the first given; resolved config, seed, code, scene): "
                   f"{esc('. '.join(said))}.</p>")
    return out
