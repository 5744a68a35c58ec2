"""What a write that failed says: the machine's OSError (a full disk, a read-only file system, a
folder that takes no new file) as one line naming the destination (:func:`write_problem`), raised as an
:class:`~tlm.errors.EnvironmentFailure` (:func:`raise_environmental`). Moved out of :mod:`tlm.storage`,
whose writers call them and which imports them from here (``tlm.storage.write_problem`` as before).
"""

from __future__ import annotations

import errno
import os
import re
from pathlib import Path

from tlm.errors import EnvironmentFailure, environment_problem, path_shown


def raise_environmental(e: BaseException, where: Path) -> None:
    """An OSError of the machine's (a full disk) as an EnvironmentFailure naming ``where``."""
    if isinstance(e, EnvironmentFailure) and isinstance(e.__cause__, OSError):
        e = e.__cause__  # a file of the folder: the folder is named instead of its temporary file
    elif isinstance(e, EnvironmentFailure):
        return
    if isinstance(e, OSError):
        what = write_problem(e, where)
        if what is not None:
            raise EnvironmentFailure(f"cannot write: {what}", source=str(where)) from e


def write_problem(e: OSError, where: Path) -> str | None:
    """What the machine's OSError ``e``, met writing ``where``, says in a few words
    (:func:`~tlm.errors.environment_problem`: ``no space left on device``), a folder that is there but takes no
    new file (``/proc``: its ENOENT) included, as one that is read-only is; None where it is not the machine's
    (nor the destination's) fault. That ENOENT is the folder's only where it names a hidden file of ``where``'s
    own beside it (:func:`tlm.storage.write_atomic`'s, :func:`tlm.storage.write_files`'): another (an input the
    block that writes reads, missing; a file of a folder gone meanwhile) is not blamed on the folder."""
    what = environment_problem(e, filename=False)
    if what is None and e.errno == errno.ENOENT and _own_file(e, Path(where)) and Path(where).parent.is_dir():
        what = takes_no_files(Path(where).parent)
    return what


def takes_no_files(folder: Path) -> str:
    """Why a file cannot be made in ``folder``, a folder that is there but whose file system makes no new
    file (``/proc``: ENOENT, as if it were not there): the words of :func:`write_problem` and of an output
    folder's claim there (:func:`tlm.claims.claimed`), the folder named as a line shows a path."""
    return f"{path_shown(folder)} takes no new files (making one there: no such file or directory)"


def _own_file(e: OSError, where: Path) -> bool:
    """Whether ``e`` names one file (no second: not a rename's) that is a hidden file of ``where``'s
    beside it (``.<name>.tmp...``, ``..<name>.new....tmp...``): the file a write of ``where`` makes."""
    if not isinstance(e.filename, (str, os.PathLike)) or e.filename2 is not None:
        return False
    made = Path(e.filename)
    return made.parent == where.parent and made.name.startswith(".") and where.name in made.name


FULL_DISK = ("no space left on device", "disk quota exceeded")  # (ENOSPC's, EDQUOT's words; numpy's short write's)
# the words as a line ends with them (``: WORDS``, ``(WORDS)``, numpy's ``WORDS?``), a worker's `` (on ...)`` aside;
# a bare OSError's by its errno (``[Errno 28] No space left on device: 'PATH'``): never a path's words
_FULL_AT_END = re.compile(rf"(?:^|: |\()(?:{'|'.join(FULL_DISK)})[)?]?$")
_FULL_ERRNOS = "|".join(str(getattr(errno, n)) for n in ("ENOSPC", "EDQUOT") if hasattr(errno, n))
_FULL_ERRNO = re.compile(rf"\[errno (?:{_FULL_ERRNOS})\]")


def says_disk_full(kind: str, message: str) -> bool:
    """Whether an error of the type named ``kind`` saying ``message`` (a sweep point's record, as its worker
    wrote it: ``EnvironmentFailure``, ``PATH: cannot write: no space left on device``) is a full disk or quota:
    :data:`FULL_DISK`'s words, as :func:`~tlm.errors.environment_problem` gives them, ending an
    EnvironmentFailure's line, or a bare OSError's errno. A path that holds the words (an output folder named
    ``no space left on device``, its point's ``file too large``) is none. No point after such a one can write its
    folder either (the sweep stops on it)."""
    text = re.sub(r" \(on [^()]*\)$", "", str(message)).lower()  # (the worker the point ran on: sweep_point)
    if kind == "OSError":
        return _FULL_ERRNO.match(text) is not None
    return kind == "EnvironmentFailure" and _FULL_AT_END.search(text) is not None
