"""The vectorized OBJ reader (tlm/scenes/objfile.py) against a plain per-line reader,
its errors, compressed files, and the sped-up crease normals against the original."""

from __future__ import annotations

import bz2
import gzip
import lzma
from pathlib import Path

import numpy as np
import pytest

from tlm.errors import InputError
from tlm.scenes import normals as fast_normals
from tlm.scenes.meshes import load_mesh
from tlm.scenes.objfile import parse_obj

REPO = Path(__file__).resolve().parents[1]
MESHES = REPO / "scenes" / "meshes"
QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\n"


def reference_obj(text: str, stem: str = "m"):
    """A slow, obvious OBJ reader: (vertices, faces, corner normals or None, part names
    per face, usemtl name per face or None), polygons fanned from their first corner."""
    v, vn, faces, fnormals, parts, mats = [], [], [], [], [], []
    obj = grp = mat = None
    has_o = any(ln.split()[:1] == ["o"] for ln in text.splitlines())
    all_normals = True
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        words = line.split()
        if not words:
            continue
        if words[0] == "v":
            v.append([float(x) for x in words[1:4]])
        elif words[0] == "vn":
            vn.append([float(x) for x in words[1:4]])
        elif words[0] == "o":
            obj = line[1:].strip()
        elif words[0] == "g":
            grp = line[1:].strip()
        elif words[0] == "usemtl":
            mat = line[6:].strip()
        elif words[0] == "f":
            idx, nidx = [], []
            for c in words[1:]:
                p = c.split("/")
                i = int(p[0])
                idx.append(i - 1 if i > 0 else len(v) + i)
                if len(p) == 3 and p[2]:
                    k = int(p[2])
                    nidx.append(k - 1 if k > 0 else len(vn) + k)
                else:
                    all_normals = False
                    nidx.append(-1)
            for i in range(1, len(idx) - 1):
                faces.append([idx[0], idx[i], idx[i + 1]])
                fnormals.append([nidx[0], nidx[i], nidx[i + 1]])
                parts.append((obj if has_o else grp) or stem)
                mats.append(mat)
    return (np.array(v, dtype=float).reshape(-1, 3), np.array(faces).reshape(-1, 3),
            np.array(fnormals).reshape(-1, 3) if all_normals else None, parts, mats)


def _check_against_reference(text: str, stem: str = "m"):
    got = parse_obj(text.encode(), "test.obj", stem)
    v, f, fn, parts, mats = reference_obj(text, stem)
    np.testing.assert_array_equal(got.vertices, v)
    np.testing.assert_array_equal(got.faces, f)
    if fn is None:
        assert got.corner_normals is None
    else:
        np.testing.assert_array_equal(got.corner_normals, fn)
    assert [got.part_names[i] for i in got.part] == parts
    assert [None if i < 0 else got.material_names[i] for i in got.material] == mats
    return got


# ---------------------------------------------------------------- reading


@pytest.mark.parametrize("corner", ["{v}", "{v}/{v}", "{v}//{n}", "{v}/{v}/{n}"])
def test_every_corner_form(corner):
    text = QUAD + "vn 0 0 1\nvn 0 1 0\nvn 1 0 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0 0\nvt 0 0\n"
    for face in ([1, 2, 3], [2, 4, 3], [1, 5, 6]):
        text += "f " + " ".join(corner.format(v=i, n=1 + i % 3) for i in face) + "\n"
    got = _check_against_reference(text)
    assert got.faces.tolist() == [[0, 1, 2], [1, 3, 2], [0, 4, 5]]
    assert (got.corner_normals is not None) == ("{n}" in corner)


def test_negative_indices_are_relative_to_the_vertices_above():
    text = ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf -3//-1 -2//-1 -1//-1\n"
            "v 5 5 5\nv 6 5 5\nv 5 6 5\nvn 1 0 0\nf -3//-1 -2//-2 -1//-1\nf 1 -1 2\n")
    got = _check_against_reference(text)
    assert got.faces.tolist() == [[0, 1, 2], [3, 4, 5], [0, 5, 1]]
    assert got.corner_normals is None  # the last face has none
    text = text.rsplit("f 1 -1 2\n", 1)[0]
    got = _check_against_reference(text)
    assert got.corner_normals.tolist() == [[0, 0, 0], [1, 0, 1]]


