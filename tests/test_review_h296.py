"""h296 (review of f710d48, a report reads each sweep file once: :class:`tlm.report.once.Reads`).

A file written in place meanwhile, at the same size, whose modification time was then set back (``cp -p`` or
``rsync -a --inplace`` of another copy over it, ``touch -r``: ``os.utime``) kept the same key (path, device,
inode, size, mtime): the report used what it read before, not the file as it is. The key holds the file's
ctime too, which the kernel sets on every write and nothing sets back.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from tlm.experiments.scaling import sweep_points
from tlm.report.once import Reads, reading


def _rewrite_keeping_mtime(path: Path, text: str) -> None:
    """``text`` over ``path`` in place (the same inode, the same size), its times set back as they were."""
    st = path.stat()
    assert len(text.encode()) == st.st_size
    with open(path, "r+", encoding="utf-8") as f:
        f.write(text)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert (path.stat().st_size, path.stat().st_mtime_ns, path.stat().st_ino) == (st.st_size, st.st_mtime_ns,
                                                                                st.st_ino)


def test_reads_reads_again_a_file_written_in_place_with_its_mtime_set_back(tmp_path):
    path = tmp_path / "sweep.yaml"
    path.write_text("points: [{hash: aaa}]\n")
    reads = Reads()
    assert reads(path) == {"points": [{"hash": "aaa"}]}
    _rewrite_keeping_mtime(path, "points: [{hash: bbb}]\n")
    assert reads(path) == {"points": [{"hash": "bbb"}]}  # (was the first read's: aaa)


def test_sweep_points_in_a_report_sees_a_row_rewritten_with_its_mtime_set_back(tmp_path):
    """What a scaling study's check of its sweep reads in a report (:func:`reading`): a point no longer ok."""
    sweep = tmp_path / "sweep"
    (sweep / "points" / "aaa").mkdir(parents=True)
    (sweep / "points" / "aaa" / "results.json").write_text("{}")
    (sweep / "sweep.yaml").write_text("points: [{hash: aaa}]\n")
    (sweep / "sweep.jsonl").write_text(json.dumps({"hash": "aaa", "status": "ok"}) + "\n")
    with reading(Reads()):
        assert sweep_points(sweep) == (["aaa"], ["aaa"])
        _rewrite_keeping_mtime(sweep / "sweep.jsonl", json.dumps({"hash": "aaa", "status": "no"}) + "\n")
        assert sweep_points(sweep) == (["aaa"], [])  # (was (['aaa'], ['aaa']): the row read before)
