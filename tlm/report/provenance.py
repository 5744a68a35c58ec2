"""Section 7: where every number of the report came from.

Per run shown (a run, a thesis cell, a sweep point): its folder, seed, git revision,
package versions and host wall seconds (and who ran it, its host and a sweep point's Dask worker, where more than
one ran the runs shown; else each sweep's line says where its points ran: :func:`ran_note`), and its resolved
config (collapsed).
Per scene the
runs rendered (once for the runs whose ``results.json`` record one scene alike: a sweep's
points on one scene, once): its materials' values as the renderer used them and its lights,
each with where it came from (:func:`scene_tables`; a built-in scene's file by its place in the repository,
``scenes/cornell.yaml``, from an installed copy too: :func:`~tlm.report.names.shown_paths`). Per study
folder (thesis, scaling, granularity, error-vs-cost): its ``provenance.json`` (its study file shown so
too) and resolved config when it has them; a folder written before they were recorded says so.
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

from tlm.config_words import dump_yaml, listing
from tlm.report.collect import Inputs, Run, with_set
from tlm.report.common import Section, count, some
from tlm.report.compare import differs_html
from tlm.report.html import esc
from tlm.report.names import digest_notes, same_file, scene_digest, shown_paths
from tlm.report.numbers import exact, sig

VERSIONS = ("tlm", "python", "numpy", "numba", "simpy", "scipy", "trimesh", "kernels")  # (kernels: numba or numpy)
MAX_CONFIGS = 64  # full resolved configs listed; the rest are in their folders


def _seconds(host: dict | None) -> float | None:
    if not host:
        return None
    # (a sweep point's one_off is a part of its functional and simulate seconds, not beside them; a tlm run's is a
    # stage of its own, taken out of the stages it fell in: tlm.experiments.run.run)
    part = "functional" in host
    return round(sum(v for k, v in host.items() if not (part and k == "one_off") and isinstance(v, int | float)), 3)


def _seconds_text(v) -> str:
    """Seconds to 3 significant digits, as a reader writes them: ``14.7``, ``3.50``, ``0.0412``, from 100 up
    whole, thousands separated: ``1,234`` (:mod:`tlm.report.numbers`)."""
    if not isinstance(v, int | float) or isinstance(v, bool):
        return str(v)
    return f"{v:,.0f}" if abs(v) >= 100 else sig(v, 3)


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


Who = tuple[str | None, str | None]  # (the Dask worker's name, the host) that ran a sweep point or a run


def ran_by(ran: dict | None) -> Who | None:
    """Who ran a sweep point, as its row's ``worker`` and ``host`` (or its ``results.json`` ``ran``, as a tlm run's
    and a thesis cell's too) record it (:func:`tlm.experiments.dask_workers.ran_here`): (the Dask worker's name or
    None, the host); None where neither is recorded (a run or point of an older tlm, a point whose worker died
    before it could say)."""
    if not isinstance(ran, dict):
        return None
    worker, host = (v if isinstance(v, str) and v else None for v in (ran.get("worker"), ran.get("host")))
    return None if worker is None and host is None else (worker, host)


def ran_label(who: Who | None) -> str:
    """A ``ran on`` cell: ``HOST``, ``WORKER on HOST`` for a Dask worker's, ``not recorded``."""
    if who is None:
        return "not recorded"
    worker, host = who
    return host if worker is None else f"{worker} on {host}" if host else worker


def ran_note(whos: list[Who | None], what: str = "point") -> str | None:
    """Where ``whos`` (a sweep's points, :func:`ran_by`) ran, in a sentence: ``All 3 points ran on host vm``
    (the Dask worker's name too, where one ran them), or, run on more than one, each host (or worker) with its
    count of points (:func:`~tlm.report.common.some` of them), most first; None where none records it."""
    known = [w for w in whos if w is not None]
    if not known:
        return None
    unknown = len(whos) - len(known)
    rest = f"{unknown} {'does' if unknown == 1 else 'do'} not record where {'it' if unknown == 1 else 'they'} ran"
    counts = Counter(known).most_common()
    if len(counts) == 1:
        (worker, host), _ = counts[0]
        where = f"host {host}" if worker is None else f"the Dask worker {worker}" + (f" on host {host}" if host else "")
        lead = (f"{len(known)} of the {len(whos)} {what}s" if unknown else
                f"All {count(len(whos), what)}" if len(whos) > 1 else f"The {what}")
        return f"{lead} ran on {where}{f' ({rest})' if unknown else ''}"
    hosts = {host for (_, host), _ in counts}
    workers = sum(worker is not None for (worker, _), _ in counts)
    local = " and local processes" if workers and workers < len(counts) else ""  # (a sweep resumed on Dask)
    places = f"{count(workers, 'Dask worker')}{local} on " * bool(workers) + count(len(hosts), "host")
    return (f"The {count(len(whos), what)} ran on {places}: "
            f"{some([f'{ran_label(who)} ({count(n, what)})' for who, n in counts])}"
            f"{f'; {rest}' if unknown else ''}")


