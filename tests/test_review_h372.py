"""h372: review of da873c5 (granularity's frames column) and aaba627 (bench_tlm.py --run-on).

* A granularity study written before the ``frames`` column, reported beside one whose sizes ran different frame
  counts: the figure goes per frame for every study, and the old one's rows hold no seconds per frame. It was
  left out as "rows lack a packet size, seconds or error" (they lack none of those); it is left out saying why.
* ``bench_tlm.py --run-on`` ran its own fixed settings whatever ``--scene``, ``--mode``, ``--fine-frames`` or
  ``--skip-fine`` said, and ``--repeat 0`` timed nothing and then failed on a KeyError: both are refused (exit 2).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tlm.report.collect import Study
from tlm.report.tradeoff import granularity_figure


def _rows(frames):
    secs = (2.0, 0.5, 0.8)
    rows = []
    for n, e, s, f in zip((1, 64, 256), (0.0, 0.004, 0.05), secs, frames, strict=True):
        row = {"packet_size": n, "max_abs_rel_error": e, "simulate_seconds": s}
        if f is not None:
            row.update(frames=f, simulate_seconds_per_frame=round(s / f, 6))
        rows.append(row)
    return rows


def test_an_old_study_beside_one_drawn_per_frame_is_left_out_saying_why(tmp_path):
    new = Study("granularity", tmp_path / "new", _rows((16, 5, 16)))
    old = Study("granularity", tmp_path / "old", _rows((None, None, None)))
    notes: list[str] = []
    fig = granularity_figure([new, old], tmp_path, "g.png", notes)
    assert fig is not None
    said = " ".join(notes)
    assert "new: the packet sizes ran different frame counts" in said
    assert "old: written before granularity.csv's frames column" in said and "not drawn" in said
    assert "rows lack a packet size, seconds or error" not in said  # (they lack none of them)
    notes = []  # (alone, or beside a study whose sizes ran the same frames, it is drawn as before)
    even = Study("granularity", tmp_path / "even", _rows((5, 5, 5)))
    assert granularity_figure([even, old], tmp_path, "h.png", notes) is not None
    assert not any("frames column" in n or "not drawn" in n for n in notes)


@pytest.mark.parametrize("argv, said", [
    (["--run-on", "--scene", "ring"], "--scene would be ignored"),
    (["--run-on", "--mode", "rcast", "--skip-fine"], "--mode, --skip-fine would be ignored"),
    (["--run-on", "--fine-frames", "9"], "--fine-frames would be ignored"),
    (["--run-on", "--repeat", "0"], "--repeat: 0 is not a whole number >= 1"),
    (["--repeat", "-1", "--skip-fine"], "--repeat: -1 is not a whole number >= 1"),
])
def test_bench_refuses_flags_run_on_ignores_and_no_repeat(monkeypatch, capsys, argv, said):
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_tlm

    monkeypatch.setattr(bench_tlm, "run_on_case", lambda **_: pytest.fail("ran with a refused flag"))
    monkeypatch.setattr(bench_tlm, "render", lambda *_: pytest.fail("ran with a refused flag"))
    with pytest.raises(SystemExit) as e:
        bench_tlm.main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert said in err and len(err.strip().splitlines()[-1]) > 0
