"""What a rerun into an output's folder keeps of its user's (out of :mod:`tlm.storage`, whose
:func:`~tlm.storage.atomic_folder` calls it under the folder's lock, before the swap).

An output that keeps what its user put in its folder (a run's, a study's: ``owned``, the names it may hold) lists
every path it wrote there in :data:`LISTING` (:func:`write_listing`, where it holds a folder), each file's with
its size and modification time. A rerun moves into its new folder, at the same path, each entry of the old folder
that is the user's (:func:`carry_over`): one of a name the output does not own (notes, an analysis folder); inside
its folders, one the old listing does not name (``images/my_annotated.png``), in a folder the old output wrote or
not (one a user made, one an earlier carry made); and a file the old output wrote that is no longer as written
(another size or modification time: an annotated ``images/pmap.png``, a hand-edited ``results.json``), at the
top too; in a folder copied without its times (no listed file has its time: :func:`untimed`), another size.
What the old listing names as written is the output's (removed with the old folder, or replaced); :data:`WHOLE`
(``report``, which ``tlm report`` writes after the run) is replaced whole. A listing of paths alone (a tlm's
before sizes and times were listed) tells no edited file, and an owned file at the top is the output's, listed or
not, as it was. An old folder with no listing (deleted; a tlm's older than listings) tells nothing of
its folders: what the new output writes there is the output's, unsaid; the rest of them is kept (a folder the
new output does not write at all, whole), and a warning names it (:func:`unlisted_line`: some may be an earlier
output's, such as the AOVs of a run that wrote them, for the user to remove, which a report leaves out as
not listed, :mod:`tlm.report.written`; none is removed as one); an owned file at the top is the output's.

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
# a file's line of a listing: its path, size and modification time (ns), a tab before each; a folder's is its path
_FILE_LINE = re.compile(rb"(.+)\t([0-9]+)\t(-?[0-9]+)", re.DOTALL)

Stamp = tuple[int, int | None]  # a file's size and modification time (ns) as listed (None: not compared, untimed)


def write_listing(tmp: Path, write: Callable[[Path, bytes], None]) -> None:
    """Record every path the finished output ``tmp`` holds (its folders' too, relative, ``/`` between names, one
    a line, as the file system names it: bytes; a file's with its size and modification time in ns, a tab before
    each: :data:`_FILE_LINE`) in its :data:`LISTING`, written by ``write`` (an atomic write), where it holds a
    folder (a run's ``images``): what a rerun into its folder tells from the user's files put in those folders,
    and the files the user edited since (:func:`carry_over`). A name with a newline or a tab is left out (its file
    or folder counts as the user's: kept, never removed by mistake). One walk of the folder, one ``lstat`` of a
    file (a link's own)."""
    with os.scandir(tmp) as listing:
        if not any(e.is_dir(follow_symlinks=False) for e in listing):
            return
    lines: list[bytes] = []
    folders = [b""]
    while folders:
        rel = folders.pop()
        with os.scandir(os.path.join(os.fsencode(tmp), rel) if rel else os.fsencode(tmp)) as entries:
            for e in entries:
                if b"\n" in e.name or b"\t" in e.name or (not rel and e.name == os.fsencode(LISTING)):
                    continue
                path = rel + b"/" + e.name if rel else e.name
                if e.is_dir(follow_symlinks=False):
                    folders.append(path)
                    lines.append(path + b"\n")
                else:
                    st = e.stat(follow_symlinks=False)
                    lines.append(b"%s\t%d\t%d\n" % (path, st.st_size, st.st_mtime_ns))
    write(tmp / LISTING, b"".join(sorted(lines)))


def listed(out: Path) -> dict[str, Stamp | None] | None:
    """The paths the output in ``out`` wrote there (its :data:`LISTING`), each a file's :data:`Stamp` as written
    (None: a folder's, or any path of a listing of paths alone, a tlm's before stamps); None where it has none
    (or it cannot be read: not a file)."""
    try:
        text = (out / LISTING).read_bytes()
    except OSError:
        return None
    names: dict[str, Stamp | None] = {}
    for line in text.split(b"\n"):
        if line:
            file = _FILE_LINE.fullmatch(line)
            names[os.fsdecode(file[1] if file else line)] = (int(file[2]), int(file[3])) if file else None
    return names


def changed(path: Path, stamp: Stamp | None) -> bool:
    """Whether the file at ``path`` that its output listed with ``stamp`` is no longer as written: another size or
    modification time (where the stamp gives one: :func:`untimed`), or a folder now (the user's, then). A folder's
    path, one listed with no stamp, or one gone: False."""
    if stamp is None:
        return False
    try:
        st = os.lstat(path)
    except OSError:
        return False
    return stat.S_ISDIR(st.st_mode) or st.st_size != stamp[0] or stamp[1] not in (None, st.st_mtime_ns)


def untimed(out: Path, names: dict[str, Stamp | None]) -> dict[str, Stamp | None]:
    """``names`` (``out``'s listing) with no file's time to compare where no file it lists that is still there has
    its listed time: a folder copied without its times (``cp -r``, an archive's, a file system of coarser times),
    every file of it "changed". Its files are then told by their sizes alone (an edit of the same size is not told);
    else ``names`` as they are. An ``lstat`` of each listed file, until one has its time."""
    there = False
    for path, stamp in names.items():
        if stamp is not None:
            try:
                st = os.lstat(out / path)
            except OSError:
                continue
            if st.st_mtime_ns == stamp[1]:
                return names
            there = True
    if not there:
        return names
    return {path: None if stamp is None else (stamp[0], None) for path, stamp in names.items()}


def real_dir(path: Path) -> bool:
    """Whether ``path`` is a folder, not a link to one (False where it is gone)."""
    try:
        return stat.S_ISDIR(os.lstat(path).st_mode)
    except OSError:
        return False


def carry_over(out: Path, tmp: Path, owned: Collection[str], moved: list[str], lost: list[str]) -> list[str]:
    """Move the user's entries of the old output's folder ``out`` to the same paths in the new output's ``tmp``
    (the module's docstring). ``moved`` gets each path moved (relative to ``out``, ``/`` between names) as it is,
    so that an error or a signal at any point finds every one of them (:func:`put_back`); ``lost`` each path of
    the user's that the new output's own takes (not moved: removed with the old folder). Returned: the paths
    moved out of the output's own folders of an ``out`` with no listing (:func:`unlisted_line`)."""
    try:
        entries = sorted(os.listdir(out))
    except OSError:
        return []
    names = listed(out)
    stamped = names is not None and any(names.values())  # (a listing of stamps, not of paths alone: a tlm's before)
    if names is not None and stamped:
        names = untimed(out, names)
    unlisted: list[str] = []
    for name in entries:
        if name == LISTING or OURS.match(name):
            continue
        if name in owned:
            if not real_dir(out / name):
                if names is None or not stamped or (name in names and not changed(out / name, names[name])):
                    continue  # (an owned file as the output wrote it, or with no listing of stamps: the output's)
            elif name in WHOLE and (names is None or name not in names):
                continue  # (a report's: replaced whole)
            elif names is None:  # (a folder of an output with no listing: the new output's paths are its own;
                first = len(moved)  # one it does not write at all is kept whole, and named so)
                _carry(out, tmp, name, {name: None} if real_dir(tmp / name) else {}, moved, [])
                unlisted.extend(moved[first:])
                continue
        _carry(out, tmp, name, names or {}, moved, lost)
    return unlisted


def _carry(out: Path, tmp: Path, path: str, names: dict[str, Stamp | None], moved: list[str],
           lost: list[str]) -> None:
    """Carry ``out/path`` to ``tmp/path`` where it is the user's (not in ``names``, the old listing, or changed
    since: :func:`changed`) and ``tmp`` has nothing on its way; look into it where it is a folder that the old
    output wrote, or one that both hold."""
    src, dst = out / path, tmp / path
    ours = path in names and not changed(src, names[path])
    if ours or os.path.lexists(dst):
        if real_dir(src) and (ours or real_dir(dst)):
            for name in sorted(os.listdir(src)):
                _carry(out, tmp, f"{path}/{name}", names, moved, lost)
        elif not ours:
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
    from tlm.config_words import listing  # (here: tlm.storage, which imports this module, imports no YAML)

    return (f"{out}: {listing(map(quoted, lost), named=SHOWN)} (yours: not written by the earlier output, or "
            f"changed since) {'was' if len(lost) == 1 else 'were'} replaced by this output's own of the same path")


def unlisted_line(out: Path, kept: list[str]) -> str:
    """The warning on the paths kept from the output's own folders of an ``out`` with no listing
    (:func:`carry_over`'s return)."""
    from tlm.config_words import listing

    return (f"{out} has no {LISTING} (deleted, or written by a tlm older than it), which tells tlm's files from "
            f"yours: {listing(map(quoted, kept), named=SHOWN)}, which this output does not write, "
            f"{'was' if len(kept) == 1 else 'were'} kept as yours (remove any an earlier output wrote: it is not "
            f"this output's; a report leaves out what the output's listing does not name)")
