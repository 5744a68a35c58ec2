"""h402 (review of bfd88fe): the items of the frame's largest phase, over several pipelines, are a tile's.

At 16x16 on 4 pipelines each tile holds 64 of the frame's 256 pixels, so packets of 64 and more run every phase as
one packet (their rows are the same, as the line says); but the line said "the 64 pixels of the frame's largest
phase (rcast.rays)", which reads as a wrong count of a 256-pixel frame's pass. It names the tiles now, and the
record keeps their number.
"""

from __future__ import annotations

import json
from pathlib import Path

from tlm.cli import main


def test_a_tiled_frame_s_largest_phase_is_said_to_be_a_tile_s(tmp_path: Path, cache, capsys):
    base = {"scene": "cornell", "mode": "reflect", "resolution": [16, 16], "render": {"spp": 2},
            "arch": {"frames": 1, "pipelines": 4}}
    study = tmp_path / "g.yaml"
    study.write_text(json.dumps({"base": base, "packet_sizes": [1, 32, 64, 256]}))
    out = tmp_path / "g"
    assert main(["granularity", str(study), "--out", str(out), "--no-report", "--no-progress"]) == 0
    line = ("packet sizes 64 and 256 are at or past the 64 pixels of the frame's largest phase (rcast.rays, in the "
            "largest of its 4 tiles): each phase runs as one packet at each, so their cycles, errors and events are "
            "the same")
    assert f"  {line}" in capsys.readouterr().out.splitlines()
    record = json.loads((out / "granularity_summary.json").read_text())
    assert record["largest_phase"] == {"phase": "rcast.rays", "items": 64, "unit": "pixels", "tiles": 4}
    assert record["one_packet"] == [64, 256] and record["notes"] == [line]
    rows = {r["packet_size"]: r for r in map(json.loads, (out / "granularity.jsonl").read_text().splitlines())}
    same = [(rows[s]["throughput"], rows[s]["latency"], rows[s]["simpy_events"], rows[s]["max_abs_rel_error"])
            for s in (32, 64, 256)]
    assert same[1] == same[2] != same[0]  # (what the line claims, and no more)
