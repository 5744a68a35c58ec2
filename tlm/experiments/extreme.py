"""Stiff and extreme cases as an experiment: each case, the behaviour expected, the result measured.

``tlm extreme extreme --out runs/extreme`` (the built-in experiment, ``configs/extreme.yaml``
in a checkout; or a file of your own) runs every case through the normal pipeline (render,
simulate, write a run folder) and checks what the case expects. The file::

    description: ...
    base: {resolution: [32, 32], arch: {frames: 1}}   # merged under every case's config
    cases:
      - name: cornell-ior1                              # unique; the case's folder name
        category: shading
        expect: the IOR-1 sphere vanishes               # the behaviour, in words
        config: {scene: extreme/cornell_ior1, mode: refract}  # a built-in scene, or a scene file's path
        checks:                                         # what is measured and judged
          - finite                                      # every image finite, no NaN number
          - invariants                                  # the timing model's invariants hold
          - {same_image: cornell-no-glass, rel_rms: 1.0e-3}
          - {value: cycles.throughput, min: 1, max: 1.0e12}
          - {compare: cycles.throughput, case: cornell, op: ">="}
          - {error: "must be > 0"}                      # bad input: this InputError, nothing written

``same_image`` compares the composite radiance with another case's (relative RMS,
0 = bitwise); ``compare`` a number of ``results.json`` (a dotted key) with the same
number of another case (``op``: ``==``, ``<=``, ``>=``, ``<``, ``>``, or ``~`` with
``rel``: within that relative difference); ``value`` takes ``min``, ``max`` (numbers)
and ``equals``. Every check's keys and values are checked before any case runs: a
misspelt key, a value of the wrong type or a case named that is not an earlier one that
runs is an input error. A case that
expects an error passes when its run fails with an input error whose one line holds
the text, and leaves no folder. Output: ``cases/<name>/`` (each run folder),
``extreme.csv`` and ``extreme.jsonl`` (one row per case: category, expectation,
checks, what was measured, pass or fail, host seconds), ``provenance.json``. The
report shows the table (``tlm report``).
"""

from __future__ import annotations

import json
import math
import operator
import time
from pathlib import Path
from typing import Any

import numpy as np

from tlm.config import SECTIONS, config_from_dict, deep_merge, file_folder
from tlm.config_words import with_overrides
from tlm.errors import InputError, did_you_mean, quoted
from tlm.experiments.study import read_study, refuse_own_keys, refuse_set, run_study, with_set
from tlm.storage import warn

COLUMNS = ("case", "category", "expect", "checks", "measured", "passed", "seconds")
CHECKS = ("finite", "invariants", "same_image", "value", "compare", "error")
OPS = {"==": operator.eq, "<=": operator.le, ">=": operator.ge, "<": operator.lt, ">": operator.gt, "~": None}
CASE_KEYS = ("name", "category", "expect", "config", "checks")
WORDS = ("finite", "invariants")  # the checks written as a bare word, without settings
CHECK_KEYS = {  # the keys of each check written as a mapping, its own name first
    "same_image": ("same_image", "rel_rms"),
    "value": ("value", "min", "max", "equals"),
    "compare": ("compare", "case", "op", "rel"),
    "error": ("error",),
}
TEXT_KEYS = ("same_image", "value", "compare", "case", "error")  # non-empty text
NUMBER_KEYS = ("rel_rms", "rel", "min", "max")  # finite numbers; rel_rms and rel >= 0, min and max may be null


def _is_number(x: Any) -> bool:
    """A real number (not a bool)."""
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _what(x: Any) -> str:
    """A value of results.json in a few words."""
    if isinstance(x, dict):
        return "a mapping"
    if isinstance(x, list):
        return "a list"
    return "null" if x is None else repr(x)


def _kind(check: Any) -> str | None:
    """The kind of a check (one of CHECKS), or None when it names none or more than one."""
    if isinstance(check, str):
        return check if check in CHECKS else None
    kinds = [k for k in check if k in CHECKS] if isinstance(check, dict) else []
    return kinds[0] if len(kinds) == 1 else None