def test_polygons_are_fanned_from_their_first_corner_in_file_order():
    text = QUAD + "f 1 2 3 4\nf 2 6 5\nf 1 2 6 5 3 4\n"
    got = _check_against_reference(text)
    assert got.faces.tolist() == [[0, 1, 2], [0, 2, 3], [1, 5, 4],
                                  [0, 1, 5], [0, 5, 4], [0, 4, 2], [0, 2, 3]]
    assert got.face_line.tolist() == [7, 7, 8, 9, 9, 9, 9]


def test_parts_objects_groups_and_the_stem():
    # objects win over groups; faces above the first object get the stem; same names merge
    text = QUAD + "f 1 2 3\no box\ng a\nf 1 2 4\no lid\nf 1 3 4\ng b\no box\nf 2 3 4\n"
    got = _check_against_reference(text, "stem")
    assert got.part_names == ("stem", "box", "lid")
    assert got.part.tolist() == [0, 1, 2, 1]
    # groups when there are no objects, an empty group skipped
    text = QUAD + "g empty\ng first part\nf 1 2 3\ng second\nf 1 2 4\ng first part\nf 2 3 4\n"
    got = _check_against_reference(text)
    assert got.part_names == ("first part", "second")
    assert got.part.tolist() == [0, 1, 0]
    got = _check_against_reference(QUAD + "f 1 2 3\nf 2 3 4\n", "plain")
    assert got.part_names == ("plain",) and got.part.tolist() == [0, 0]


def test_usemtl_runs_and_mtllib():
    text = ("mtllib a.mtl b.mtl\n" + QUAD + "f 1 2 3\nusemtl red\nf 1 2 4\nf 2 3 4\n"
            "usemtl blue\nf 1 3 4\nusemtl red\nf 1 5 6 2\n")
    got = _check_against_reference(text)
    assert got.material_names == ("red", "blue") and got.material_lines == (9, 12)
    assert got.material.tolist() == [-1, 0, 0, 1, 0, 0]
    assert got.mtllibs == (("a.mtl b.mtl", 1),)


