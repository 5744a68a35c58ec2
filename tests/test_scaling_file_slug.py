"""``tlm scaling``'s figure ``scaling_<scene>.png``: the scene's part of the name is ASCII only,
and an ASCII scene keeps the name it had."""

from __future__ import annotations

import re

from tlm.experiments.scaling import file_slug

SAFE = re.compile(r"[A-Za-z0-9_.-]+")


def test_a_scene_name_is_ascii_told_apart_and_an_ascii_one_unchanged():
    names = {t: file_slug(t) for t in ("café", "cafè", "cafe", "日本", "Ærø/scène (1)", "é" * 70)}
    for text, slug in names.items():
        assert SAFE.fullmatch(slug) and slug.isascii() and len(slug) <= 60, (text, slug)
    assert re.fullmatch(r"cafe_[0-9a-f]{8}", names["café"]), names["café"]  # (the accent dropped)
    assert len(set(names.values())) == len(names), names  # (café is not cafe, nor cafè)
    assert file_slug("café") == names["café"]  # (the same name every time)
    # an ASCII scene's file keeps its name
    assert file_slug("cornell") == "cornell"
    assert file_slug("thesis/ring") == "thesis_ring"
    assert file_slug("scenes/my room.yaml") == "scenes_my_room.yaml"
    assert file_slug("x" * 70) == "x" * 60