def _equals_ok(x: Any) -> bool:
    """``equals`` may be text, true/false, null, a finite number or a list of them."""
    if isinstance(x, list):
        return all(_equals_ok(v) for v in x)
    if _is_number(x):
        return math.isfinite(x) if isinstance(x, float) else True
    return x is None or isinstance(x, (str, bool))


def _check_check(chk: Any, src: str, key: str, earlier: set[str], ran: set[str]) -> str:
    """The kind of the check ``chk`` at ``key`` of ``src``, its keys and values checked: a case it
    names must be one of ``earlier`` and one that ``ran`` (not one that expects an error)."""
    kind = _kind(chk)
    if kind is None:
        if isinstance(chk, dict) and len([k for k in chk if k in CHECKS]) > 1:
            raise InputError(f"holds more than one check ({', '.join(k for k in chk if k in CHECKS)}): "
                             "write each as a check of its own", source=src, key=key)
        word = chk if isinstance(chk, str) else (str(next(iter(chk))) if isinstance(chk, dict) and chk else "")
        raise InputError(f"{chk!r} is not a check ({', '.join(CHECKS)}){did_you_mean(word, CHECKS)}", source=src,
                         key=key)
    if isinstance(chk, str):
        return kind
    if kind in WORDS:
        raise InputError(f"{kind!r} takes no settings: write it as the word {kind}", source=src, key=key)
    allowed = CHECK_KEYS[kind]
    for k in chk:
        if k not in allowed:
            hint = did_you_mean(str(k), allowed) or f" (a {kind} check takes {', '.join(allowed)})"
            raise InputError(f"unknown key {k!r}{hint}", source=src, key=key)
    if kind == "compare" and "case" not in chk:
        raise InputError("missing key 'case' (the earlier case to compare with)", source=src, key=key)
    for k, v in chk.items():
        if k in TEXT_KEYS and (not isinstance(v, str) or not v):
            raise InputError(f"{v!r} is not a non-empty text", source=src, key=f"{key}.{k}")
        if k in NUMBER_KEYS and not (v is None and k in ("min", "max")):
            if not _is_number(v):
                raise InputError(f"{v!r} is not a number", source=src, key=f"{key}.{k}")
            if isinstance(v, float) and not math.isfinite(v):
                raise InputError(f"{v!r} is not finite", source=src, key=f"{key}.{k}")
            if k in ("rel_rms", "rel") and v < 0:
                raise InputError(f"{v!r} must be >= 0", source=src, key=f"{key}.{k}")
        if k == "equals" and not _equals_ok(v):
            raise InputError(f"{v!r} is not text, true/false, null, a finite number or a list of them", source=src,
                             key=f"{key}.{k}")
    if kind == "compare":
        op = chk.get("op", "==")
        if not isinstance(op, str) or op not in OPS:
            raise InputError(f"op {op!r} is not one of {', '.join(OPS)}", source=src, key=f"{key}.op")
        if "rel" in chk and op != "~":
            raise InputError(f"rel applies to op '~' only, not {op!r}", source=src, key=f"{key}.rel")
    if kind in ("same_image", "compare"):
        other = chk["case"] if kind == "compare" else chk["same_image"]
        if other not in earlier:
            raise InputError(f"{quoted(other)} is not an earlier case", source=src, key=key)
        if other not in ran:
            raise InputError(f"{quoted(other)} expects an error, so it has no results to compare with", source=src,
                             key=key)
    return kind


