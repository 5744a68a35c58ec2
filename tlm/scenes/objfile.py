"""A fast Wavefront OBJ reader: numpy over the file's bytes, no Python loop per line.

:func:`read_obj` reads the statements a renderer needs and ignores the rest:

* ``v x y z [w | r g b]`` positions (the first three numbers), ``vn`` normals (a unit
  one read as written: :func:`unit_as_written`);
  ``vt``, ``vp``, ``s``, ``l``, ``p``, comments and any unknown statement are skipped;
* ``f`` faces with every corner form (``i``, ``i/j``, ``i//k``, ``i/j/k``), 1-based or
  negative (relative: ``-1`` is the last vertex defined above the face) indices;
  a polygon of k corners becomes k - 2 triangles fanned from its first corner
  ``(0, i, i + 1)``, in file order;
* ``o`` objects and ``g`` groups (the name is the rest of the line), ``usemtl`` and
  ``mtllib`` (a library's name may hold spaces: the whole rest of the line when that is
  one file, otherwise its words).

A line that ends with a backslash continues on the next (the spec's long lines; joined before any
other reading, a comment's too: :func:`_joined`), each line keeping its number; a CR alone ends a
line as a newline does.

How it is fast: the line starts come from one ``np.flatnonzero`` over the bytes, a line's
statement from its first two or three bytes, and the ``v``/``vn``/``f`` lines (gathered
in runs of consecutive lines, which is how files hold them) are parsed in one
``np.fromstring`` call each. In a face line, a number that follows a ``/`` continues
its corner, and its slot (vertex, texture or normal index) grows by the number of
slashes since the previous number (``i//k``: two). A line that the fast path cannot
read (an inline comment, a stray character) sends its block through a per-line Python
reader, which either reads it or raises an :class:`~tlm.errors.InputError` naming the
line.

Compressed files (``.gz``, ``.xz``, ``.bz2``) are decompressed by :func:`read_bytes`.
"""

from __future__ import annotations

import bz2
import functools
import gzip
import hashlib
import lzma
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tlm.config import note_read
from tlm.errors import InputError

__all__ = ["COMPRESSED_SUFFIXES", "ObjData", "colour_notes", "parse_obj", "read_bytes", "read_obj", "unit_as_written",
           "unit_preimage"]

COMPRESSED_SUFFIXES = {".gz": gzip.decompress, ".xz": lzma.decompress, ".bz2": bz2.decompress}


@dataclass(frozen=True)
class ObjData:
    """What an OBJ file holds, triangulated.

    vertices : (nv, 3) float64, every ``v`` of the file in order.
    faces : (t, 3) int64 0-based indices into ``vertices``.
    face_line : (t,) int64 the 1-based line number of each triangle's ``f`` statement.
    vertex_normals : (nn, 3) float64, every ``vn`` (a unit one so that normalizing it
        gives it back as written: :func:`unit_as_written`).
    corner_normals : (t, 3) int64 0-based indices into ``vertex_normals``; None unless
        every corner of every face gives one.
    part : (t,) int32 into ``part_names``: the ``o`` object of each face when the file
        has any ``o``, else its ``g`` group, else one part named ``stem``; a face above
        the first ``o`` (``g``), or one under a nameless one, gets ``stem``; parts with
        the same name are one part; parts are in the order of their first face.
    material : (t,) int32 into ``material_names`` (the ``usemtl`` in force, in the order
        of their first use by a face), -1 for faces above the first ``usemtl``.
    material_lines : the line number of each material name's first ``usemtl``.
    mtllibs : ``(file name, line number)`` of every library ``mtllib`` names.
    colour_lines : ``(count, first line)`` of the ``v`` statements that give a vertex
        colour (``v x y z r g b``: six numbers or more), ``(0, 0)`` when none does;
        :func:`colour_notes` says that they are not rendered.
    """

    vertices: np.ndarray
    faces: np.ndarray
    face_line: np.ndarray
    vertex_normals: np.ndarray
    corner_normals: np.ndarray | None
    part: np.ndarray
    part_names: tuple[str, ...]
    material: np.ndarray
    material_names: tuple[str, ...]
    material_lines: tuple[int, ...]
    mtllibs: tuple[tuple[str, int], ...]
    colour_lines: tuple[int, int] = (0, 0)  # (how many v lines give a colour, the first one's number)


