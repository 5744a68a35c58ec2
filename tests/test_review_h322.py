"""h322 (review of 746018c): the OBJ reader's fast path dropped a face corner of slashes alone (``f 1 2 // 3``
read as the triangle 1 2 3) that the per-line reader refuses, so that a file loaded or not by an unrelated line
of its block (a comment sent the block to the per-line reader); ``tlm sweep``'s lines of its points' warnings
said one warning whose numbers differ per point (the stream's settling, ``moved by 0.14%``) as a line per point,
five of them, and hid the other warnings behind ``and K more``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tlm.cli_tables import print_point_warnings
from tlm.errors import InputError
from tlm.scenes.objfile import parse_obj

QUAD = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 1\n"  # lines 1-5


@pytest.mark.parametrize(("face", "corner"), [
    ("f 1 2 // 3", "//"),
    ("f 1 2 / 3", "/"),
    ("f 1 2 3 //", "//"),
    ("f 1//1 2//1 3//1 //", "//"),
])
def test_a_corner_of_slashes_alone_is_refused_by_either_reader(face, corner):
    for after in (b"", b"f 1 2 3 # a comment: the block read line by line\n"):
        with pytest.raises(InputError) as e:
            parse_obj(QUAD + b"f 1 2 3\n" + face.encode() + b"\n" + after, "q.obj", "q")
        assert str(e.value) == f"q.obj: line 7: cannot read the face corner '{corner}'"
    assert parse_obj(QUAD + b"f 1/ 2// 3/\n", "q.obj", "q").faces.tolist() == [[0, 1, 2]]  # (a slash after one: read)


def test_a_warning_whose_numbers_differ_per_point_is_one_line(tmp_path, capsys):
    rows = []
    for i in range(200):
        lines = [f"the stream did not settle within 64 frames: its running mean moved by {i / 7:.2f}% over "
                 f"its last {10 + i % 40} completions"]
        if i == 150:
            lines.append("1 material of the mesh file ('floor') uses what tlm does not render: map_Kd")
        folder = tmp_path / "points" / f"h{i}"
        folder.mkdir(parents=True)
        (folder / "results.json").write_text(json.dumps({"warnings": lines}))
        rows.append({"point": i, "hash": f"h{i}", "status": "ok"})
    print_point_warnings(rows, Path(tmp_path), [])
    assert capsys.readouterr().err.splitlines() == [
        "tlm: warning: 200 of 200 points (in 200 wordings that differ in their numbers; the first met): the stream "
        "did not settle within 64 frames: its running mean moved by 0.00% over its last 10 completions",
        "tlm: warning: 1 of 200 points: 1 material of the mesh file ('floor') uses what tlm does not render: map_Kd",
    ]