def load_cases(path: Path, overrides: tuple[str, ...] = ()) -> tuple[dict, list[dict], Path]:
    """The base config and the cases of the file, every one checked before any runs.
    ``overrides``: ``tlm extreme --set`` strings, applied to the base (merged under every case's
    config) as ``tlm run --set`` applies them; one of a key a case's config gives (or a section
    above or below one) is refused: that case's value would win unsaid."""
    overrides = tuple(overrides)  # (read twice: an iterator's, once; h455)
    raw, base, src = read_study(path, ("cases",), overrides, lambda raw: _scened(raw.get("cases"))[1])
    label = src  # (what a case's config is named by in its errors)
    if overrides:
        given = base  # (a --set scene that a case's scene refuses below: not warned of, h455)
        base = with_set(base, overrides, [file_folder(path)], not _scened(raw.get("cases"))[0])
        refuse_own_keys(overrides, ("cases",), src)
        label = with_overrides(src)
        try:  # (a bad --set said as tlm run says it; a base that holds only under its cases, as ever by them)
            config_from_dict(base, label)
        except InputError:
            try:
                config_from_dict(given, src)
            except InputError:
                pass
            else:
                raise
    cases = raw.get("cases")
    if not isinstance(cases, list) or not cases:
        raise InputError("must be a non-empty list of cases", source=src, key="cases")
    names: set[str] = set()  # the cases so far
    ran: set[str] = set()  # those of them that run (expect no error): their results can be compared
    for i, c in enumerate(cases):
        where = f"cases[{i}]"
        if not isinstance(c, dict):
            raise InputError("must be a mapping (name, category, expect, config, checks)", source=src, key=where)
        for k in c:
            if k not in CASE_KEYS:
                raise InputError(f"unknown key (expected {', '.join(CASE_KEYS)})", source=src, key=f"{where}.{k}")
        for k in CASE_KEYS:
            if k not in c:
                raise InputError("missing", source=src, key=f"{where}.{k}")
        name = c["name"]
        if not isinstance(name, str) or not name or "/" in name or name.startswith("."):
            raise InputError(f"{quoted(name)} must be a folder name", source=src, key=f"{where}.name")
        if name in names:
            raise InputError(f"{quoted(name)} is used twice", source=src, key=f"{where}.name")
        if not isinstance(c["config"], dict):
            raise InputError("must be a run config mapping", source=src, key=f"{where}.config")
        if not isinstance(c["checks"], list) or not c["checks"]:
            raise InputError("must be a non-empty list", source=src, key=f"{where}.checks")
        expects_error = False
        for j, chk in enumerate(c["checks"]):
            kind = _check_check(chk, src, f"{where}.checks[{j}]", names, ran)
            expects_error |= kind == "error"
        if expects_error and len(c["checks"]) != 1:
            raise InputError("a case that expects an error has that one check", source=src, key=f"{where}.checks")
        if overrides:  # (its keys: a --set of one would be lost in this case)
            refuse_set(overrides, {k: f"set by the case {quoted(name)} ({where}.config.{k}), whose config wins over "
                                      "--set; change the case in the cases file, not by --set"
                                   for k in _leaves(c["config"])}, src)
        if not expects_error:  # a case that should run must have a valid config now
            config_from_dict(deep_merge(base, c["config"]), f"{label} ({where})")
            ran.add(name)
        names.add(name)
    return base, cases, file_folder(path)  # (a pipe's, <(...): the working folder)


def _scened(cases: Any) -> tuple[bool, bool]:
    """Whether some and whether every case of ``cases`` (the file's, unchecked) gives its config a ``scene``:
    the base's is then not that case's (every case's: not warned of, :func:`tlm.config_paths.shadowed_warning`),
    and a ``--set scene`` is refused (h455)."""
    scened = [isinstance(c, dict) and isinstance(c.get("config"), dict) and "scene" in c["config"]
              for c in (cases if isinstance(cases, list) else [])]
    return any(scened), bool(scened) and all(scened)


def _leaves(config: dict, prefix: str = "") -> list[str]:
    """The dotted keys a case's ``config`` gives, as :func:`tlm.config.deep_merge` merges it over
    the base: each key of a mapping given for a section (none of an empty one: it changes nothing),
    else the key itself; as :func:`~tlm.experiments.study.set_leaves` reads a ``--set``."""
    out = []
    for k, v in config.items():
        key = f"{prefix}{k}"
        out.extend(_leaves(v, f"{key}.") if isinstance(v, dict) and key in SECTIONS else [key])
    return out


def _get(results: dict, key: str) -> Any:
    """``results`` at a dotted key; a key may hold dots itself (``timing.units.pipe0.vertex``)."""
    v: Any = results
    parts = key.split(".")
    while parts:
        for n in range(len(parts), 0, -1):  # the longest key first
            k = ".".join(parts[:n])
            if isinstance(v, dict) and k in v:
                v, parts = v[k], parts[n:]
                break
        else:
            raise KeyError(key)
    return v


