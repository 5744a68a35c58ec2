"""h325, leftovers of this stop's reviews:

1. An OBJ with old-Mac CR-only line endings was read as one line ("1 vertices but no faces"): it is read as lines,
   the same arrays as the file with LF or CRLF endings.
2. ``tlm scene show`` gives each material's ``from`` (where its values came from), as results.json does.
3. A thesis cell's "not comparable" list named ``arch.settle_frames`` though the thesis's static stream never reads
   it (the thesis's value stands for none; ``arch.scheduler`` says the difference).
4. The note on an unsettled scaling point said its latency is over "the later half of its steady completions": it is
   over the frames that arrived in that window, or, in a stream too short for any of them to be done before the
   drain (5 frames of two images), over those that arrived after the warm-up.
"""

from __future__ import annotations

import copy
import dataclasses
import zipfile
from pathlib import Path

import numpy as np
import pytest

from tlm.arch.steady import steady_throughput
from tlm.experiments.scaling import unsteady
from tlm.experiments.thesis_setting import setting_mismatches, thesis_setting
from tlm.scenes.objfile import parse_obj, read_obj

REPO = Path(__file__).resolve().parents[1]
ZIP = Path("/work/shared/scenes/CornellBox.zip")


def _cornell_obj() -> bytes:
    """CornellBox-Original.obj as published (CRLF), from the archive where present, else the repository's copy."""
    if ZIP.exists():
        with zipfile.ZipFile(ZIP) as z:
            return z.read("CornellBox-Original.obj")
    return (REPO / "scenes" / "meshes" / "CornellBox-Original.obj").read_bytes()


def _same(a, b) -> None:
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            assert x is not None and y is not None and x.dtype == y.dtype, f.name
            np.testing.assert_array_equal(x, y, err_msg=f.name)
        else:
            assert x == y, f.name


def test_a_cr_only_obj_is_read_as_its_lines(tmp_path):
    crlf = _cornell_obj()
    assert b"\r\n" in crlf
    lf = crlf.replace(b"\r\n", b"\n")
    cr = lf.replace(b"\n", b"\r")
    want = parse_obj(lf, "box.obj", "box")
    assert want.faces.shape[0] > 30
    _same(parse_obj(crlf, "box.obj", "box"), want)
    _same(parse_obj(cr, "box.obj", "box"), want)
    (tmp_path / "box.obj").write_bytes(cr)  # (and from a file, as a scene reads it)
    _same(read_obj(tmp_path / "box.obj"), want)


def test_a_cr_only_obj_error_names_its_line():
    with pytest.raises(Exception, match=r"box\.obj.*3|3.*box\.obj"):
        parse_obj(b"v 0 0 0\rv 1 0 0\rf 1 2 9\r", "box.obj", "box")


def test_scene_show_gives_each_materials_origin():
    from tlm import api

    info = api.scene_info("cornell-box")
    origins = [m.get("from") for m in info["materials"]]
    assert origins and all(o and "CornellBox-Original.mtl:" in o for o in origins), origins


def test_a_key_the_thesis_never_reads_is_not_a_mismatch():
    thesis = thesis_setting("cornell", "rcast")
    assert thesis["arch"]["scheduler"] == "static" and thesis["arch"]["settle_frames"] == 64
    ours = copy.deepcopy(thesis)
    # (h354: the thesis's static stream of two images may run on until it settles: it reads arch.settle_frames; its
    # one pipeline never reads arch.fanout)
    assert thesis["arch"]["pipelines"] == 1 and thesis["arch"]["fanout"] == "broadcast"
    ours["arch"].update(scheduler="dynamic", pipelines=2, fanout="serial")
    said = setting_mismatches("cornell", ours)
    assert "arch.scheduler dynamic (thesis: static)" in said, said
    assert not any(m.startswith("arch.fanout") for m in said), said
    ours["cache"]["pairs"] = 1  # (the thesis's 4 is read, and gives what 2 does: 1 differs)
    assert "cache.pairs 1 (thesis: 4)" in setting_mismatches("cornell", ours)


@pytest.mark.parametrize("frames", [5, 6, 16])
def test_an_unsettled_points_note_names_the_frames_of_its_latency(frames):
    done = [100 + 30 * i + (7 * i * i) % 11 for i in range(frames)]  # (no period: it does not settle)
    _, est = steady_throughput(done, 2, settling=True)
    assert est["settled"] is False
    after_warmup = est["latency_arrivals"][0] == 2 + 1  # (frame k + i arrives at completion i; k - 1 = 1)
    assert after_warmup == (frames == 5), est
    note = unsteady({"settled": False, "frames": frames, "in_flight": 2})
    assert "later half of its steady completions and its latency" in note, note
    assert ("arrived after the warm-up" in note) == after_warmup, note
    assert ("arrived in that window" in note) != after_warmup or "none that arrived in that window" in note, note
    assert "after the warm-up where none" in unsteady({"settled": False, "frames": frames})  # (no in_flight: both)