FLAGS = ("mode", "seed")  # tlm run's --mode and --seed: results.json ``overrides`` ends with them as mode=, seed=


def given_set(run: Run) -> list[str]:
    """The ``--set`` strings a run was made with as given: a ``tlm run``'s ``results.json`` ``overrides``
    less the ``mode=``/``seed=`` its ``--mode``/``--seed`` added at their end (the mode is in the run's
    label, the seed in its own column); a study cell's or sweep point's all of them."""
    found = list(run.overrides)
    if run.kind == "run":
        while found and found[-1].partition("=")[0].strip() in FLAGS:
            found.pop()
    return found


def _run_row(run: Run, shared: dict[str, float] | None = None, overrides: bool = False) -> list[str]:
    """A run's row. Its host seconds: a sweep point's render (``functional.render_host_seconds``) is
    said as part of them where the point rendered (its ``host_seconds.functional`` was measured
    around it), beside them where the render was cached (done before, by another point or run);
    ``shared``: the stages of a thesis cell that its scene's other cells record too (one render);
    ``overrides``: a cell after the folder's for its ``--set`` overrides (``none`` where it had none)."""
    r = run.results
    host = _seconds(r.get("host_seconds"))
    render = (r.get("functional") or {}).get("render_host_seconds")
    if render:
        host = (f"{host} (+ {_seconds(render)} render, cached)" if r["functional"].get("cached") else
                f"{host} (of which {_seconds(render)} render)")
    elif shared:
        host = f"{host} (of which {_seconds(shared)} shared with its scene's other modes)"
    elif run.kind == "run" and isinstance(once := (r.get("host_seconds") or {}).get("one_off"), int | float) and once:
        host = f"{host} (of which {_seconds_text(once)} one-off: numba compiling, first imports)"
    return [run.label, run.kind, str(run.path), *([", ".join(given_set(run)) or "none"] if overrides else []),
            str(r.get("seed")), _code(r), _versions(r.get("versions")), str(host)]


def shared_stages(runs: list[Run]) -> dict[int, dict[str, float]]:
    """Per thesis cell (its index in ``runs``), the stages of its ``host_seconds`` that another cell of
    the same study and scene records with the same seconds: the scene's one render (its load, BSP,
    casts and the passes both modes ran), timed once and recorded in each cell that uses it."""
    groups: dict[str, list[int]] = {}
    for i, run in enumerate(runs):
        if run.kind == "thesis" and isinstance(run.results.get("host_seconds"), dict):
            groups.setdefault(str(run.path.parent.resolve()), []).append(i)
    out: dict[int, dict[str, float]] = {}
    for members in groups.values():
        for i in members:
            mine = runs[i].results["host_seconds"]
            same = {k: v for k, v in mine.items() if k != "simulate" and isinstance(v, int | float) and v > 0
                    and any(runs[j].results["host_seconds"].get(k) == v for j in members if j != i)}
            if same:
                out[i] = same
    return out


MATERIAL_VALUES = ("albedo", "reflectance", "ior", "transmittance")  # (one of them: a kind's values recorded)
MAX_LISTED = 6  # runs named per scene; the rest counted
OLD = "not recorded by the tlm of this run (an older one)"
NOW = " (of its files now: not recorded)"  # (a scene digest of a run of an older tlm: names.scene_digest)
NOT_HERE = " (not recorded, and its scene file is not on this machine)"  # (no digest at all: names.scene_digest)