def _numbers(x: Any):
    if isinstance(x, dict):
        for v in x.values():
            yield from _numbers(v)
    elif isinstance(x, list):
        for v in x:
            yield from _numbers(v)
    elif isinstance(x, float):
        yield x


def _rel_rms(a: np.ndarray, b: np.ndarray) -> float:
    den = float(np.sqrt(np.mean(b.astype(np.float64) ** 2)))
    num = float(np.sqrt(np.mean((a.astype(np.float64) - b) ** 2)))
    return num / den if den > 0 else (0.0 if num == 0 else math.inf)


def judge(check, folder: Path, results: dict, done: dict[str, tuple[Path, dict]]) -> tuple[bool, str]:
    """(passed, what was measured) of one check of a case that ran."""
    try:
        return _judge(check, folder, results, done)
    except KeyError as e:
        return False, f"results.json has no {e.args[0]!r}"


def _judge(check, folder: Path, results: dict, done: dict[str, tuple[Path, dict]]) -> tuple[bool, str]:
    kind = _kind(check)
    other = check.get("case" if kind == "compare" else "same_image") if kind in ("compare", "same_image") else None
    if other is not None and other not in done:
        return False, f"case {quoted(other)} has no results (its run failed)"
    if kind == "finite":
        bad_images = [p.name for p in sorted((folder / "radiance").glob("*.npy")) if not np.isfinite(np.load(p)).all()]
        bad_numbers = sum(1 for v in _numbers(results) if not math.isfinite(v))
        ok = not bad_images and bad_numbers == 0
        return ok, ("images finite, no NaN or inf number" if ok
                    else f"non-finite images {bad_images}, {bad_numbers} non-finite numbers")
    if kind == "invariants":
        inv = results["timing"]["invariants"]
        failed = [k for k, v in inv.items() if not v]
        return not failed, (f"{len(inv)} invariants hold" if not failed else f"failed: {failed}")
    if kind == "same_image":
        other, _ = done[check["same_image"]]
        tol = float(check.get("rel_rms", 0.0))
        a = np.load(folder / "radiance" / "composite.npy")
        b = np.load(other / "radiance" / "composite.npy")
        if a.shape != b.shape:
            return False, f"image {a.shape[:2]} against {b.shape[:2]}"
        err = _rel_rms(a, b)
        return err <= tol, f"relative RMS {err:.3g} against {check['same_image']} (tolerance {tol:g})"
    if kind == "value":
        v = _get(results, check["value"])
        if (check.get("min") is not None or check.get("max") is not None) and not _is_number(v):
            return False, f"{check['value']} is {_what(v)}, not a number"
        ok = (check.get("min") is None or v >= check["min"]) and (check.get("max") is None or v <= check["max"])
        if "equals" in check:
            ok = ok and v == check["equals"]
        return bool(ok), f"{check['value']} = {v:.6g}" if isinstance(v, float) else f"{check['value']} = {v}"
    if kind == "compare":
        _, theirs = done[check["case"]]
        a, b = _get(results, check["compare"]), _get(theirs, check["compare"])
        op = check.get("op", "==")
        if op != "==" and not (_is_number(a) and _is_number(b)):
            return False, f"{check['compare']}: {_what(a)} against {_what(b)} ({check['case']}), not numbers"
        if op == "~":
            rel = float(check.get("rel", 0.0))
            err = abs(a - b) / abs(b) if b else math.inf
            return err <= rel, f"{check['compare']}: {a} against {b} ({check['case']}): {err:.3%} (within {rel:.0%})"
        return bool(OPS[op](a, b)), f"{check['compare']}: {a} {op} {b} ({check['case']})"
    raise ValueError(kind)


def case_named(e: InputError, source: str, case: str) -> InputError:
    """``e`` naming the case ``case`` beside the cases file ``source`` (``extreme.yaml (bad-x): ...``),
    as the config's own checks name it; ``e`` itself where it names another file, or the case already."""
    if e.source not in (source, with_overrides(source)):  # (a run of a case under --set: its config's, so named)
        return e
    return e.replaced(source=f"{e.source} ({case})")


