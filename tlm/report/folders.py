"""The report's folder search: which tlm command wrote a folder (:func:`kind_of`, by the files
in it: the table of :mod:`tlm.report.collect`), and the tlm folders under a folder that no tlm
command wrote, at any depth (:func:`find`), with a note on each folder it passed over that may
have been meant. :func:`tlm.report.collect.read` reads what it finds.
"""

from __future__ import annotations

from collections.abc import Container
from pathlib import Path

from tlm.config_words import listing
from tlm.errors import InputError


def kind_of(folder: Path, names: Container[str] | None = None) -> str | None:
    """Which tlm command wrote ``folder`` (None: none of them). ``names``: the names in it, where
    its listing is at hand (:func:`find`): a file not among them is not looked for."""
    def file(name: str) -> bool:
        return (names is None or name in names) and (folder / name).is_file()

    def subfolder(name: str) -> bool:
        return (names is None or name in names) and (folder / name).is_dir()

    if file("sweep.yaml") and (subfolder("points") or file("sweep.jsonl")):
        return "sweep"  # (a sweep *file* named sweep.yaml beside other things is not one)
    if file("thesis_comparison.csv"):
        return "thesis"
    if file("eq52.json"):
        return "scaling"
    if file("extreme.jsonl"):
        return "extreme"  # its cases/<name>/ run folders are not read as runs
    if file("granularity.jsonl"):
        return "granularity"
    if file("rows.jsonl") and file("reference.json"):
        return "error-vs-cost"
    if file("results.json"):
        return "run"
    return None


def real_path(folder: Path) -> str:
    import os

    return os.path.realpath(folder)


NOTES_SHOWN = 10  # the lines :func:`find` gives of each kind of folder it passes over; then how many more (one
# more than that: named too, never "and 1 more")
# folders of installed software, which no tlm command writes into, not searched by :func:`find` (``tlm report ~``
# would list every file of every environment): by their name, or by what they hold (a virtual environment's
# ``pyvenv.cfg``, a conda installation's or environment's ``conda-meta``)
SOFTWARE_NAMES = {"site-packages": "installed Python packages", "dist-packages": "installed Python packages",
                  "node_modules": "installed Node.js packages"}
SOFTWARE_MARKS = {"pyvenv.cfg": "a Python virtual environment", "conda-meta": "a conda environment"}
SOFTWARE_SHOWN = 3  # the folders of installed software the one line of :func:`find` names; then how many more
# a search that listed this many folders, or took this many seconds, is said to have been long (:func:`find`)
LONG_FOLDERS = 10_000
LONG_SECONDS = 5.0