def test_line_endings_comments_tabs_indents_and_other_statements():
    text = ("# header\r\nmtllib x.mtl\r\n\tv 0 0 0 # a comment\r\nv\t1 0 0 1.0\r\n  v 0 1 0 0.5 0.5 0.5\r\n"
            "vt 0 0\r\nvp 0.5\r\ns 1\r\nl 1 2\r\np 1\r\n\r\nf 1 2 3 # tri\r\n  f 3 2 1")  # no final newline
    got = _check_against_reference(text)
    np.testing.assert_array_equal(got.vertices, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert got.faces.tolist() == [[0, 1, 2], [2, 1, 0]]


@pytest.mark.slow
def test_random_files_match_the_reference_reader():
    rng = np.random.default_rng(7)
    for trial in range(20):
        lines, nv, nn = [], 0, 0
        with_normals = trial % 2 == 0
        for _ in range(200):
            r = rng.random()
            if r < 0.3 or nv < 3:
                lines.append("v " + " ".join(f"{x:.6g}" for x in rng.normal(size=3)))
                nv += 1
            elif r < 0.4:
                lines.append("vn " + " ".join(f"{x:.6g}" for x in rng.normal(size=3)))
                nn += 1
            elif r < 0.45:
                lines.append(f"{'o' if trial % 3 == 0 else 'g'} part{rng.integers(4)}")
            elif r < 0.5:
                lines.append(f"usemtl m{rng.integers(3)}")
            else:
                k = int(rng.integers(3, 7))
                corners = []
                for i in rng.integers(0, nv, size=k):
                    vi = int(i) + 1 if rng.random() < 0.5 else int(i) - nv
                    if with_normals and nn:
                        corners.append(f"{vi}/{rng.integers(1, 9)}/{rng.integers(1, nn + 1)}")
                    else:
                        corners.append(str(vi))
                lines.append("f " + " ".join(corners))
        if with_normals and nn == 0:
            continue
        fast = _check_against_reference("\n".join(lines) + "\n")
        # an inline comment on the first v, vn and f line sends their blocks through the
        # per-line reader: the same result
        for key in ("v ", "vn ", "f "):
            first = next((i for i, ln in enumerate(lines) if ln.startswith(key)), None)
            if first is not None:
                lines[first] += " # sends the block to the slow path"
        slow = _check_against_reference("\n".join(lines) + "\n")
        for field in ("vertices", "faces", "vertex_normals", "part", "material"):
            np.testing.assert_array_equal(getattr(fast, field), getattr(slow, field))


# ---------------------------------------------------------------- errors


@pytest.mark.parametrize(("text", "words"), [
    (QUAD + "f 1 2 0\n", ["line 7", "0"]),
    (QUAD + "f 1 2 9\n", ["line 7", "vertex 9", "6 vertices"]),
    (QUAD + "f 1 2 -7\n", ["line 7", "-7"]),
    (QUAD + "f 1 2\n", ["line 7", "3 corners"]),
    (QUAD + "f 1 2 x\n", ["line 7", "'x'"]),
    (QUAD + "f 1/2/3/4 2 3\n", ["line 7", "'1/2/3/4'"]),
    (QUAD + "vn 0 0 1\nf 1//1 2//2 3//1\n", ["line 8", "normal 2"]),
    ("v 0 0 0\nv 1 0 zero\nv 0 1 0\nf 1 2 3\n", ["line 2", "'zero'"]),
    ("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", ["line 2", "3 numbers"]),
    ("", ["empty"]),
    ("# nothing\n\n", ["empty"]),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\n", ["without faces"]),
])
def test_errors_are_one_line_naming_file_and_line(tmp_path, text, words):
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        load_mesh(path)
    msg = str(info.value)
    assert "\n" not in msg and str(path) in msg
    for w in words:
        assert w in msg


def test_nan_vertex_names_it(tmp_path):
    path = tmp_path / "nan.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n")
    with pytest.raises(InputError, match=r"NaN.*vertex 3, line 3"):
        load_mesh(path)


# ---------------------------------------------------------------- compressed files


@pytest.mark.parametrize(("suffix", "pack"), [(".gz", gzip.compress), (".xz", lzma.compress),
                                              (".bz2", bz2.compress)])
def test_compressed_files_give_the_same_geometry(tmp_path, suffix, pack):
    obj = ("mtllib box.mtl\n" + QUAD + "vn 0 0 1\no lid\nusemtl red\nf 1//1 2//1 3//1 4//1\n"
           "o side\nusemtl glass\nf 1//1 2//1 6//1 5//1\n")
    mtl = "newmtl red\nKd 0.8 0.1 0.1\nnewmtl glass\nillum 7\nNi 1.4\n"
    plain = tmp_path / "plain"
    packed = tmp_path / "packed"
    plain.mkdir()
    packed.mkdir()
    (plain / "box.obj").write_text(obj)
    (plain / "box.mtl").write_text(mtl)
    (packed / f"box.obj{suffix}").write_bytes(pack(obj.encode()))
    (packed / f"box.mtl{suffix}").write_bytes(pack(mtl.encode()))  # the MTL compressed like it
    a, b = load_mesh(plain / "box.obj"), load_mesh(packed / f"box.obj{suffix}")
    for field in ("triangles", "part", "normals", "face_material"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)
    assert a.part_names == b.part_names == ("lid", "side")
    assert a.materials == b.materials and [m.kind for m in a.materials] == ["lambertian", "dielectric"]
    # a plain MTL beside the compressed OBJ is found too
    (packed / f"box.mtl{suffix}").unlink()
    (packed / "box.mtl").write_text(mtl)
    assert load_mesh(packed / f"box.obj{suffix}").materials == a.materials


