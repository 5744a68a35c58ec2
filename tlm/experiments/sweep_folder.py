"""What a sweep finds in its folder from before it (out of :mod:`tlm.experiments.sweep`): the report of an earlier
sweep (``OUT/report``), which it removes as it claims the folder (:func:`drop_report`), and the point folders that
are not its own, which it counts and says what they are (:func:`other_names`, :func:`other_folders_line`): where
the folder's sweep before this one (its ``sweep.yaml`` as found, :func:`earlier_sweep`) names them, what changed
since (a factor's values then and now, a ``set`` key's, the ``--set`` strings, the base's), or that only tlm's
code did (the ``code_fingerprint`` their ``results.json`` hold); else what may have left them.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import stat
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from tlm import storage
from tlm.config_words import dump_yaml, listing, safe_load, value_text
from tlm.errors import InputError
from tlm.storage_carry import real_dir

REPORT = "report"  # a sweep folder's report (tlm sweep's, tlm report's), a report's folder: its page REPORT_PAGE
REPORT_PAGE = "report.html"
SHOWN = 3  # the changes a line names (and how many more)
# a point of a sweep.yaml: its hash's line (sweep_file.Sweep.marker writes each so, quoted where YAML reads a number)
_HASH_LINE = re.compile(r"^  hash: '?([0-9a-f]{16})'?$", re.MULTILINE)
_POINTS = re.compile(r"^points:", re.MULTILINE)  # (the last key of a sweep.yaml: its head is before it)
_PARTS = (("base", "base's"), ("set", "set's"), ("grid", "grid's"), ("zip", "zip's"))


def drop_report(out: Path, current: bool = False) -> str | None:
    """Remove the report in the sweep folder ``out`` (``OUT/report``: a real folder, not a link, that holds its
    ``report.html``, which tlm wrote), as a sweep claims the folder: its rows are this sweep's from then on, and a
    report of the earlier ones beside them (another sweep's, another ``--set``'s, a sweep cut short) would be read
    as theirs. The sweep's own is written after its points (``tlm sweep``, unless ``--no-report``); ``tlm run``
    into a run folder removes its earlier report the same way, whole (:data:`tlm.storage_carry.WHOLE`). Kept where
    it is of the rows the sweep leaves: ``current`` (the folder's ``sweep.yaml`` is this sweep's, and no point is to
    run) and written after the rows (``sweep.jsonl``). Renamed aside under the report folder's lock (no report
    swapped in meanwhile is half removed), then removed. A ``report`` of anything else (a user's folder, a link, a
    file) is left alone. The warning line where it could not be removed (the folder not writable); else None."""
    report = out / REPORT
    if not report_goes(out, current):
        return None
    aside = out / f".{REPORT}.old-{storage.new_writer()}"  # (a killed sweep's: removed by the next report's writer)
    storage.hold(aside.name)
    try:
        with storage.folder_lock(report):
            if _report_there(report):
                os.rename(report, aside)
    except OSError as e:
        return (f"{report} is the report of the folder's earlier sweep, not of this one's rows: it could not be "
                f"removed ({e.strerror or e}); write this sweep's with: tlm report {out}")
    finally:
        shutil.rmtree(aside, ignore_errors=True)
        storage.release(aside.name)
    return None


def report_goes(out: Path, current: bool = False) -> bool:
    """Whether a sweep that claims the folder ``out`` removes its report there (:func:`drop_report`'s rule, which
    ``tlm sweep --dry-run`` tells too: :func:`~tlm.experiments.sweep_plan.plan`): a report's folder is there and it
    is not of the rows the sweep leaves (``current``, and written after ``sweep.jsonl``)."""
    report = out / REPORT
    return _report_there(report) and not (current and _after_rows(out, report))


def _after_rows(out: Path, report: Path) -> bool:
    """Whether the page in ``report`` was written after the rows of the sweep in ``out`` (``sweep.jsonl``)."""
    try:
        return os.stat(report / REPORT_PAGE).st_mtime_ns >= os.stat(out / "sweep.jsonl").st_mtime_ns
    except OSError:
        return False


@contextmanager
def rows_dated(out: Path) -> Iterator[None]:
    """Around a rewrite of the rows of the sweep in ``out``: where ``sweep.jsonl`` then holds the very bytes it held
    before (a rerun with no point to run), its time is set back to when they were first written, so a report of
    them stays newer than the rows (:func:`_after_rows`): without it, the second rerun of an unchanged sweep with
    ``--no-report`` removed the report the first kept (h493)."""
    rows = out / "sweep.jsonl"
    try:  # (read only where a report is there to be kept)
        before, st = (rows.read_bytes(), os.stat(rows)) if _report_there(out / REPORT) else (None, None)
    except OSError:
        before = st = None
    yield
    if st is not None:
        with suppress(OSError):
            if rows.read_bytes() == before:
                os.utime(rows, ns=(st.st_atime_ns, st.st_mtime_ns))


def _report_there(report: Path) -> bool:
    """Whether ``report`` is a report's folder (a real folder holding a file ``report.html``)."""
    try:
        return real_dir(report) and stat.S_ISREG(os.lstat(report / REPORT_PAGE).st_mode)
    except OSError:
        return False


