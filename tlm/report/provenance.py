"""Section 7: where every number of the report came from.

Per run shown (a run, a thesis cell, a sweep point): its folder, seed, git revision,
package versions and host wall seconds, and its resolved config (collapsed). Per study
folder (thesis, scaling, granularity, error-vs-cost): its ``provenance.json`` and
resolved config when it has them; a folder written before they were recorded says so.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tlm.report.collect import Inputs, Run
from tlm.report.common import Section
from tlm.report.html import esc

VERSIONS = ("tlm", "python", "numpy", "numba", "simpy", "scipy", "trimesh", "kernels")  # (kernels: numba or numpy)
MAX_CONFIGS = 64  # full resolved configs listed; the rest are in their folders


def _seconds(host: dict | None) -> float | None:
    if not host:
        return None
    return round(sum(v for v in host.values() if isinstance(v, int | float)), 3)


def _seconds_text(v) -> str:
    """Seconds to 3 significant digits, as a reader writes them: ``14.7``, ``3.50``, ``0.0412``, ``1234``."""
    if not isinstance(v, int | float) or isinstance(v, bool):
        return str(v)
    return f"{v:.0f}" if abs(v) >= 100 else f"{v:#.3g}".rstrip(".")


def _per_scene(seconds) -> str:
    """A thesis study's host seconds per scene in words: ``thesis/ring 14.7, cornell 3.50``."""
    if not isinstance(seconds, dict):
        return str(seconds)
    return ", ".join(f"{scene} {_seconds_text(v)}" for scene, v in seconds.items())


def _versions(v: dict | None) -> str:
    if not v:
        return "not recorded"
    return ", ".join(f"{k} {v[k]}" for k in VERSIONS if k in v)


def _code(r: dict) -> str:
    """A result's code: its git revision (12 digits), "modified" where the checkout differed
    from it, and the package's fingerprint (:func:`tlm.experiments.provenance.code_state`)."""
    rev = str(r.get("git_revision") or "not recorded")[:12]
    more = (["modified"] if r.get("git_modified") else []) + (
        [f"code {r['code_fingerprint']}"] if r.get("code_fingerprint") else [])
    return f"{rev} ({', '.join(more)})" if more else rev


def _run_row(run: Run) -> list[str]:
    r = run.results
    host = _seconds(r.get("host_seconds"))
    render = (r.get("functional") or {}).get("render_host_seconds")
    if render:
        host = f"{host} (+ {_seconds(render)} render, {'cached' if r['functional'].get('cached') else 'this point'})"
    return [run.label, run.kind, str(run.path), str(r.get("seed")), _code(r), _versions(r.get("versions")), str(host)]


def provenance_section(inputs: Inputs, out: Path) -> Section:
    sec = Section("provenance", "Provenance: config, seed, versions, revision and host time of every run")
    head = ["run", "kind", "folder", "seed", "git revision", "versions", "host s"]
    parts = ["<table><tr>" + "".join(f'<th class="l">{esc(h)}</th>' for h in head) + "</tr>"]
    for run in inputs.runs:
        parts.append("<tr>" + "".join(f'<td class="l">{esc(c)}</td>' for c in _run_row(run)) + "</tr>")
    parts.append("</table>")
    for run in inputs.runs[:MAX_CONFIGS]:
        parts.append(f"<details><summary>{esc(run.label)}: resolved config</summary><pre>"
                     f"{esc(yaml.safe_dump(run.config, sort_keys=False))}</pre></details>")
    if len(inputs.runs) > MAX_CONFIGS:
        sec.notes.append(f"The resolved configs of the first {MAX_CONFIGS} of {len(inputs.runs)} runs are listed; "
                         "every run's is its folder's config.resolved.yaml.")
    for st in inputs.studies:
        p = st.meta.get("provenance")
        line = (f"{st.kind} folder {st.path}: " + (
            f"study {p.get('study')}, git {_code(p)}, {_versions(p.get('versions'))}, "
            f"host {p.get('host_seconds')} s" if p else
            "no provenance.json (written by an older tlm); its runs' folders, when it has them, record theirs"))
        if st.kind == "thesis" and st.meta.get("host_seconds"):
            line += f"; host seconds per scene: {_per_scene(st.meta['host_seconds'])}"
        parts.append(f"<p>{esc(line)}</p>")
        if "config" in st.meta:
            parts.append(f"<details><summary>{esc(st.path.name)}: resolved config</summary><pre>"
                         f"{esc(yaml.safe_dump(st.meta['config'], sort_keys=False))}</pre></details>")
    sec.html = "\n".join(parts)
    if not inputs.runs and not inputs.studies:
        sec.absent = "no inputs"
    return sec