def test_a_corrupt_compressed_file_is_an_input_error(tmp_path):
    path = tmp_path / "m.obj.xz"
    path.write_bytes(b"not xz at all")
    with pytest.raises(InputError, match=r"m\.obj\.xz.*decompress"):
        load_mesh(path)


@pytest.mark.slow
def test_the_shipped_meshes_are_the_published_files():
    """Decompressed, the shipped OBJ files have the published files' SHA-256."""
    import hashlib

    published = {
        "CornellBox-Original.obj": "6e2b8b91590e54005fba03b1847c626ee4d9fd85f754045780e6c0001ada4188",
        "CornellBox-Sphere.obj.xz": "74d3a8ad49b09bfe702980ae4c877861db01f722a586e3777735f7a0e2b833cc",
        "CornellBox-Water.obj.xz": "ef051544c10e26e195afa67d66be20517cb600cadb2442d16171a0013c367559",
        "conference.obj.xz": "034a0af3ca60340813c67b3405c84872282e5aa03fd818d26f9b2651f76ea47a",
        "CornellBox-Original.mtl": "1f687df1ba44bae18097242528fe39f36f1ff9f4e4b2a5c10bf36e08837bb857",
        "CornellBox-Sphere.mtl": "96be0e286cb4e0c31e166223ef3c90449edf29fa05d8c4b28bab4954bf8b4ff8",
        "CornellBox-Water.mtl": "07fc3ce3a76bc9b9e7b4646b6691a701f2afc84a520a02ed0f52d125a133e574",
        "conference.mtl": "7bb5ec226868f1981d77449aa26f0e161bb5dca042fa03cd5ec04d7d03c0b14d",
    }
    for name, digest in published.items():
        data = (MESHES / name).read_bytes()
        if name.endswith(".xz"):
            data = lzma.decompress(data)
        assert hashlib.sha256(data).hexdigest() == digest, name


@pytest.mark.slow
def test_shipped_cornell_boxes_match_the_reference_reader():
    for name in ("CornellBox-Original.obj", "CornellBox-Sphere.obj.xz", "CornellBox-Water.obj.xz"):
        data = (MESHES / name).read_bytes()
        text = (lzma.decompress(data) if name.endswith(".xz") else data).decode()
        got = _check_against_reference(text, name.split(".")[0])
        g = load_mesh(MESHES / name)
        np.testing.assert_array_equal(g.triangles, got.vertices[got.faces])


# ---------------------------------------------------------------- crease normals