@dataclass(frozen=True)
class Earlier:
    """The folder's ``sweep.yaml`` as found before this sweep claimed it (its text: read then, parsed only where a
    line needs it)."""

    text: str

    def hashes(self) -> set[str]:
        """Its points' hashes."""
        return set(_HASH_LINE.findall(self.text))

    def head(self) -> dict | None:
        """Its data but its points (None where it is not a sweep's)."""
        end = _POINTS.search(self.text)
        try:
            data = safe_load(self.text[:end.start()] if end else self.text)
        except (yaml.YAMLError, InputError, ValueError):
            return None
        return data if isinstance(data, dict) and data.get("tlm") == "sweep/1" else None


def earlier_sweep(out: Path) -> Earlier | None:
    """The folder ``out``'s ``sweep.yaml`` (an earlier sweep's), read before this sweep writes its own; None where
    there is none (or it cannot be read)."""
    try:
        return Earlier((out / "sweep.yaml").read_text(encoding="utf-8", errors="replace"))
    except (OSError, ValueError):
        return None


def other_names(points_dir: Path, hashes) -> list[str]:
    """The folders in ``points_dir`` that are none of ``hashes`` (this sweep's points), sorted: those an earlier
    run into the folder left. One listing, names only; a writer's hidden temporary folders are not counted."""
    try:
        names = os.listdir(points_dir)
    except OSError:
        return []
    return sorted(n for n in names if not n.startswith(".") and n not in hashes)


def other_folders_line(n: int, points_dir: Path, earlier: Earlier | None = None, sweep=None,
                       code: str | None = None, names: list[str] | None = None) -> str:
    """The line that says what the ``n`` folders of :func:`other_names` are (``names``, where the caller listed
    them: those an earlier run into the folder left, of other tlm code, another config or a different ``--set``: a
    point's hash holds the code's fingerprint, its resolved config, the ``--set`` values included, and its input
    files' content). Given the folder's ``earlier``
    sweep (:func:`earlier_sweep`), this ``sweep`` (a :class:`~tlm.experiments.sweep_file.Sweep`) and tlm's
    ``code`` fingerprint (None: this process's): of those that are the earlier sweep's points, what changed since
    (:func:`changes`), or that only tlm's code did (their ``results.json``'s ``code_fingerprint``, not this one's);
    else (or of the others) what may have left them: other code, another config or a different ``--set``."""
    them, its = ("them", "are") if n != 1 else ("it", "is")
    tail = (f"; nothing reads {them}, and removing {them} changes no result (sweep.yaml lists this sweep's hashes)")
    head = f"{n} point folder{'s' if n != 1 else ''} in {points_dir} {its} not this sweep's: "
    generic = ("of other tlm code, another config or a different --set (an edit under tlm/ or to an input file "
               "changes every point's hash)")
    then = earlier.head() if earlier is not None and sweep is not None else None
    if then is None:
        names = []
    elif names is None:
        names = other_names(points_dir, {p.hash for p in sweep.points})
    hashes = earlier.hashes() if then is not None else set()
    ours = [name for name in names if name in hashes]
    said = _why(then, sweep, [points_dir / name for name in ours], code) if ours else None
    if said is None:
        return f"{head}left by an earlier run into the folder {generic}{tail}"
    rest = len(names) - len(ours)
    if rest > 0:
        said = (f"{len(ours)} of them {'are' if len(ours) != 1 else 'is'} {said}; {rest} more left by a sweep into "
                f"the folder before it, {generic.split(' (')[0]}")
    return f"{head}{said}{tail}"