def find(root: Path, skip: Path | None = None, notes: list[str] | None = None,
         named: list[int] | None = None) -> list[tuple[Path, str]]:
    """The tlm folders under ``root`` (a folder no tlm command wrote) at any depth, each with its
    kind (:func:`kind_of`), in sorted order of their paths: a tlm folder's own subfolders are its
    own (a sweep's points), not searched. Not searched either: a hidden folder (``.git``, ``.venv``,
    ``.cache``, a report half written), a report's folder (``report.html``; ``skip``, the report being
    written), and a folder of installed software (``site-packages``, ``dist-packages``, ``node_modules``,
    a virtual environment's or a conda installation's: :data:`SOFTWARE_NAMES`, :data:`SOFTWARE_MARKS`).
    A link to a tlm folder outside ``root`` is one (never searched: no loop); a link to another folder
    outside it is not followed, and one to a folder inside it is passed over (that folder is
    searched, and named, where it lies there).

    ``notes`` gets a line for each folder passed over that may have been meant, at most
    :data:`NOTES_SHOWN` of a kind and then a line of how many more (never "and 1 more": one over
    :data:`NOTES_SHOWN` is named, as :func:`~tlm.config_words.listing` does): a link to a folder outside
    ``root`` that is not a tlm folder, a folder that could not be listed and, where tlm folders were
    found, a folder with none in it at any depth (its subfolders not named apart), then one line
    that says the folders of installed software passed over and a long search (:data:`LONG_FOLDERS`
    folders listed, or :data:`LONG_SECONDS`), where there were any or it was; where none were found,
    the hidden, report and installed software's folders passed over instead. ``named`` gets, for
    each line of ``notes``, how many folders it names (1; a line of how many more, that many; the
    line on the search, the folders of installed software it counts), so that what is passed over
    is counted in folders, not in lines (:func:`tlm.report.collect.read`). Each folder is listed
    once; its entries' types come with the listing (no stat of a file, nor of a folder but a link's)."""
    import os
    import time

    t0 = time.perf_counter()
    top = real_path(root)
    skipped = real_path(skip) if skip is not None else None
    lines: dict[str, list[str]] = {"link": [], "unlisted": [], "empty": [], "hidden": [], "report": [],
                                   "software": []}
    met = dict.fromkeys(lines, 0)  # (the folders of each kind passed over: its lines and how many more)
    found: list[tuple[Path, str]] = []
    software: list[Path] = []  # (the folders of installed software passed over, in the order met)
    listed = 0  # (the folders listed: how long the search was)

    def note(kind: str, line: str) -> None:
        met[kind] += 1
        if len(lines[kind]) <= NOTES_SHOWN:  # (one over kept: named in place of "and 1 more")
            lines[kind].append(line)

    def listing(d: Path) -> list[os.DirEntry] | str:
        nonlocal listed
        listed += 1
        try:
            with os.scandir(d) as it:
                return sorted(it, key=lambda e: e.name)
        except OSError as e:
            return e.strerror or str(e)

    empty: list[Path] = []  # (folders with no tlm folder in them, though their parent has one)

    def walk(d: Path, real: str, entries: list[os.DirEntry]) -> tuple[bool, list[Path]]:
        """Search ``d`` (its real path and listing given): whether a tlm folder is in it, and its
        subfolders with none (said where ``d`` has one; else ``d`` is said in their stead)."""
        any_found, none = False, []
        for e in entries:
            try:
                if not e.is_dir():  # (a link to a folder is one: followed by the stat)
                    continue
                link = e.is_symlink()
            except OSError:
                continue
            c = Path(d, e.name)
            if e.name.startswith("."):
                note("hidden", f"{c}: a hidden folder, not searched")
                continue
            if link:
                target = real_path(c)
                if target == skipped or os.path.commonpath([top, target]) == top:
                    continue  # (a link to a folder inside ``root``: what it holds is read where it lies, by its name)
                k = kind_of(c)
                if k is not None:
                    found.append((c, k))
                    any_found = True
                else:
                    note("link", f"{c}: a link to {target}, a folder outside {root} and no run, sweep or study "
                                 "itself: not followed (give it to tlm report as a folder of its own)")
                continue
            c_real = os.path.join(real, e.name)  # (not a link: no need to ask the file system)
            if c_real == skipped:
                continue
            if e.name in SOFTWARE_NAMES:  # (passed over unlisted: node_modules may hold 100,000 files)
                software.append(c)
                note("software", f"{c}: {SOFTWARE_NAMES[e.name]}, not searched")
                continue
            inner = listing(c)
            if isinstance(inner, str):  # (a folder that cannot be listed may still be a tlm folder)
                k = kind_of(c)
                if k is None:
                    note("unlisted", f"{c}: not searched ({inner})")
                    continue
            else:
                names = {i.name for i in inner}
                if "report.html" in names and (c / "report.html").is_file():
                    note("report", f"{c}: a report's folder, not searched")
                    continue
                k = kind_of(c, names)
                mark = next((m for m in SOFTWARE_MARKS if m in names), None) if k is None else None
                if mark is not None:
                    software.append(c)
                    note("software", f"{c}: {SOFTWARE_MARKS[mark]} ({mark}), not searched")
                    continue
            if k is not None:
                found.append((c, k))
                any_found = True
                continue
            has, inner_empty = walk(c, c_real, inner)
            if has:
                any_found = True
                empty.extend(inner_empty)
            else:
                none.append(c)
        return any_found, none

    entries = listing(root)
    if isinstance(entries, str):
        raise InputError(f"cannot be searched ({entries})", source=str(root))
    empty.extend(walk(root, top, entries)[1])
    for c in sorted(empty):  # (in the order of their paths, as the tlm folders are)
        note("empty", f"{c}: no run, sweep or study in it")
    said = notes if notes is not None else []
    counts = named if named is not None else []
    wording = {"link": "links to folders outside {root} not followed", "unlisted": "folders not searched",
               "empty": "folders with no run, sweep or study in them", "hidden": "hidden folders not searched",
               "report": "report folders not searched", "software": "folders of installed software not searched"}
    for kind in ("link", "unlisted", *(("empty",) if found else ("hidden", "report", "software"))):
        if met[kind] <= NOTES_SHOWN + 1:
            said.extend(lines[kind])
            counts.extend([1] * len(lines[kind]))
        else:  # (2 or more: a plural)
            said.extend([*lines[kind][:NOTES_SHOWN], f"and {met[kind] - NOTES_SHOWN} more "
                         f"{wording[kind].format(root=root)}"])
            counts.extend([*[1] * NOTES_SHOWN, met[kind] - NOTES_SHOWN])
    if found:
        search = _search_line(root, software, listed, time.perf_counter() - t0)
        said.extend(search)
        counts.extend([len(software)] * len(search))
    return found


def _search_line(root: Path, software: list[Path], listed: int, seconds: float) -> list[str]:
    """:func:`find`'s one line on its search of ``root`` where it found tlm folders: the folders of
    installed software it passed over, and how long it was where it was long (none: ``[]``)."""
    parts = []
    if listed >= LONG_FOLDERS or seconds >= LONG_SECONDS:
        parts.append(f"the search for tlm folders listed {listed:,} folders in {seconds:.1f} s (name the folders "
                     "that hold the runs, or one nearer them, for a quicker report)")
    if software:
        shown = listing(map(str, software), SOFTWARE_SHOWN)
        parts.append(f"{len(software)} folder{'s' * (len(software) > 1)} of installed software not searched "
                     f"(a virtual or conda environment, site-packages, dist-packages or node_modules: no tlm "
                     f"command writes there): {shown}")
    return [f"{root}: {'; '.join(parts)}"] if parts else []