def _reference_crease_normals(triangles, part=None, crease_angle=30.0):
    """tlm.scenes.normals.crease_normals as it was before it was sped up (commit 0a6af23)."""
    _unit, corner_angles = fast_normals._unit, fast_normals.corner_angles
    tri = np.asarray(triangles, dtype=np.float64)
    n = tri.shape[0]
    face = _unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    if n == 0 or not crease_angle > 0.0:
        return np.repeat(face[:, None, :], 3, axis=1)
    part = np.zeros(n, dtype=np.int64) if part is None else np.asarray(part, dtype=np.int64)
    cos_crease = np.cos(np.radians(min(float(crease_angle), 180.0)))
    weight = corner_angles(tri).reshape(-1)
    key = np.concatenate([np.repeat(part, 3)[:, None].astype(np.float64), tri.reshape(-1, 3)], axis=1)
    _, vid = np.unique(key, axis=0, return_inverse=True)
    vid = vid.reshape(-1)
    order = np.argsort(vid, kind="stable")
    sorted_vid = vid[order]
    starts = np.flatnonzero(np.r_[True, sorted_vid[1:] != sorted_vid[:-1]])
    sizes = np.diff(np.r_[starts, sorted_vid.shape[0]])
    corner_face = np.arange(3 * n) // 3
    acc = np.zeros((3 * n, 3))
    pairs = np.cumsum(sizes * sizes)
    lo = 0
    while lo < starts.shape[0]:
        base = pairs[lo - 1] if lo else 0
        hi = max(int(np.searchsorted(pairs, base + (1 << 22), side="right")), lo + 1)
        st, sz = starts[lo:hi], sizes[lo:hi]
        rep = np.repeat(np.arange(hi - lo), sz * sz)
        within = np.arange(rep.shape[0]) - np.repeat(np.cumsum(sz * sz) - sz * sz, sz * sz)
        a = order[st[rep] + within // sz[rep]]
        b = order[st[rep] + within % sz[rep]]
        fa, fb = corner_face[a], corner_face[b]
        ok = np.sum(face[fa] * face[fb], axis=1) >= cos_crease
        np.add.at(acc, a[ok], weight[b[ok], None] * face[fb[ok]])
        lo = hi
    normals = _unit(acc).reshape(n, 3, 3)
    flat = ~np.any(normals != 0.0, axis=2)
    normals[flat] = np.repeat(face[:, None, :], 3, axis=1)[flat]
    return normals


def _meshes_for_normals():
    from tlm.scenes.builders import BUILDERS

    for name, build in BUILDERS.items():
        g = build()
        yield name, g.triangles, g.part
    g = load_mesh(MESHES / "CornellBox-Sphere.obj.xz")
    yield "CornellBox-Sphere", g.triangles, g.part
    rng = np.random.default_rng(3)  # shared corners, -0.0 beside 0.0, slivers, repeated triangles
    v = rng.integers(-2, 3, size=(40, 3)).astype(float)
    v[v == 0] = np.where(rng.random(int((v == 0).sum())) < 0.5, 0.0, -0.0)
    tri = v[rng.integers(0, 40, size=(3000, 3))]
    yield "random", tri, rng.integers(0, 3, size=3000)
    yield "random-one-part", tri, None


@pytest.mark.slow
def test_crease_normals_are_bit_for_bit_the_original():
    for name, tri, part in _meshes_for_normals():
        for angle in (30.0, 0.0, 5.0, 89.0, 180.0):
            a = _reference_crease_normals(tri, part, angle)
            b = fast_normals.crease_normals(tri, part, angle)
            assert a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64)), (name, angle)


@pytest.mark.slow
def test_crease_normals_weld_exactly_on_a_hash_collision(monkeypatch):
    """The hash is checked against the positions: with every hash equal (a collision
    everywhere) the welding falls back to the exact sort and gives the same normals."""
    _, tri, part = next(m for m in _meshes_for_normals() if m[0] == "random")
    expected = _reference_crease_normals(tri, part, 30.0)
    calls = []

    def collide(pts, p):
        calls.append(1)
        return np.zeros(pts.shape[0], dtype=np.uint64)

    monkeypatch.setattr(fast_normals, "_row_hash", collide)
    got = fast_normals.crease_normals(tri, part, 30.0)
    assert calls and np.array_equal(got.view(np.uint64), expected.view(np.uint64))


def test_a_concave_polygon_is_named_in_the_notes(tmp_path):
    """A U-shaped face fanned from its first corner covers its notch, with a triangle facing
    back: the mesh's notes name it (the run warns); convex polygons and triangles give none."""
    u = "v 0 0 0\nv 3 0 0\nv 3 2 0\nv 2 2 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\n"
    (tmp_path / "u.obj").write_text(u + "f 1 2 3 4 5 6 7 8\nf 1 2 3\n")
    (tmp_path / "quads.obj").write_text(u + "f 1 2 3 8\nf 2 3 4 5 6\nf 1 2 3\n")  # (convex, star from corner 1)
    note = load_mesh(tmp_path / "u.obj").notes
    assert note == (f"{tmp_path / 'u.obj'}: 1 polygon is not convex (first at line 9): fanned from its first "
                    "corner, it covers another area than the face, with triangles facing back; split such faces "
                    "into triangles in the file",)
    assert load_mesh(tmp_path / "quads.obj").notes == ()
    # a convex face with corners along an edge (slivers of no area, their sign rounding noise): no note
    (tmp_path / "coll.obj").write_text("v 0 0 0\nv .1 .2 .3\nv .3 .6 .9\nv .7 1.4 2.1\nv 1 2 3\nv 1 3 3\nv 0 1 0\n"
                                       "f 1 2 3 4 5 6 7\n")
    assert load_mesh(tmp_path / "coll.obj").notes == ()