def _text(v) -> str:
    """A recorded value as a reader writes it: a triple ``0.725 0.71 0.68``, a number ``1.5``, text as it is;
    a number as recorded, not rounded, thousands separated (:func:`~tlm.report.numbers.exact`: a light's power
    ``1,100,000 950,000 750,000``, not ``1.1e+06 950000 750000``)."""
    if isinstance(v, list) and v and all(isinstance(x, int | float) and not isinstance(x, bool) for x in v):
        return " ".join(exact(x) for x in v)
    if isinstance(v, int | float) and not isinstance(v, bool):
        return exact(v)
    if isinstance(v, list):
        return ", ".join(_text(x) for x in v)
    if isinstance(v, dict):
        return "; ".join(f"{k}: {_text(x)}" for k, x in v.items())
    return str(v)


def _table(head: list[str], rows: list[list[str]]) -> str:
    return ("<table><tr>" + "".join(f'<th class="l">{esc(h)}</th>' for h in head) + "</tr>" + "".join(
        "<tr>" + "".join(f'<td class="l">{esc(c)}</td>' for c in row) + "</tr>" for row in rows) + "</table>")


def _recorded(mats) -> bool:
    """Whether ``results.json`` ``scene.materials`` records the values (each material its kind's): an older
    tlm recorded each one's kind and triangles only, or nothing."""
    return isinstance(mats, dict) and bool(mats) and all(
        isinstance(m, dict) and any(k in m for k in MATERIAL_VALUES) for m in mats.values())


def _materials_table(mats) -> str:
    """``results.json`` ``scene.materials`` as a table, or a line saying they were not recorded."""
    if not _recorded(mats):
        kinds = sorted({str(m.get("kind")) for m in mats.values() if isinstance(m, dict)}) \
            if isinstance(mats, dict) else []
        more = f"; {len(mats)} materials, of kinds {', '.join(kinds)}" if kinds else ""
        return f"<p>Material values: {esc(OLD + more)}.</p>"
    rows = [[str(name), str(m.get("kind")), _text(m.get("triangles", "")),
             ", ".join(f"{k} {_text(m[k])}" for k in MATERIAL_VALUES if k in m), _text(m.get("emission", "")),
             _text(m.get("ignored", "")), shown_paths(str(m.get("from", "")))] for name, m in mats.items()]
    return _table(["material", "kind", "triangles", "values", "emission Le", "ignored (not rendered)", "from"], rows)


def _lights_table(lights, mats) -> str:
    """``results.json`` ``scene.lights`` as a table: where each came from (``from``: a mesh file's light; none:
    the scene file's ``lights:`` entry, where ``mats`` are recorded, else not recorded by an older tlm); the mesh
    light's emission, its materials'."""
    if not isinstance(lights, list) or not all(isinstance(lt, dict) for lt in lights):
        return f"<p>Lights: {esc(OLD)}.</p>"
    if not lights:
        return "<p>Lights: none.</p>"
    said = ("type", "kind", "power", "from")
    emits = {str(k): m.get("emission") for k, m in mats.items() if isinstance(m, dict)} if _recorded(mats) else {}

    def source(lt: dict) -> str:
        if lt.get("from"):
            return shown_paths(str(lt["from"]))
        if lt.get("type", lt.get("kind")) == "mesh":
            return "its materials' emission" + ("".join(
                f"; {k} {_text(emits[k])}" for k in lt.get("materials") or [] if emits.get(k)) if emits else "")
        return "the scene file's lights:" if _recorded(mats) else OLD

    rows = [[str(lt.get("type", lt.get("kind"))), _text(lt.get("power", "")),
             ", ".join(f"{k} {_text(v)}" for k, v in lt.items() if k not in said), source(lt)] for lt in lights]
    return _table(["light", "power W", "where", "from"], rows)


