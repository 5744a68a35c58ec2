"""h400 (probes h394, h397): ``tlm granularity`` says when packet sizes cannot differ, keeps its table aligned
for a packet size of any width, and keeps its warnings with the study.

At 16x16 (256 eye rays, one a pixel) every packet size from 256 to 102400 gave the same row, unsaid: at or past
the items of the frame's largest phase (the pixels of a ray pass, the photons of a photon phase) each phase runs
as one packet. The line under the table and the study's ``granularity_summary.json`` say which sizes, judged from
the frame program's phases, never past a larger phase (a pmap frame's photons). A size of 2e12 pushed its row's
columns out of line. The frame's own warnings and the overrides' went to stderr and ``attrs["warnings"]`` but not
into the study folder, so ``tlm report`` could not list them.
"""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

from tlm.cli import main
from tlm.report.collect import read
from tlm.report.warnings import warnings_html

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"spp": 1, "light_samples": 1},
        "arch": {"frames": 1}}
SAME = ("packet sizes 256, 1024 and 102400 are at or past the 256 pixels of the frame's largest phase "
        "(rcast.rays): each phase runs as one packet at each, so their cycles, errors and events are the same")


def _study(tmp_path: Path, base: dict, sizes: list[int]) -> Path:
    study = tmp_path / "g.yaml"
    study.write_text(json.dumps({"base": base, "packet_sizes": sizes}))
    return study


def test_sizes_past_the_frame_s_largest_phase_are_said_to_give_the_same_row(tmp_path, cache, capsys):
    out = tmp_path / "g"
    assert main(["granularity", str(_study(tmp_path, BASE, [1, 64, 256, 1024, 102400])), "--out", str(out),
                 "--no-report"]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert f"  {SAME}" in printed, printed
    table = [i for i, line in enumerate(printed) if "max |cycle error|" in line]
    assert printed.index(f"  {SAME}") == table[-1] + 1  # (under the table)
    record = json.loads((out / "granularity_summary.json").read_text())
    assert record["largest_phase"] == {"phase": "rcast.rays", "items": 256, "unit": "pixels"}
    assert record["one_packet"] == [256, 1024, 102400] and record["notes"] == [SAME]
    rows = [json.loads(line) for line in (out / "granularity.jsonl").read_text().splitlines()]
    cycles = {r["packet_size"]: (r["throughput"], r["latency"], r["simpy_events"]) for r in rows}
    assert cycles[256] == cycles[1024] == cycles[102400] != cycles[64]  # (what the line claims, and no more)
    assert "granularity_summary.json" in (out / ".tlm-files").read_text().split()


def test_a_larger_photon_phase_keeps_smaller_sizes_apart(tmp_path, cache):
    """A pmap frame's 256 pixels are one packet at 256, but its 4000 photons are not: 4096 and 8192 are said,
    256 is not; the count is the frame program's, each phase's items in packets of one."""
    from tlm.arch.frame_program import frame_program
    from tlm.experiments.frames import cached_render
    from tlm.experiments.granularity import LEVEL_KINDS, load_granularity, run_granularity
    from tlm.experiments.run import programs_for

    base = {**BASE, "mode": "pmap", "photons": {"count": 4000}}
    study = _study(tmp_path, base, [256, 4096, 8192])
    rows = run_granularity(study, tmp_path / "g", warned=lambda line: None)
    record = json.loads((tmp_path / "g" / "granularity_summary.json").read_text())
    assert record["largest_phase"] == {"phase": "photons.emit", "items": 4000, "unit": "photons"}
    assert record["one_packet"] == [4096, 8192]
    assert record["notes"] == ["packet sizes 4096 and 8192 are at or past the 4000 photons of the frame's largest "
                               "phase (photons.emit): each phase runs as one packet at each, so their cycles, "
                               "errors and events are the same"]
    assert rows[0]["throughput"] != rows[1]["throughput"] == rows[2]["throughput"]
    cfg, _, folder = load_granularity(study)
    fn = cached_render(cfg, folder, str(study)).functional
    ones = frame_program(fn, programs_for(cfg, folder), replace(cfg.arch, packet_size=1))
    assert max(ph.jobs[0].n for ph in ones.phases if ph.jobs[0].kind not in LEVEL_KINDS) == 4000


def test_the_table_stays_aligned_for_a_packet_size_of_any_width(tmp_path, cache, capsys):
    out = tmp_path / "g"
    assert main(["granularity", str(_study(tmp_path, BASE, [1, 16, 2000000000000])), "--out", str(out),
                 "--no-report", "--no-progress"]) == 0
    table = [line for line in capsys.readouterr().out.splitlines() if "max |cycle error|" in line]
    assert len(table) == 3 and table[-1].startswith("  packets of 2000000000000: ")
    for mark in (": max", " against packets of ", " s, ", " frame"):
        assert len({line.index(mark) for line in table}) == 1, (mark, table)
    assert len({re.search(r"\d+ frames? \(", line).end() for line in table}) == 1, table
    assert json.loads((out / "granularity_summary.json").read_text())["one_packet"] == [2000000000000]


def test_the_line_s_words():
    """One pixel is said so; a frame with no phase the packet size cuts gives every size the same cycles."""
    from tlm.experiments.granularity import one_packet_line

    one = {"phase": "rcast.rays", "items": 1, "unit": "pixels"}
    assert one_packet_line([1, 4], one).startswith("packet sizes 1 and 4 are at or past the 1 pixel of the frame's")
    assert one_packet_line([1, 4, 16, 17, 18], {**one, "items": 17}).startswith("packet sizes 17 and 18 are ")
    assert one_packet_line([1, 4, 16], None) == (
        "packet sizes 1, 4 and 16: the frame has no pixel or photon phase for a packet size to cut (its BSP builds "
        "are a packet per level), so their cycles, errors and events are the same")
    assert one_packet_line([4], None) == "" == one_packet_line([4, 16, 17], {**one, "items": 17})


def test_the_study_keeps_its_warnings_and_the_report_lists_them(tmp_path, cache, capsys):
    """The furnace seen from outside, looking away (tests/test_probe_h394.py): the frame's own warnings and the
    one of a --set that sets nothing are in granularity_summary.json, and the report's warnings box lists them,
    naming the study and the file."""
    from tests.test_probe_h394 import _away

    _away(tmp_path)
    study = _study(tmp_path, {"scene": "furnace.yaml", "mode": "rcast", "resolution": [8, 8],
                              "arch": {"frames": 1}}, [1, 16])
    out = tmp_path / "g"
    assert main(["granularity", str(study), "--out", str(out), "--no-report", "--set", "render={}"]) == 0
    err = capsys.readouterr().err
    said = [line.removeprefix("tlm: warning: ") for line in err.splitlines() if line.startswith("tlm: warning: ")]
    kept = json.loads((out / "granularity_summary.json").read_text())["warnings"]
    assert "granularity: the camera faces nothing: none of its 256 eye rays hits the scene" in " ".join(kept), kept
    assert any("render={}" in line for line in kept), kept
    assert said and [" ".join(w.split()) for w in kept] == [" ".join(w.split()) for w in said], (kept, err)
    page = warnings_html(read([out]))
    for line in kept:
        assert line.replace("'", "&#x27;").replace('"', "&quot;") in page or line in page, (line, page)
    assert "granularity_summary.json" in page and f"the granularity study {out}" in page, page
