"""Which files of a run folder its run wrote: the report reads those alone.

A rerun into a run folder keeps what the new run does not write there of the earlier one's (the user's files, a
file the user edited since, and, where the folder had no listing, whole folders such as the earlier run's
``radiance/``: :mod:`tlm.storage_carry`). The new run lists what it wrote in its
:data:`~tlm.storage_carry.LISTING`; a file present but not listed there is not its own, and the report reads it
as absent (h477: an earlier 16x16 run's ``radiance/rcast.npy`` rebuilt the image panels of a 24x24 rerun that
wrote no radiance, with no sign of it). :func:`wrote` is the one test of the report's reads of a run's files
(:meth:`tlm.report.collect.Run.wrote`), :func:`kept` what the report then says of such a file, and
:func:`study_cells` the same test of a thesis study's cells by the study's own listing, and :func:`own_runs` of the
run folders a search under a folder finds (``tlm report T/cornell``, ``tlm report X/cases``: a thesis cell or an
extreme case, each a run folder of its own, h486). A folder with no listing (a tlm's older than listings) is read
as it is. Only membership counts: a listed file the user edited in place is read as it is now.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from tlm.storage_carry import LISTING, listed


def names_of(run: Any) -> dict | None:
    """The paths ``run`` (a :class:`~tlm.report.collect.Run`) wrote in its folder (its :data:`LISTING`, read once,
    kept as ``run.listing``: None until then, then a 1-tuple); None where the folder has no listing."""
    if run.listing is None:
        run.listing = (listed(run.path),)
    return run.listing[0]


def wrote(run: Any, rel: str, folder: bool = False) -> Path | None:
    """``run.path / rel`` (``/`` between names) where it is a file (``folder``: a folder) that the run wrote: one
    its listing names, where it has one; else None (gone, another kind, or not the run's)."""
    path = run.path / rel
    if not (path.is_dir() if folder else path.is_file()):
        return None
    names = names_of(run)
    return path if names is None or rel in names else None


def kept(run: Any, rel: str) -> str:
    """What the report says of ``rel`` that it reads as absent (:func:`wrote`): where it is there but not the
    run's, a clause saying so (after the absence the report names); else ""."""
    names = names_of(run)
    if names is None or rel in names or not (run.path / rel).exists():
        return ""
    shown = f"{rel}/" if (run.path / rel).is_dir() else rel  # (a folder as the report names one: radiance/)
    return f" ({shown} is there, but not in the run's {LISTING}: an earlier output's, kept by a rerun, or the user's)"


def study_cells(folder: Path) -> tuple[list[Path], list[str]]:
    """A thesis study's cells (``folder/<scene>/<mode>``, those with a ``results.json``) that the study wrote, and
    a note on each one there that its listing does not name (:func:`left_out`: kept by a rerun, not read); every
    one for a study folder with no listing."""
    names = listed(folder)
    cells, notes = [], []
    for results in sorted(folder.glob("*/*/results.json")):
        cell = results.parent
        rel = f"{cell.parent.name}/{cell.name}/results.json"
        if wrote_run(folder, rel, names):
            cells.append(cell)
        else:
            notes.append(left_out(cell, "a thesis cell", folder))
    return cells, notes


def wrote_run(study: Path, rel: str, names: dict | None) -> bool:
    """Whether the study in ``study``, whose listing is ``names`` (None: it has none), wrote the run file ``rel``
    (``<scene>/<mode>/results.json``): its listing names it, or names it where it was before a rename (:func:`moved`);
    every one of a study with no listing."""
    return names is None or rel in names or moved(study, rel, names)


def moved(study: Path, rel: str, names: dict) -> bool:
    """Whether ``study``'s run file ``rel`` (``<scene>/<mode>/results.json``), which its listing ``names`` does not
    name, is one it wrote in a folder renamed since (by hand: h420): its size and modification time (ns) are those
    the listing gives a run file of the study's that is no longer where it was written. Not a file a rerun kept (an
    earlier study's: its own time), nor one of a listing without stamps."""
    try:
        st = os.stat(study / rel)
    except OSError:
        return False
    stamp = (st.st_size, st.st_mtime_ns)
    return any(was == stamp and name.endswith("/results.json") and not (study / name).exists()
               for name, was in names.items())


def left_out(folder: Path, what: str, study: Path) -> str:
    """The note on the run ``folder`` (``what`` it is: "a thesis cell") that ``study``'s listing does not name."""
    return (f"{folder}: {what} that the study {study} did not write (not in its {LISTING}: an earlier study's, kept "
            "by a rerun, or the user's), left out of this report")


def own_runs(found: list[tuple[Path, str]], said: list[str], named: list[int]) -> list[tuple[Path, str]]:
    """The folders a search found (:func:`tlm.report.folders.find`: each with its kind) but each run folder that
    lies where a study puts its runs (a thesis cell ``<study>/<scene>/<mode>``, an extreme case
    ``<study>/cases/<name>``) and that the study's listing does not name: not its own, as :func:`study_cells`
    leaves one out of a study read whole (h486: ``tlm report T/cornell`` drew a cell that a rerun of the study kept,
    and put it in Table III). ``said`` gets a line on each one left out, ``named`` a 1 each (the search's notes and
    their counts). A study with no listing names every one; a run folder given itself is never searched for."""
    from tlm.config import MODES
    from tlm.report.folders import kind_of

    own, studies = [], {}  # (each study's kind and listing, read once: a search may find thousands of run folders)
    for folder, kind in found:
        at = Path(os.path.abspath(folder))  # (not folder's pure parents: ``tlm report .`` in T/cornell finds ``pmap``)
        study = at.parent.parent
        if kind == "run" and study not in studies:
            of = kind_of(study)
            studies[study] = (of, listed(study) if of in ("thesis", "extreme") else None)
        of, names = studies[study] if kind == "run" else (None, None)
        what = ("a thesis cell" if of == "thesis" and at.name in MODES else
                "an extreme case" if of == "extreme" and at.parent.name == "cases" else None)
        rel = f"{at.parent.name}/{at.name}/results.json"
        if what is not None and not wrote_run(study, rel, names):
            said.append(left_out(folder, what, study))
            named.append(1)
        else:
            own.append((folder, kind))
    return own