def scene_tables(runs: list[Run]) -> list[str]:
    """Per scene the runs rendered, its materials and lights as their ``results.json`` record them
    (``scene.materials``, ``scene.lights``), collapsed: once for the runs that record one scene alike (its
    name, file, materials, lights and inputs' digest, :func:`~tlm.report.names.scene_digest`; a run that records
    no digest, a sweep point, is told by its files now, and is not put with runs that recorded it where runs of its
    scene file recorded two: it may have read either), naming them. A later record of a scene listed (its name
    and file: a sweep's points that differ in a material) lists only its materials and lights that differ from the
    first's (a sweep of 200 points over one material of the conference room: 200 rows, not 200 tables of 36);
    no more than :data:`MAX_CONFIGS` records are listed, the rest counted."""
    groups: dict[str, list[Run]] = {}
    digests: dict[int, tuple[str | None, bool]] = {}  # (each run's scene_digest: the digest, whether recorded)
    recorded_of: dict[str, set] = {}  # (each scene file's digests that its runs recorded)
    for run in runs:
        digests[id(run)] = got, recorded = scene_digest(run)
        scene = run.results.get("scene") if isinstance(run.results.get("scene"), dict) else {}
        if recorded:
            recorded_of.setdefault(same_file(scene.get("source")), set()).add(got)
    for run in runs:
        scene = run.results.get("scene") if isinstance(run.results.get("scene"), dict) else {}
        got, recorded = digests[id(run)]
        # (by the digest alone: a run that recorded it and a sweep point whose files are digested now, of one
        # scene, are one record; but not where another run of the file recorded other contents, the file edited
        # between runs: what the point read is not known, and its own record says its digest is of the files now)
        joins = recorded or recorded_of.get(same_file(scene.get("source")), set()) <= {got}
        key = json.dumps([scene.get(k) for k in ("name", "source", "materials", "lights")] + [got, joins],
                         sort_keys=True, default=str)
        groups.setdefault(key, []).append(run)
    parts = []
    first: dict[str, tuple[dict, str]] = {}  # (a scene's name and file -> its first record listed, and its runs)
    for members in list(groups.values())[:MAX_CONFIGS]:
        scene = members[0].results.get("scene") or {}
        mats, lights = scene.get("materials"), scene.get("lights")
        named = listing([r.label for r in members], MAX_LISTED)
        runs_named = f"{'runs' if len(members) > 1 else 'run'} {named}"
        which = json.dumps([scene.get(k) for k in ("name", "source")], default=str)
        was = first.get(which)
        digest = digests[id(members[0])][0]
        now = "" if any(digests[id(r)][1] for r in members) else NOW  # (none of them recorded it: digested now)
        if was is not None and _recorded(mats) and _recorded(was[0].get("materials")) \
                and set(mats) == set(was[0]["materials"]):
            other = {k: m for k, m in mats.items() if was[0]["materials"][k] != m}
            same_lights = lights == was[0].get("lights")
            what = listing([f"{len(other)} material{'' if len(other) == 1 else 's'}"] * bool(other)
                           + ["its lights"] * (not same_lights)
                           + [f"inputs {digest}{now}"] * (digest is not None and digest != was[2])
                           + [f"inputs not known{NOT_HERE}"] * (digest is None and was[2] is not None))
            but = f", but {what}" if what else ""  # (none: values alike but written otherwise, 1 and 1.0)
            parts.append(f"<details><summary>scene {esc(members[0].scene_label)}: as for {esc(was[1])}{esc(but)} "
                         f"({esc(runs_named)})</summary>{_materials_table(other) if other else ''}"
                         f"{'' if same_lights else _lights_table(lights, mats)}</details>")
            continue
        first.setdefault(which, (scene, runs_named, digest))
        counts = ", ".join(f"{len(v)} {w}{'' if len(v) == 1 else 's'}" if isinstance(v, t) else f"no {w}s"
                           for v, t, w in ((mats, dict, "material"), (lights, list, "light")))
        counts += f", inputs {digest}{now}" if digest else ""
        parts.append(f"<details><summary>scene {esc(members[0].scene_label)}: {esc(counts)} "
                     f"({esc(runs_named)})</summary>"
                     f"{_materials_table(mats)}{_lights_table(lights, mats)}</details>")
    if len(groups) > MAX_CONFIGS:
        left = sum(len(m) for m in list(groups.values())[MAX_CONFIGS:])
        parts.append(f"<p>The materials and lights of {len(groups) - MAX_CONFIGS} more scene records ({left} "
                     f"run{'' if left == 1 else 's'}) are not listed: each run's results.json holds them "
                     "(scene.materials, scene.lights).</p>")
    return parts