def run_extreme(path: Path, out: Path, progress=None, overrides: tuple[str, ...] = (), *, via: str = "--set",
                warned=warn) -> list[dict]:
    """Run every case of ``path`` into ``out``; returns the rows (one per case). ``overrides``: ``tlm
    extreme --set`` strings (:func:`load_cases`), which each case's ``results.json`` (``overrides``)
    and the study's ``provenance.json`` list. Of the warnings each case's ``results.json`` holds, only
    those of its ``--set`` are said on stderr (``tlm: warning: ...``), once for the study: one that sets
    nothing (``--set render={}``: :func:`~tlm.experiments.run_warnings.empty_sets`) before the cases, one
    that some cases never read after them, with which and why (:func:`unread_lines`); the others (a
    coarse packet size, ...) are each case's own, in its folder and the report. ``via``: what those lines call the
    overrides; ``warned``: where they go (default: stderr; :func:`tlm.api.extreme` returns them)."""
    from tlm.experiments.run import run
    from tlm.experiments.run_warnings import empty_sets

    overrides = tuple(str(o) for o in overrides)
    base, cases, folder = load_cases(Path(path), overrides)
    empty = empty_sets(overrides, via)  # (a --set render={}: said once now, before the cases, not after each)
    for line in empty:
        warned(line)
    done: dict[str, tuple[Path, dict]] = {}
    unread: dict[str, dict[str, list[str]]] = {}  # a --set some case never reads -> why -> those cases
    given = {f"{via} {o.strip()}" if via.startswith("-") else f"{o.strip()} (in {via})" for o in overrides}

    def one(c: dict, tmp: Path) -> dict:
        t0 = time.perf_counter()
        dest = tmp / "cases" / c["name"]
        checks = c["checks"]
        want_error = isinstance(checks[0], dict) and "error" in checks[0]
        try:
            cfg = config_from_dict(deep_merge(base, c["config"]), f"{path} ({c['name']})")
            results = run(cfg, dest, folder, config_path=str(path), overrides=list(overrides) or None, via=via)
        except InputError as e:
            e = case_named(e, str(path), c["name"])  # (the run's own checks name the file alone: the case too)
            if want_error:
                text = checks[0]["error"]
                ok = text in str(e) and len(str(e).splitlines()) == 1 and not dest.exists()
                measured = f"input error: {e}"
            else:
                ok, measured = False, f"unexpected input error: {e}"
        else:
            if want_error:
                ok, measured = False, "ran without the expected error"
            else:
                verdicts = [judge(chk, dest, results, done) for chk in checks]
                ok = all(v for v, _ in verdicts)
                measured = "; ".join(m for _, m in verdicts)
                done[c["name"]] = (dest, results)
                for line in results["warnings"]:  # (its --set it never read: said once below, for every case)
                    item, said, why = line.partition(" has no effect in this run: ")
                    if said and item in given and line not in empty:  # (as tlm thesis words its cells': its mode)
                        why = why.replace(f"mode {results['mode']!r}", "its mode")
                        unread.setdefault(item, {}).setdefault(why, []).append(c["name"])
        return {"case": c["name"], "category": c["category"], "expect": c["expect"],
                "checks": json.dumps(checks), "measured": measured, "passed": ok,
                "seconds": round(time.perf_counter() - t0, 3)}

    rows = run_study(str(path), out, "extreme", cases, one, columns=COLUMNS, progress=progress, overrides=overrides)
    for line in unread_lines(unread, len(done)):
        warned(line)
    return rows


def unread_lines(unread: dict[str, dict[str, list[str]]], ran: int) -> list[str]:
    """One line per ``--set`` of the study that some of its cases never read (``unread``: the override
    as given, ``--set KEY=VALUE``, -> why, as the case's ``results.json`` says it, -> those cases;
    ``ran``: how many cases ran), once for the study: how many cases, which, and why (each case's
    ``results.json`` ``warnings`` keeps its own line)."""
    lines = []
    for item, whys in unread.items():
        n = sum(len(names) for names in whys.values())
        lines.append(f"{item} has no effect in {n} of {ran} cases: "
                     + "; ".join(f"{why} ({'case' if len(names) == 1 else 'cases'} {', '.join(names)})"
                               for why, names in whys.items()))
    return lines
