"""Which files of a run folder its run wrote: the report reads those alone.

A rerun into a run folder keeps what the new run does not write there of the earlier one's (the user's files, a
file the user edited since, and, where the folder had no listing, whole folders such as the earlier run's
``radiance/``: :mod:`tlm.storage_carry`). The new run lists what it wrote in its
:data:`~tlm.storage_carry.LISTING`; a file present but not listed there is not its own, and the report reads it
as absent (h477: an earlier 16x16 run's ``radiance/rcast.npy`` rebuilt the image panels of a 24x24 rerun that
wrote no radiance, with no sign of it). :func:`wrote` is the one test of the report's reads of a run's files
(:meth:`tlm.report.collect.Run.wrote`), :func:`kept` what the report then says of such a file, and
:func:`study_cells` the same test of a thesis study's cells by the study's own listing. A folder with no listing
(a tlm's older than listings) is read as it is. Only membership counts: a listed file the user edited in place
is read as it is now.
"""

from __future__ import annotations

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
    return (f" ({rel} is there, but not in the run's {LISTING}: kept by a rerun from an earlier output or the user, "
            "not this run's, so not read)")


def study_cells(folder: Path) -> tuple[list[Path], list[str]]:
    """A thesis study's cells (``folder/<scene>/<mode>``, those with a ``results.json``) that the study wrote, and
    a note on each one there that its listing does not name (kept by a rerun into the folder: not read); every
    one for a study folder with no listing."""
    names = listed(folder)
    cells, notes = [], []
    for results in sorted(folder.glob("*/*/results.json")):
        cell = results.parent
        rel = f"{cell.parent.name}/{cell.name}/results.json"
        if names is None or rel in names:
            cells.append(cell)
        else:
            notes.append(f"{cell}: a thesis cell the study {folder} did not write (not in its {LISTING}: kept by a "
                         "rerun into the folder from an earlier study), left out of this report")
    return cells, notes
