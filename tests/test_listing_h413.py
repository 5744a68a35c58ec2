"""h413: one way to say "a, b, c and N more": :func:`tlm.config_words.listing`, and the places that list
items then count the rest, which now read alike (the last item after "and", never "and 1 more")."""

from __future__ import annotations

import pytest

from tlm.config_words import listing


@pytest.mark.parametrize(("items", "kwargs", "said"), [
    ([], {}, ""),
    (["a"], {}, "a"),
    (["a", "b"], {}, "a and b"),
    (["a", "b", "c"], {}, "a, b and c"),
    (list("abcdefghij"), {}, "a, b, c, d, e, f, g, h, i and j"),  # (named None: every item)
    (list("abc"), {"last": "or"}, "a, b or c"),
    (list("abcdefgh"), {"named": 3}, "a, b, c and 5 more"),
    (list("abcde"), {"named": 3, "more": "more files"}, "a, b, c and 2 more files"),
    (list("abcd"), {"named": 3}, "a, b, c and d"),  # (one left over is named: never "and 1 more")
    (list("abc"), {"named": 3}, "a, b and c"),
    (list("abcdefgh"), {"named": 4, "whole": 8}, "a, b, c, d, e, f, g and h"),  # (all of up to whole)
    (list("abcdefghi"), {"named": 4, "whole": 8}, "a, b, c, d and 5 more"),
    (list("abc"), {"named": 0}, "3 more"),
])
def test_listing(items, kwargs, said):
    assert listing(items, **kwargs) == said


def test_listing_takes_any_iterable():
    assert listing(str(i) for i in range(12)) == "0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10 and 11"
    assert listing((str(i) for i in range(12)), 4) == "0, 1, 2, 3 and 8 more"


def test_report_some_lists_with_and():
    from tlm.report.common import some
    assert some(["r1", "r2", "r3"]) == "r1, r2 and r3"  # (was "r1, r2, r3")
    assert some([f"{i}" for i in range(13, 23)]) == "13, 14, 15, 16 and 6 more"


def test_tradeoff_points_name_the_eighth():
    from tlm.report.tradeoff import _points
    rows = [{"point": i} for i in range(10)]
    assert _points(rows, [True] * 8 + [False] * 2) == "Points 0, 1, 2, 3, 4, 5, 6 and 7 of rows.csv"
    assert _points(rows, [True] * 10) == "Points 0, 1, 2, 3, 4, 5, 6 and 3 more of rows.csv"


def test_tied_points_of_least_error_each_with_its_frame_rate():
    """Five tied points: all five named, each with its frame rate (was four and "1 more")."""
    from tlm.report.summary_effects import _named
    where = [f"a = {i}, b = 1" for i in range(5)]
    fps = [f" at {i} FPS" for i in range(5)]
    assert _named(where, ["a", "b"], fps) == ("(a = 0, b = 1) at 0 FPS, (a = 1, b = 1) at 1 FPS, (a = 2, b = 1) at "
                                              "2 FPS, (a = 3, b = 1) at 3 FPS and (a = 4, b = 1) at 4 FPS")
    assert _named(where + ["a = 9, b = 1"], ["a", "b"]).endswith("(a = 3, b = 1) and 2 more")


def test_gltf_notes_list_with_and():
    from tlm.scenes.gltf_imports import _listed
    assert _listed(["'a'", "'b'", "'c'"]) == "'a', 'b' and 'c'"
    assert _listed([f"'{c}'" for c in "abcdef"]) == "'a', 'b', 'c', 'd' and 2 more"


def test_an_obj_of_three_libraries_lists_them(tmp_path):
    """The OBJ of an MTL's stem that names three other libraries: ``a.mtl, b.mtl and c.mtl`` (was "a.mtl and
    b.mtl and c.mtl")."""
    from tlm.mesh_files import mtl_users
    (tmp_path / "box.mtl").write_text("newmtl m\n")
    (tmp_path / "box.obj").write_text("mtllib a.mtl\nmtllib b.mtl\nmtllib c.mtl\nv 0 0 0\n")
    assert mtl_users(tmp_path / "box.mtl") == ([], ("box.obj", "a.mtl, b.mtl and c.mtl"))


def test_material_warnings_name_a_last_file(tmp_path):
    """Of four files past three shown, the fourth is named (was "and 1 more files")."""
    from types import SimpleNamespace

    from tlm.render import checks
    hit = [SimpleNamespace(name=f"m{i}", ignored={"Ks": "x"}, kind="lambertian", origin=f"{tmp_path}/f{i}.mtl:1")
           for i in range(4)]
    scene = SimpleNamespace(materials=hit, material_index=__import__("numpy").arange(4))
    (line,) = checks.material_warnings(scene)
    assert "'m0', 'm1', 'm2' and 'm3'" in line and "'f0.mtl', 'f1.mtl', 'f2.mtl' and 'f3.mtl'" in line, line


def test_idle_points_left_out_are_listed():
    """Points of no scheduler or N: ``point 3`` of one (was "points 3"), ``points 0, 1 and 2`` of several."""
    from pathlib import Path

    from tlm.report.collect import Sweep
    from tlm.report.scaling import idle_points

    def said(n):
        rows = [{"point": i, "status": "ok", "hash": f"h{i}", "idle.vertex": 0.1} for i in range(n)]
        notes: list[str] = []
        idle_points(Sweep(Path("sw"), {}, rows, []), notes)
        return [x for x in notes if "idle figures" in x]

    assert said(1) == ["sw: point 0 left out of the idle figures: neither the row nor a results folder gives "
                       "their scheduler and N"]
    assert said(3)[0].startswith("sw: points 0, 1 and 2 left out")
