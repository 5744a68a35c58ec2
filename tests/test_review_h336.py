"""h336, review of 425be40: an OBJ statement continued by a backslash reads alike whatever the file's line ends
(LF, CRLF, a CR alone), as the docs say of line ends: the backslash and its line end are one blank, so a name
continued over lines (``o``, ``g``, ``usemtl``, ``mtllib``) is the same name in a file saved with CRLF (where the
backslash and the CR and LF were three blanks, against two for LF: ``my   box`` and ``my    box``)."""

from __future__ import annotations

import random

import numpy as np
import pytest

from tlm.errors import InputError
from tlm.scenes import objfile
from tlm.scenes.objfile import parse_obj

FIELDS = ("vertices", "faces", "face_line", "vertex_normals", "corner_normals", "part", "part_names", "material",
          "material_names", "material_lines", "mtllibs", "colour_lines")
ENDS = ("\n", "\r\n", "\r")


def _read(data: bytes):
    try:
        return parse_obj(data, "m.obj", "m")
    except InputError as e:
        return str(e)


def _same(got, want) -> None:
    if isinstance(got, str) or isinstance(want, str):
        assert got == want
        return
    for field in FIELDS:
        a, b = getattr(got, field), getattr(want, field)
        if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=field)
        else:
            assert a == b, field


@pytest.mark.parametrize("end", ENDS)
def test_a_name_continued_over_lines_is_one_name_whatever_the_line_ends(end):
    text = ("mtllib my \\\nlib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\no my \\\nbox\nusemtl red\\\n wine\nf 1 \\\n2 3\n"
            "g a\\\n\\\nb\nf 1 2 3\n")
    got = parse_obj(text.replace("\n", end).encode(), "m.obj", "m")
    assert got.part_names == ("my  box",)  # (the o's: one blank for the backslash and its line end)
    assert got.material_names == ("red  wine",)
    assert got.mtllibs == (("my  lib.mtl", 1),)
    assert got.face_line.tolist() == [10, 15] and got.part.tolist() == [0, 0]


def _statements(rng: random.Random) -> list[str]:
    out = [f"v {rng.uniform(-1, 1):.3f} {rng.uniform(-1, 1):.3f} {rng.uniform(-1, 1):.3f}" for _ in range(5)]
    out += ["vn 0 0 1", "vn 0 1 0"]
    for _ in range(rng.randint(2, 5)):
        out.append(rng.choice(["o my box", "g part a", "usemtl red wine", "mtllib a b.mtl", "# a note", "s 1"]))
        corners = rng.sample(range(1, 6), rng.randint(3, 5))
        form = rng.choice(["{v}", "{v}//{n}", "{v}/{v}/{n}"])
        out.append("f " + " ".join(form.format(v=c, n=rng.randint(1, 2)) for c in corners))
    return out


def _continued(statements: list[str], rng: random.Random) -> list[str]:
    lines = []
    for s in statements:
        words = s.split(" ")
        while len(words) > 1 and rng.random() < 0.5:
            k = rng.randint(1, len(words) - 1)
            lines.append(" ".join(words[:k]) + rng.choice([" \\", "\\", "\t\\"]))
            words = words[k:]
        lines.append(" ".join(words))
    return lines


def test_continued_files_read_alike_with_every_line_end_in_both_readers(monkeypatch):
    rng = random.Random(336)
    for _ in range(60):
        lines = _continued(_statements(rng), rng)
        want = _read(("\n".join(lines) + "\n").encode())
        assert not isinstance(want, str), want
        mixed = "".join(line + rng.choice(ENDS) for line in lines)
        for data in [*((end.join(lines) + end).encode() for end in ENDS), mixed.encode()]:
            _same(_read(data), want)
    with monkeypatch.context() as m:  # (the per-line reader: every block sent through it)
        m.setattr(objfile, "_vectors_fast", lambda *a: None)
        m.setattr(objfile, "_corners_fast", lambda *a: None)
        rng = random.Random(336)
        for _ in range(20):
            lines = _continued(_statements(rng), rng)
            want = _read(("\n".join(lines) + "\n").encode())
            assert not isinstance(want, str), want
            _same(_read(("\r\n".join(lines) + "\r\n").encode()), want)
