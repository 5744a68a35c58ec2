"""What a rerun into an output's folder keeps of its user's (out of :mod:`tlm.storage`, whose
:func:`~tlm.storage.atomic_folder` calls it under the folder's lock, before the swap).

An output that keeps what its user put in its folder (a run's, a study's: ``owned``, the names it may hold) lists
every path it wrote there in :data:`LISTING` (:func:`write_listing`, where it holds a folder). A rerun moves into
its new folder, at the same path, each entry of the old folder that is the user's (:func:`carry_over`): one of a
name the output does not own (notes, an analysis folder), and, inside its folders, one the old listing does not
name (``images/my_annotated.png``), in a folder the old output wrote or not (one a user made, one an earlier carry
made). What the old listing names is the output's (removed with the old folder, or replaced); an owned file
(``results.json``) is the output's; :data:`WHOLE` (``report``, which ``tlm report`` writes after the run) is
replaced whole; an old folder with no listing (a tlm older than it) has its owned folders replaced whole.

The listing decides membership only: the paths moved are those of the folder's own entries (``os.listdir``),
never one the listing names, so a damaged or edited listing (``../x``, ``/etc``) moves or removes nothing outside
the folder; a link is moved as a link, never followed, on either side. A path of the user's that the new output
writes itself (the same name, a file where the user's folder was, or the reverse) is the new output's: it is
noted (``lost``) and said once the new folder took the old one's place (:func:`lost_line`).
"""

from __future__ import annotations

import os
import re
import stat
from collections.abc import Callable, Collection
from pathlib import Path

from tlm.errors import quoted

LISTING = ".tlm-written"  # the paths an output wrote in its folder (write_listing), where it holds a folder
# the folders of an output's own names that another writer puts there after it (a run's or a study's report, by
# ``tlm report``): not the output's, not the user's; replaced whole by a rerun unless the listing names them
WHOLE = frozenset({"report"})
OURS = re.compile(r"\..+\.(tmp|old)-")  # the temporary folders tlm's writers leave while they work
SHOWN = 5  # the paths a lost_line names (and how many more)


def write_listing(tmp: Path, write: Callable[[Path, bytes], None]) -> None:
    """Record every path the finished output ``tmp`` holds (its folders' too, relative, ``/`` between names, one
    a line, as the file system names it: bytes) in its :data:`LISTING`, written by ``write`` (an atomic write),
    where it holds a folder (a run's ``images``): what a rerun into its folder tells from the user's files put in
    those folders (:func:`carry_over`). A name with a newline is left out (its file counts as the user's: kept,
    never removed by mistake). One walk of the folder, no stat of a file."""
    with os.scandir(tmp) as listing:
        if not any(e.is_dir(follow_symlinks=False) for e in listing):
            return
    top = os.fsencode(tmp)
    sep = os.fsencode(os.sep)
    lines = []
    for root, dirs, files in os.walk(top):
        rel = root[len(top) + 1:].replace(sep, b"/")
        lines.extend((rel + b"/" + n if rel else n) + b"\n" for n in (*dirs, *files) if b"\n" not in n)
    own = os.fsencode(LISTING) + b"\n"
    write(tmp / LISTING, b"".join(sorted(p for p in lines if p != own)))


def listed(out: Path) -> set[str] | None:
    """The paths the output in ``out`` wrote there (its :data:`LISTING`); None where it has none (or it cannot
    be read: not a file)."""
    try:
        return {os.fsdecode(p) for p in (out / LISTING).read_bytes().split(b"\n") if p}
    except OSError:
        return None


def real_dir(path: Path) -> bool:
    """Whether ``path`` is a folder, not a link to one (False where it is gone)."""
    try:
        return stat.S_ISDIR(os.lstat(path).st_mode)
    except OSError:
        return False


def carry_over(out: Path, tmp: Path, owned: Collection[str], moved: list[str], lost: list[str]) -> None:
    """Move the user's entries of the old output's folder ``out`` to the same paths in the new output's ``tmp``
    (the module's docstring). ``moved`` gets each path moved (relative to ``out``, ``/`` between names) as it is,
    so that an error or a signal at any point finds every one of them (:func:`put_back`); ``lost`` each path of
    the user's that the new output's own takes (not moved: removed with the old folder)."""
    try:
        entries = sorted(os.listdir(out))
    except OSError:
        return
    names = listed(out)
    for name in entries:
        if name == LISTING or OURS.match(name):
            continue
        if name in owned and (names is None or not real_dir(out / name) or (name in WHOLE and name not in names)):
            continue  # (an owned file; an older tlm's folder; a report's: the output's, replaced)
        _carry(out, tmp, name, names or set(), moved, lost)


def _carry(out: Path, tmp: Path, path: str, names: set[str], moved: list[str], lost: list[str]) -> None:
    """Carry ``out/path`` to ``tmp/path`` where it is the user's (not in ``names``, the old listing) and ``tmp``
    has nothing on its way; look into it where it is a folder that the old output wrote, or one that both hold."""
    src, dst = out / path, tmp / path
    if path in names or os.path.lexists(dst):
        if real_dir(src) and (path in names or real_dir(dst)):
            for name in sorted(os.listdir(src)):
                _carry(out, tmp, f"{path}/{name}", names, moved, lost)
        elif path not in names:
            lost.append(path)  # (the user's, where the new output writes a path of that name)
        return
    if not _way_clear(tmp, path):
        lost.append(path)
        return
    dst.parent.mkdir(parents=True, exist_ok=True)
    try:
        src.rename(dst)
    except FileNotFoundError:
        if os.path.lexists(src):
            raise
        return  # (gone meanwhile: nothing to keep)
    moved.append(path)


def _way_clear(tmp: Path, path: str) -> bool:
    """Whether each folder on the way to ``tmp/path`` is one, or is not there yet (then made): not a file, nor a
    link, which would take the user's entry elsewhere."""
    way = os.fspath(tmp)
    for name in path.split("/")[:-1]:
        way = os.path.join(way, name)
        try:
            if not stat.S_ISDIR(os.lstat(way).st_mode):
                return False
        except FileNotFoundError:
            return True
    return True


def put_back(tmp: Path, out: Path, moved: list[str]) -> list[str]:
    """Move the paths ``moved`` (:func:`carry_over`'s) from ``tmp`` back to ``out``, the last first, each taken
    off ``moved`` once it is back: a signal meanwhile leaves ``moved`` naming every one still in ``tmp``. Those
    that cannot be moved back stay in ``tmp`` and on ``moved``, which is returned: the caller keeps ``tmp``."""
    i = len(moved)
    while i:
        i -= 1
        try:
            (tmp / moved[i]).rename(out / moved[i])
        except OSError:
            if os.path.lexists(tmp / moved[i]):
                continue
        del moved[i]
    return list(moved)


def lost_line(out: Path, lost: list[str]) -> str:
    """The warning on the user's paths that a new output's own took in ``out`` (:func:`carry_over`'s ``lost``)."""
    shown = ", ".join(map(quoted, lost[:SHOWN])) + (f" and {len(lost) - SHOWN} more" if len(lost) > SHOWN else "")
    return (f"{out}: {shown} (not written by the earlier output: yours) "
            f"{'was' if len(lost) == 1 else 'were'} replaced by this output's own of the same path")