def read_bytes(path: Path, side: bool = False) -> bytes:
    """The file's bytes, decompressed when its suffix is ``.gz``, ``.xz`` or ``.bz2``. ``side``: a file
    a mesh's parse reads beside the mesh (an OBJ's material library), whose read is noted inside
    :func:`tlm.config.noting_reads` as ``("side", path, sha256 of the bytes read)``: what the parse
    read, which what remembers the parse checks the file by (not its digest taken after the parse,
    which an edit saved meanwhile changes: :func:`tlm.scenes.cache.read_as`)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read the file ({exc.strerror or exc})", source=str(path)) from None
    if side:
        note_read(("side", str(path), hashlib.sha256(data).hexdigest(), len(data)))
    unzip = COMPRESSED_SUFFIXES.get(path.suffix.lower())
    if unzip is not None:
        try:
            data = unzip(data)
        except Exception as exc:  # OSError, lzma.LZMAError, EOFError, ValueError
            text = " ".join(str(exc).split()) or type(exc).__name__
            raise InputError(f"cannot decompress the {path.suffix} file ({text})", source=str(path)) from None
    return data


def read_obj(path: Path, stem: str | None = None) -> ObjData:
    """Read an OBJ file (plain or compressed); ``stem`` names the single part of a file
    without ``o``/``g`` (default: the file name without its suffixes)."""
    path = Path(path)
    if stem is None:
        stem = Path(path.stem).stem if path.suffix.lower() in COMPRESSED_SUFFIXES else path.stem
    return parse_obj(read_bytes(path), str(path), stem)


_PHI = (5 ** 0.5 - 1) / 2  # (scales 2 ** frac(k phi): spread evenly over [1, 2), the same on every run)


def _unit(v: np.ndarray) -> np.ndarray:
    """``v`` over its length, as tlm's mesh reading normalizes a file's normals
    (``tlm.scenes.meshes``: OBJ, PLY and glTF alike), zero vectors kept."""
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, length, out=np.zeros_like(v), where=length > 0)


@functools.cache
def _scales() -> np.ndarray:
    """The scales :func:`unit_preimage` tries, in order: 2 ** frac(k phi) for k = 1 .. 4096 + 2 ** 16
    (the first 4096 by Python's float power, the rest by numpy's over an array: bit for bit the
    scales of the first, one-scale-at-a-time search, whose results an exported file holds)."""
    first = np.array([2.0 ** ((k * _PHI) % 1.0) for k in range(1, 4097)])
    scales = np.concatenate([first, 2.0 ** ((np.arange(4097, 4097 + (1 << 16)) * _PHI) % 1.0)])
    scales.flags.writeable = False
    return scales


def _gives_back(cx: np.ndarray, cy: np.ndarray, cz: np.ndarray, n: tuple[np.ndarray, ...]) -> np.ndarray:
    """Where the vector ``(cx, cy, cz)`` normalizes (:func:`_unit`, bit for bit: its length is
    ``sqrt((x x + y y) + z z)``, as ``np.linalg.norm`` sums, and one of length 0 or NaN becomes 0)
    to ``n`` (its components, broadcast against ``cx``)."""
    length = cx * cx
    t = cy * cy
    length += t
    np.multiply(cz, cz, out=t)
    length += t
    np.sqrt(length, out=length)
    with np.errstate(divide="ignore", invalid="ignore"):
        ok = np.divide(cx, length, out=t) == n[0]
        ok &= np.divide(cy, length, out=t) == n[1]
        ok &= np.divide(cz, length, out=t) == n[2]
    if not length.min(initial=1.0) > 0:  # (a length 0 or NaN: _unit gives 0)
        flat = ~(length > 0)
        zero = (n[0] == 0) & (n[1] == 0) & (n[2] == 0)
        ok[flat] = np.broadcast_to(zero, ok.shape)[flat]
    return ok


_ROWS, _BLOCK, _MIN = 1 << 17, 1 << 15, 1 << 12  # vectors done at a time; most, fewest candidates tried at once


def unit_preimage(normals: np.ndarray) -> np.ndarray:
    """Vectors whose normalization (:func:`_unit`, as tlm's mesh reading normalizes a file's
    normals) gives the unit ``normals`` (..., 3) back to the bit: each one itself where that
    holds (its length computes to 1), else the first of it times 2 ** frac(k phi)
    (k = 1, 2, ...) that does (a unit vector's rounded length is often 1 +- an ulp, and
    its normalization then moves a component by an ulp); one for which none of the
    4096 + 2 ** 16 scales does is kept as it is (an ulp off). What ``tlm scene export`` writes as a
    PLY's normals (:mod:`tlm.scenes.export`), and how the reader keeps a unit ``vn``
    (:func:`unit_as_written`). Vectorized, :data:`_ROWS` vectors at a time (:func:`_first_scales`)."""
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    out = n.copy()
    scales = _scales()
    for a in range(0, n.shape[0], _ROWS):
        k = _first_scales(n[a: a + _ROWS], scales)
        found = np.flatnonzero(k >= 0)
        out[a + found] = n.take(a + found, axis=0) * scales.take(k[found])[:, None]
    return out.reshape(np.shape(normals))


def _first_scales(n: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """For each row of ``n`` (m, 3) that does not normalize to itself, the index of the first of
    ``scales`` whose multiple of it does (:func:`_gives_back`); -1 for the others. The rows left
    try the next scales together, a block of them (those left times the block between
    :data:`_MIN` and :data:`_BLOCK` candidates: about as many scales as a hit takes, by the last
    block's hits), each keeping its first hit."""
    x, y, z = (np.ascontiguousarray(n[:, j]) for j in range(3))
    first = np.full(n.shape[0], -1, dtype=np.intp)
    idx = np.flatnonzero(~_gives_back(x, y, z, (x, y, z)))
    x, y, z = x[idx], y[idx], z[idx]
    k, rate = 0, 1.0
    while idx.shape[0] and k < scales.shape[0]:
        m = idx.shape[0]
        b = max(1, min(_BLOCK // m, max(-(-_MIN // m), int(0.5 / rate))))
        s = scales[k: k + b]
        if b == 1:
            hit = _gives_back(x * s[0], y * s[0], z * s[0], (x, y, z))
            first[idx[hit]] = k
        elif b <= m:  # candidates (scale, vector): the longer axis inner
            s2 = s[:, None]
            ok = _gives_back(x * s2, y * s2, z * s2, (x, y, z))
            hit = ok.any(axis=0)
            first[idx[hit]] = k + ok.argmax(axis=0)[hit]
        else:
            xt, yt, zt = x[:, None], y[:, None], z[:, None]
            ok = _gives_back(xt * s, yt * s, zt * s, (xt, yt, zt))
            hit = ok.any(axis=1)
            first[idx[hit]] = k + ok[hit].argmax(axis=1)
        hits = np.count_nonzero(hit)
        rate = max(hits / (m * b), 1e-9)
        if hits:
            keep = np.flatnonzero(~hit)
            idx, x, y, z = idx[keep], x[keep], y[keep], z[keep]
        k += b
    return first


UNIT_TOLERANCE = 4 * np.finfo(np.float64).eps  # a vn whose length is within this of 1 is unit, as written


def unit_as_written(vn: np.ndarray) -> np.ndarray:
    """``vn`` (n, 3) with each unit vector (its length within :data:`UNIT_TOLERANCE` of 1:
    written as unit, to the last digit) replaced by its :func:`unit_preimage`, so that the
    loader's normalization gives the vector back as written, not an ulp off: a unit
    normal is not normalized again (an exported OBJ's normals read back to the bit).
    Other vectors are kept (the loader normalizes them)."""
    vn = np.asarray(vn, dtype=np.float64)
    if vn.shape[0] == 0:
        return vn
    length = np.linalg.norm(vn, axis=-1)
    unit = np.flatnonzero(np.abs(length - 1.0) <= UNIT_TOLERANCE)
    if unit.shape[0] == 0:
        return vn
    out = vn.copy()
    out[unit] = unit_preimage(vn[unit])
    return out


# ------------------------------------------------------------------ helpers


def _runs(idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and last element of each run of consecutive integers in sorted ``idx``."""
    brk = np.flatnonzero(np.diff(idx) != 1)
    return idx[np.r_[0, brk + 1]], idx[np.r_[brk, idx.shape[0] - 1]]


class _Lines:
    """Line boundaries of a byte string that ends with a newline."""

    def __init__(self, data: bytes):
        self.data = data
        buf = np.frombuffer(data + b"\n\n", dtype=np.uint8)  # padded: byte start + 2 exists
        self.buf = buf
        self.end = np.flatnonzero(buf[: len(data)] == 10)  # each line's newline
        self.start = np.empty_like(self.end)
        if self.end.shape[0]:
            self.start[0] = 0
            self.start[1:] = self.end[:-1] + 1

    def text(self, i: int) -> str:
        return self.data[self.start[i]: self.end[i]].decode("utf-8", "replace").strip()

    def block(self, idx: np.ndarray) -> bytes:
        """The lines ``idx`` (sorted), newlines included, joined."""
        if idx.shape[0] == 0:
            return b""
        first, last = _runs(idx)
        s, e, d = self.start, self.end, self.data
        if first.shape[0] == 1:
            return d[s[first[0]]: e[last[0]] + 1]
        return b"".join([d[a:b] for a, b in zip(s[first].tolist(), (e[last] + 1).tolist(), strict=True)])


def _strip_comment(line: bytes) -> bytes:
    cut = line.find(b"#")
    return line if cut < 0 else line[:cut]


def _err(source: str, line: int, message: str) -> InputError:
    return InputError(f"line {line}: {message}", source=source)


def _shown(word: bytes) -> str:
    text = word.decode("utf-8", "replace")
    return repr(text if len(text) <= 40 else text[:37] + "...")


# ------------------------------------------------------------------ numeric blocks


def _blank_keys(block: bytes, key: bytes) -> tuple[bytes, np.ndarray, np.ndarray]:
    """``block`` (lines that each start with ``key``) with ``key`` blanked where it starts a line and
    only there, its bytes and its newlines: a letter anywhere else (``v -1.01v0.5 0 1``, ``f 1 2 3f4``)
    stays, for ``np.fromstring`` to refuse and the per-line reader to name (a blank would read it as a
    separator)."""
    b = np.frombuffer(block, dtype=np.uint8).copy()
    newline = np.flatnonzero(b == 10)
    for k in range(len(key)):
        b[k] = 32
        b[newline[:-1] + 1 + k] = 32
    return b.tobytes(), b, newline


def _vectors_fast(block: bytes, n: int, key: bytes) -> np.ndarray | None:
    """(n, 3) the first three numbers of each of the ``n`` lines of ``block`` (every
    line starting with ``key``), or None when the fast path cannot read them."""
    body, b, newline = _blank_keys(block, key)
    try:
        values = np.fromstring(body, dtype=np.float64, sep=" ")
    except ValueError:
        return None
    word = b > 32
    tok = np.flatnonzero(word[1:] & ~word[:-1]) + 1  # where each number starts
    if tok.shape[0] != values.shape[0]:
        return None
    if values.shape[0] == 3 * n:  # the usual case: check that every line holds 3 of them
        t = tok.reshape(n, 3)
        if (t[1:, 0] > newline[:-1]).all() and (t[:, 2] < newline).all():
            return values.reshape(n, 3)
        return None
    count = np.bincount(np.searchsorted(newline, tok), minlength=n)
    if count.shape[0] != n or count.min() < 3:
        return None
    first = np.cumsum(count) - count
    return values[first[:, None] + np.arange(3)]


def _colour_lines(block: bytes, lines: np.ndarray) -> tuple[int, int]:
    """``(count, first line number)`` of the ``v`` lines ``lines`` (0-based, their text
    ``block``) that hold six numbers or more (a vertex colour, ``v x y z r g b``)."""
    body = np.frombuffer(block, dtype=np.uint8)
    word = body > 32
    starts = int(np.count_nonzero(word[1:] & ~word[:-1])) + int(word[:1].sum())
    if starts <= 4 * lines.shape[0]:  # (every line 'v' and 3 numbers, or some of 4: no colour)
        return 0, 0
    found = []
    for i, raw in enumerate(block.split(b"\n")[: lines.shape[0]]):
        words = _strip_comment(raw).split()[1:]
        if len(words) >= 6:
            try:
                [float(w) for w in words[3:6]]
            except ValueError:
                continue
            found.append(i)
    return (len(found), int(lines[found[0]]) + 1) if found else (0, 0)


def colour_notes(obj: ObjData, src: str) -> tuple[str, ...]:
    """A line saying that the file's vertex colours are not rendered (none when it gives
    none), as :func:`tlm.scenes.plyfile.colour_notes` says of a PLY's."""
    count, line = obj.colour_lines
    if not count:
        return ()
    return (f"{src}: its vertex colours ('v x y z r g b', {count} line{'s' if count > 1 else ''} from line {line}) "
            "are not rendered: a triangle's material is the scene file's or its MTL's (usemtl, parts:, materials:, "
            "default_material)",)


def _vectors_slow(block: bytes, lines: np.ndarray, what: str, source: str) -> np.ndarray:
    """The per-line reader of :func:`_vectors_fast`'s lines, naming the first it cannot read (Python's
    ``float`` less its underscores: ``1_0`` is no OBJ number): the first three numbers of each, and a
    ``v``'s fourth to sixth (``w``, or a vertex colour ``r g b``: read as the fast path reads them,
    not kept)."""
    out = np.empty((lines.shape[0], 3))
    for i, raw in enumerate(block.split(b"\n")[: lines.shape[0]]):
        words = _strip_comment(raw).split()[1:]
        if len(words) < 3:
            raise _err(source, int(lines[i]) + 1,
                       f"a '{what}' statement needs 3 numbers, got {len(words)}")
        for j in range(min(len(words), 6) if what == "v" else 3):
            try:
                if b"_" in words[j]:
                    raise ValueError
                number = float(words[j])
                if j < 3:
                    out[i, j] = number
            except ValueError:
                raise _err(source, int(lines[i]) + 1,
                           f"cannot read {_shown(words[j])} as a number in a '{what}' statement") from None
    return out


_INDEX = re.compile(rb"[+-]?[0-9]+")  # a face corner's index, as the fast path reads it
_HUGE = 2 ** 62  # |index| from here on: no file has that many elements (and int64 holds them)


def _corners_fast(block: bytes, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """Every corner of the ``n`` face lines of ``block``: its line (0..n-1), vertex index,
    and normal index (0 where it has none) with a flag; None when the fast path cannot
    read the block."""
    body, b, newline = _blank_keys(block, b"f")
    try:
        values = np.fromstring(body.replace(b"/", b" "), dtype=np.int64, sep=" ")
    except ValueError:
        return None
    if ((values >= _HUGE) | (values <= -_HUGE)).any():  # (read as int64's limit, its sign lost: the slow path names it)
        return None
    if b"-" in body or b"+" in body:  # a sign alone: np.fromstring reads "- 3" as -3, "-" as 0
        sign = np.flatnonzero((b == 45) | (b == 43))
        if not ((b[sign + 1] >= 48) & (b[sign + 1] <= 57)).all():
            return None
    slash = np.flatnonzero(b == 47)
    if (b[slash - 1] <= 32).any():  # a corner of slashes without its vertex ("f 1 2 // 3"): not dropped, refused
        return None
    digit = (b > 32) & (b != 47)  # bytes of numbers (byte 0, the blanked 'f', is not one)
    edge = np.flatnonzero(np.diff(digit.view(np.int8)))
    start, end = edge[0::2] + 1, edge[1::2] + 1  # each number's first byte and the byte after it
    if start.shape[0] != values.shape[0]:
        return None
    # a number after a '/' continues its corner, in the slot after the slashes in between
    cont = b[start - 1] == 47
    gap = np.zeros(start.shape[0], dtype=np.int64)
    gap[1:] = start[1:] - end[:-1]
    if cont[0]:
        return None
    after = np.zeros(start.shape[0], dtype=bool)  # the byte after the previous number is a '/'
    after[1:] = b[end[:-1]] == 47
    if (cont != after).any() or (gap[cont] > 2).any():  # "1 /2", "1/ 2", "1///2"
        return None
    first = ~cont
    corner = np.cumsum(first) - 1
    total = np.cumsum(np.where(cont, gap, 0))
    slot = total - total[first][corner]
    if slot.max(initial=0) > 2:
        return None
    line = np.searchsorted(newline, start[first])
    vertex = values[first]
    has_normal = np.zeros(vertex.shape[0], dtype=bool)
    normal = np.zeros(vertex.shape[0], dtype=np.int64)
    third = slot == 2
    has_normal[corner[third]] = True
    normal[corner[third]] = values[third]
    return line, vertex, normal, has_normal


def _corners_slow(block: bytes, lines: np.ndarray, source: str):
    line_of, vertex, normal, has_normal = [], [], [], []
    for i, raw in enumerate(block.split(b"\n")[: lines.shape[0]]):
        for corner in _strip_comment(raw).split()[1:]:
            parts = corner.split(b"/")
            if len(parts) > 3 or not parts[0]:
                raise _err(source, int(lines[i]) + 1, f"cannot read the face corner {_shown(corner)}")
            try:
                if not all(_INDEX.fullmatch(p) for p in parts if p):  # (int() would read "3_0" as 30)
                    raise ValueError
                idx = [int(p) if p else None for p in parts]
            except ValueError:
                raise _err(source, int(lines[i]) + 1,
                           f"cannot read the face corner {_shown(corner)} (indices are integers)") from None
            for k, what in zip(idx, ("vertex", "texture coordinate", "normal"), strict=False):
                if k is not None and abs(k) >= _HUGE:
                    why = f"before the first {what}" if k < 0 else f"beyond any file's {what} count"
                    raise _err(source, int(lines[i]) + 1, f"a face references {what} {k}: an index far {why}")
            line_of.append(i)
            vertex.append(idx[0])
            n = idx[2] if len(idx) == 3 else None
            normal.append(0 if n is None else n)
            has_normal.append(n is not None)
    return (np.array(line_of, dtype=np.int64), np.array(vertex, dtype=np.int64),
            np.array(normal, dtype=np.int64), np.array(has_normal, dtype=bool))


def _resolve(raw: np.ndarray, before: np.ndarray, total: int, corner_line: np.ndarray,
             what: str, source: str) -> np.ndarray:
    """0-based indices from OBJ's 1-based (or negative: relative to the ``before``
    elements defined above the line) ones; a bad one is an error naming its line."""
    idx = np.where(raw > 0, raw - 1, before + raw)
    bad = (raw == 0) | (idx < 0) | (idx >= total)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        r = int(raw[k])
        if r == 0:
            why = "0 is not an OBJ index (they start at 1)"
        elif r < 0:
            why = f"{r} reaches before the first {what} ({int(before[k])} defined above the line)"
        else:
            plural = {"vertex": "vertices", "normal": "normals"}[what]
            why = f"there {'is' if total == 1 else 'are'} only {total} {what if total == 1 else plural}"
        raise _err(source, int(corner_line[k]) + 1, f"a face references {what} {r}: {why}")
    return idx


def _names(L: _Lines, idx: np.ndarray, keyword: str) -> list[str]:
    out = []
    for i in idx.tolist():
        text = L.text(i)
        out.append(text[len(keyword):].strip())
    return out


def _current(marks: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Index (into the lines flagged by ``marks``) of the last flagged line above each
    line ``at``; -1 where none is."""
    return np.cumsum(marks)[at] - 1


# ------------------------------------------------------------------ the reader


_CONTINUED = re.compile(rb"\\\r?\n")  # a backslash that ends a line: the next line continues its statement


def _joined(data: bytes) -> bytes:
    """``data`` (ending with a newline) with each statement continued over lines by a backslash at their
    end (the OBJ spec's long lines, ``f 1 2 \\`` then ``3``) joined on its first line: each backslash and
    its line end read as one blank, whatever the line end (``o my \\`` then ``box`` is the object
    ``my  box`` in a file of LF, CRLF or CR line ends alike), and as many empty lines put after the
    statement, so that every later line keeps its number (an error, ``face_line``, names the
    statement's first line)."""
    found = [m.span() for m in _CONTINUED.finditer(data)] if b"\\" in data else []
    if not found:
        return data
    pieces, at, k = [], 0, 0
    while k < len(found):
        joined = 0
        while True:
            b = found[k][1]
            joined += 1
            end = data.find(b"\n", b)  # (the newline of the line it continues on)
            if k + 1 < len(found) and found[k + 1][1] == end + 1:  # (that line ends with a backslash too)
                k += 1
                continue
            break
        k += 1
        end = len(data) if end < 0 else end + 1
        pieces += [_CONTINUED.sub(b" ", data[at:end]), b"\n" * joined]
        at = end
    return b"".join([*pieces, data[at:]])


def parse_obj(data: bytes, source: str, stem: str) -> ObjData:
    """Parse OBJ text (bytes); ``source`` names the file in errors."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    if b"\r" in data and data.count(b"\r") != data.count(b"\r\n"):  # a CR alone ends a line (old Mac, a stray one)
        data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    if not data.endswith(b"\n"):
        data += b"\n"
    data = _joined(data)
    L = _Lines(data)
    c0 = L.buf[L.start]
    if ((c0 == 32) | (c0 == 9)).any():  # indented statements: rare, normalize them first
        data = b"\n".join(line.lstrip(b" \t") for line in data.split(b"\n"))
        L = _Lines(data)
        c0 = L.buf[L.start]
    c1, c2 = L.buf[L.start + 1], L.buf[L.start + 2]
    sep1, sep2 = c1 <= 32, c2 <= 32
    is_v = (c0 == ord("v")) & sep1
    is_vn = (c0 == ord("v")) & (c1 == ord("n")) & sep2
    is_f = (c0 == ord("f")) & sep1
    is_o = (c0 == ord("o")) & sep1
    is_g = (c0 == ord("g")) & sep1
    is_use = np.zeros_like(is_v)
    mtllibs: list[tuple[str, int]] = []
    for i in np.flatnonzero((c0 == ord("u")) | (c0 == ord("m"))).tolist():
        text = L.text(i)
        word = text.split(maxsplit=1)[0] if text else ""
        if word == "usemtl":
            is_use[i] = True
        elif word == "mtllib":
            mtllibs.append((text[len("mtllib"):].strip(), i + 1))

    v_lines = np.flatnonzero(is_v)
    vn_lines = np.flatnonzero(is_vn)
    f_lines = np.flatnonzero(is_f)
    n_v = v_lines.shape[0]

    block = L.block(v_lines)
    vertices = _vectors_fast(block, n_v, b"v") if n_v else np.zeros((0, 3))
    if vertices is None:
        vertices = _vectors_slow(block, v_lines, "v", source)
    colour_lines = _colour_lines(block, v_lines) if n_v else (0, 0)
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():  # (named as the file numbers them: from 1, with the line)
        k, count = int(np.flatnonzero(bad)[0]), int(bad.sum())
        raise InputError(f"the mesh has {count} {'vertex' if count == 1 else 'vertices'} with NaN or infinite "
                         f"coordinates (first: vertex {k + 1}, line {int(v_lines[k]) + 1}, {vertices[k].tolist()})",
                         source=source)
    block = L.block(vn_lines)
    vnormals = _vectors_fast(block, vn_lines.shape[0], b"vn") if vn_lines.shape[0] else np.zeros((0, 3))
    if vnormals is None:
        vnormals = _vectors_slow(block, vn_lines, "vn", source)
    vnormals = unit_as_written(vnormals)

    if f_lines.shape[0] == 0:
        if n_v == 0:
            raise InputError("the file holds no geometry (empty mesh)", source=source)
        raise InputError(f"the file has {n_v} vertices but no faces: a point cloud without faces, "
                         "not a triangle mesh", source=source)
    block = L.block(f_lines)
    corners = _corners_fast(block, f_lines.shape[0])
    if corners is None:
        corners = _corners_slow(block, f_lines, source)
    c_line, c_vertex, c_normal, c_has_normal = corners
    n_f = f_lines.shape[0]
    count = np.bincount(c_line, minlength=n_f)
    if count.min() < 3:
        k = int(np.flatnonzero(count < 3)[0])
        raise _err(source, int(f_lines[k]) + 1, f"a face needs at least 3 corners, got {int(count[k])}")
    corner_file_line = f_lines[c_line]
    v_before = np.cumsum(is_v)[corner_file_line]
    vertex = _resolve(c_vertex, v_before, n_v, corner_file_line, "vertex", source)
    normal = None
    if c_has_normal.all():
        vn_before = np.cumsum(is_vn)[corner_file_line]
        normal = _resolve(c_normal, vn_before, vnormals.shape[0], corner_file_line, "normal", source)

    # fan triangulation: (0, i, i + 1) from each face's first corner
    first = np.cumsum(count) - count
    n_tri = count - 2
    face_of = np.repeat(np.arange(n_f), n_tri)
    j = np.arange(face_of.shape[0]) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri)
    a = first[face_of]
    tri_corner = np.stack([a, a + j + 1, a + j + 2], axis=1)
    faces = vertex[tri_corner]
    corner_normals = None if normal is None else normal[tri_corner]

    # parts: o objects, else g groups, else the file stem
    marks = is_o if is_o.any() else is_g
    if marks.any():
        keyword = "o" if is_o.any() else "g"
        labels = _names(L, np.flatnonzero(marks), keyword)
        owner = _current(marks, f_lines)
    else:
        labels, owner = [], np.full(n_f, -1, dtype=np.int64)
    part_of_face, part_names = _group(owner, [lb or stem for lb in labels], stem)

    # materials: usemtl names in the order of their first use
    mat_lines = np.flatnonzero(is_use)
    use_names = _names(L, mat_lines, "usemtl")
    mat_owner = _current(is_use, f_lines) if mat_lines.shape[0] else np.full(n_f, -1, dtype=np.int64)
    mat_of_face, material_names, material_lines = _materials(mat_owner, use_names, mat_lines)

    return ObjData(
        vertices=vertices,
        faces=faces,
        face_line=f_lines[face_of] + 1,
        vertex_normals=vnormals,
        corner_normals=corner_normals,
        part=part_of_face[face_of],
        part_names=part_names,
        material=mat_of_face[face_of],
        material_names=material_names,
        material_lines=material_lines,
        mtllibs=tuple(mtllibs),
        colour_lines=colour_lines,
    )


def _group(owner: np.ndarray, labels: list[str], stem: str) -> tuple[np.ndarray, tuple[str, ...]]:
    """Part index of each face from the index of its owning statement (-1: none), parts
    named by ``labels`` (``stem`` for -1), merged by name, in order of first face."""
    ids, first = np.unique(owner, return_index=True)
    names: list[str] = []
    table = np.zeros(ids.shape[0], dtype=np.int32)
    for k in np.argsort(first, kind="stable").tolist():
        name = stem if ids[k] < 0 else labels[int(ids[k])]
        if name not in names:
            names.append(name)
        table[k] = names.index(name)
    return table[np.searchsorted(ids, owner)], tuple(names)


def _materials(owner: np.ndarray, labels: list[str], lines: np.ndarray):
    ids, first = np.unique(owner, return_index=True)
    names: list[str] = []
    at: list[int] = []
    table = np.full(ids.shape[0], -1, dtype=np.int32)
    for k in np.argsort(first, kind="stable").tolist():
        if ids[k] < 0:
            continue
        name = labels[int(ids[k])]
        if name not in names:
            names.append(name)
            at.append(int(lines[int(ids[k])]) + 1)
        table[k] = names.index(name)
    return table[np.searchsorted(ids, owner)], tuple(names), tuple(at)
