"""h326, a last read of stop 61: the "no effect" line of ``arch.settle_frames`` named the default's 64 where
``arch.frames`` past it is the default's bound (70 frames "within ... the default's (64)"), and called a stream
that ran the frames asked "settled after" them; an MTL saved with a UTF-8 byte order mark lost its first
material (the mark read as part of ``newmtl``)."""

from __future__ import annotations

from tlm.experiments.run_warnings import inert_timing_changes
from tlm.scenes.materials import mtl_text, parse_mtl

from .test_review_h321 import _run, refract  # noqa: F401  (the module's fixture)


def test_a_bound_past_frames_asked_is_said_against_the_bound_that_ran(refract):  # noqa: F811
    t, cfg = _run(refract, frames=70, settle_frames=100)
    assert inert_timing_changes(t, cfg).get("arch.settle_frames") == (
        "the stream ran the 70 frames asked (arch.frames), settled by then: within this bound and the default's (70)")


def test_an_mtl_with_a_byte_order_mark_keeps_its_first_material(tmp_path):
    data = b"\xef\xbb\xbfnewmtl floor\nKd 0.5 0.5 0.5\nnewmtl wall\nKd 0.2 0.3 0.4\n"
    notes: list[str] = []
    text = mtl_text(data, str(tmp_path / "lib.mtl"), notes)
    got = parse_mtl(text, str(tmp_path / "lib.mtl"), notes)
    assert [m.name for m in got] == ["floor", "wall"] and got[0].albedo == (0.5, 0.5, 0.5), (got, notes)