def provenance_section(inputs: Inputs, out: Path) -> Section:
    sec = Section("provenance", "Provenance: config, seed, versions, revision and host time of every run")
    # (a --set column where some run was made with overrides: a sweep point's are its sweep's)
    overrides = any(given_set(run) for run in inputs.runs)
    # (who ran each run, its host and Dask worker: a column where more than one did, else a sweep's line below says
    # it once for its points; a tlm run's or a thesis cell's host is its results.json's "ran", shown only beside
    # another host's run: one machine's runs, one run alone, need no column)
    whos = [ran_by(run.results.get("ran")) for run in inputs.runs]
    ran = len({w for w in whos if w is not None}) > 1
    head = ["run", "kind", "folder", *(["--set"] if overrides else []), "seed", "git revision", "versions", "host s",
            *(["ran on"] if ran else [])]
    parts = []
    if inputs.runs:
        shared = shared_stages(inputs.runs)
        parts.append("<table><tr>" + "".join(f'<th class="l">{esc(h)}</th>' for h in head) + "</tr>")
        for i, run in enumerate(inputs.runs):
            cells = _run_row(run, shared.get(i), overrides) + ([ran_label(whos[i])] if ran else [])
            parts.append("<tr>" + "".join(f'<td class="l">{esc(c)}</td>' for c in cells) + "</tr>")
        parts.append("</table>")
        if shared:  # (the study's line, when the study is an input, is above the notes: html.section's order)
            where = ("its line above" if any(st.kind == "thesis" for st in inputs.studies)
                     else "its folder's provenance.json")
            sec.notes.append("A thesis study renders each scene once for all its modes: each cell's host seconds "
                             "count that render (the part said as shared with its scene's other modes), so its "
                             f"cells sum to more than the study's host seconds ({where}), which count the "
                             "render once.")
    else:
        cases = inputs.unread_cases()
        parts.append(f"<p>No run among the inputs{'; ' + esc(cases) if cases else ''}.</p>")
    parts += differs_html(inputs)  # (runs compared: what differs between them, not two whole configs alone)
    parts += scene_tables(inputs.runs)  # (each scene's materials and lights, as the runs read them)
    sec.notes += digest_notes(inputs.runs)  # (one scene file of other contents in two runs)
    for run in inputs.runs[:MAX_CONFIGS]:
        parts.append(f"<details><summary>{esc(run.label)}: resolved config</summary><pre>"
                     f"{esc(dump_yaml(run.config, sort_keys=False))}</pre></details>")
    if len(inputs.runs) > MAX_CONFIGS:
        sec.notes.append(f"The resolved configs of the first {MAX_CONFIGS} of {len(inputs.runs)} runs are listed; "
                         "every run's is its folder's config.resolved.yaml.")
    for sw in inputs.sweeps:  # (its points' rows above list its --set; its file and --set once, as the studies')
        line = f"sweep folder {sw.path}: sweep file {sw.spec.get('sweep')}, {with_set(sw.overrides) or 'no --set'}"
        if (where := ran_note([ran_by(r) for r in sw.rows])) is not None:  # (its host seconds are that machine's)
            line += f"; {where[0].lower()}{where[1:]}"
        parts.append(f"<p>{esc(line)}</p>")
    for st in inputs.studies:
        p = st.meta.get("provenance")
        line = (f"{st.kind} folder {st.path}: " + (
            f"study {shown_paths(str(p.get('study')))}, "
            f"{with_set(st.overrides) + ', ' if st.overrides else ''}git {_code(p)}, "
            f"{_versions(p.get('versions'))}, host {p.get('host_seconds')} s" if p else
            "no provenance.json (written by an older tlm); its runs' folders, when it has them, record theirs"))
        if st.kind == "thesis" and st.meta.get("host_seconds"):
            line += f"; host seconds per scene: {_per_scene(st.meta['host_seconds'])}"
        parts.append(f"<p>{esc(line)}</p>")
        if "config" in st.meta:
            parts.append(f"<details><summary>{esc(st.path.name)}: resolved config</summary><pre>"
                         f"{esc(dump_yaml(st.meta['config'], sort_keys=False))}</pre></details>")
    sec.html = "\n".join(parts)
    if not inputs.runs and not inputs.studies:
        sec.absent = "no inputs"
    return sec