def _why(then: dict, sweep, folders: list[Path], code: str | None) -> str | None:
    """What the folders of the earlier sweep ``then`` (its ``sweep.yaml``'s data but its points) that ``sweep``
    does not have are: its points, what changed, or the code that wrote them; None where neither changed (an
    input file, or code the folders' ``results.json`` do not tell: none there, a point that failed)."""
    now = safe_load(dump_yaml({k: v for k, v in sweep.to_dict().items() if k != "points"}, sort_keys=False))
    changed = changes(then, now)
    if code is None:
        from tlm.fingerprint import code_fingerprint

        code = code_fingerprint()
    codes = sorted({c for f in folders if (c := code_of(f)) is not None})
    old_code = bool(codes) and code not in codes
    was = (f"other tlm code (code_fingerprint {listing(codes, named=SHOWN, last='or')} in their results.json, "
           f"this tlm's {code})")
    source = then.get("sweep")
    of = f"{source}, " if isinstance(source, str) and source != str(sweep.path) else ""  # (another file's)
    said = f"{'points' if len(folders) != 1 else 'a point'} of the folder's earlier sweep ({of}its sweep.yaml " \
           "before this one's)"
    if changed and old_code:  # (the code first: it alone changes every point's hash, whatever the grid did: h531)
        them = "them" if len(folders) != 1 else "it"
        return (f"{said}, run by {was}, which alone leaves {them} behind (a point's hash holds the code's "
                f"fingerprint); the sweep changed since too: {listing(changed, named=SHOWN, more='more changes')}")
    if changed:
        return f"{said}: {listing(changed, named=SHOWN, more='more changes')}"
    if old_code:  # (the same sweep: the code alone)
        return f"{said}, of the same settings and factors, run by {was}"
    return None  # (the code or an input file, untold: the line says what may have left them)


def code_said(folders: list[Path], code: str, whose: str) -> str | None:
    """What the point ``folders`` an earlier run into a sweep's folder left are, told by their ``results.json``'s
    ``code_fingerprint`` alone (where no earlier ``sweep.yaml`` names them: ``tlm report``'s note, the folder's
    holding the latest sweep's only), against ``code``, that of ``whose`` points (``"this sweep's"``): of other
    tlm code, or of the same (so of another config, a different ``--set`` or an edited input file), or some of
    each; None where a folder's code is not told (no ``results.json``: a point that failed, or unreadable)."""
    codes = [code_of(f) for f in folders]
    if not codes or None in codes:
        return None
    other = sorted({c for c in codes if c != code})
    was = (f"other tlm code (code_fingerprint {listing(other, named=SHOWN, last='or')} in "
           f"{'their' if len(codes) != 1 else 'its'} results.json, {whose} {code})")
    same = "another config, a different --set or an edited input file"
    if not other:
        return f"{whose} tlm code (code_fingerprint {code} in {'their' if len(codes) != 1 else 'its'} " \
               f"results.json), so of {same}"
    if code not in codes:
        return was
    n = codes.count(code)
    return f"{was}: {len(codes) - n} of them; {n} more of {whose} tlm code, so of {same}"


def code_of(folder: Path) -> str | None:
    """The ``code_fingerprint`` of the point's ``results.json`` in ``folder`` (None: none, or unreadable)."""
    try:
        code = json.loads((folder / "results.json").read_bytes()).get("code_fingerprint")
    except (OSError, ValueError, AttributeError):
        return None
    return code if isinstance(code, str) else None


def changes(then: dict, now: dict) -> list[str]:
    """What differs between two sweeps' data (``sweep.yaml``'s, but their points), in words: a factor's values
    (``grid's arch.fifo_depth was [16, 256], now [16, 1024]``), one new or gone, a ``set`` key's, the base's
    (its keys dotted) and the ``--set`` strings (``overrides``). Their file, description and points aside."""
    said = []
    for part, word in _PARTS:
        a, b = ((_dotted(d.get(part)) if part == "base" else d.get(part)) for d in (then, now))
        a, b = a if isinstance(a, dict) else {}, b if isinstance(b, dict) else {}
        for key in dict.fromkeys([*a, *b]):
            if key not in b:
                said.append(f"{word} {key} was {_shown(a[key])}, now none")
            elif key not in a:
                said.append(f"{word} {key} was none, now {_shown(b[key])}")
            elif a[key] != b[key]:
                said.append(f"{word} {key} was {_shown(a[key])}, now {_shown(b[key])}")
    given = [then.get("overrides") or [], now.get("overrides") or []]
    if given[0] != given[1]:
        then_set, now_set = (" ".join(map(str, g)) if isinstance(g, list) and g else "none" for g in given)
        said.append(f"its --set was {then_set}, now {now_set}")
    return said


def _dotted(data: Any, prefix: str = "") -> dict:
    """A nested mapping's leaves by their dotted keys (``render.spp``)."""
    if not isinstance(data, dict):
        return {prefix: data} if prefix else {}
    flat: dict = {}
    for k, v in data.items():
        key = f"{prefix}.{k}" if prefix else str(k)
        flat.update(_dotted(v, key) if isinstance(v, dict) and v else {key: v})
    return flat


def _shown(v: Any) -> str:
    """A value as YAML writes it, cut short (:func:`~tlm.config_words.value_text`)."""
    return value_text(v, limit=60)
