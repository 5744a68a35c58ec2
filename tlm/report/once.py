"""The files of a report's inputs that several of its steps read, each read once per report.

A scaling study's sweep (its ``sweep.yaml`` and ``sweep.jsonl``) is read as an input
(:func:`tlm.report.collect.read`), and again by each check of whether the study's fit still shows
the sweep as it is now (:func:`tlm.experiments.scaling_dated.sweep_points`: §3's fits and notes, the
summary's "Does it scale"): six reads of each file a report. :class:`Reads` keeps what one report
read, by the file's resolved path and its stat (a file replaced or written to meanwhile is read
again, its modification time set back too: ``cp -p``, ``rsync -a --inplace``, ``touch -r``), on that
report's :class:`~tlm.report.collect.Inputs`; its sections and summary read through it too
(:func:`reading`). Nothing of it outlives the report (:func:`tlm.api.write_report`, called
from a notebook, reads the files again the next time).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from tlm.report.checks import read_yaml
from tlm.storage import read_jsonl


class Reads:
    """A report's reads of its inputs' ``.yaml`` and ``.jsonl`` files (called with the file's path: its data,
    read as the report reads it, :func:`~tlm.report.checks.read_yaml` or :func:`~tlm.storage.read_jsonl`, with
    their errors), each read once while the file stays as it was. The data is shared: its readers do not
    change it."""

    def __init__(self) -> None:
        self._read: dict[tuple, Any] = {}

    def __call__(self, path: Path) -> Any:
        path = Path(path)
        load = read_jsonl if path.suffix == ".jsonl" else read_yaml
        try:
            st = path.stat()
        except OSError:  # (read as it would be: its error, nothing kept)
            return load(path)
        # (its ctime too: the kernel's, which a write sets and no one sets back, where the mtime can be: os.utime)
        key = (str(path.resolve()), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
        if key not in self._read:
            self._read[key] = load(path)
        return self._read[key]


@contextlib.contextmanager
def reading(reads: Reads) -> Iterator[None]:
    """Within it (in this thread), a sweep's files that :func:`tlm.experiments.scaling_dated.sweep_points` reads
    are read by ``reads`` (:data:`tlm.experiments.scaling.SWEEP_READ`), as it was before at its end."""
    from tlm.experiments.scaling import SWEEP_READ

    token = SWEEP_READ.set(reads)
    try:
        yield
    finally:
        SWEEP_READ.reset(token)
