"""The report names each sweep so that two sweeps whose folders have one name can be told
apart (``a/sw`` and ``b/sw``: the shortest tail of their paths that differs), in figure
titles, the sweeps section's headings and notes, the summary's findings and its points'
labels; a sweep whose name no other sweep has keeps its plain name."""

from __future__ import annotations

from pathlib import Path

from tests.sweep_folders import start, write_point, write_rows
from tlm.report.collect import read
from tlm.report.names import path_labels
from tlm.report.summary import sweep_findings
from tlm.report.sweeps import sweeps_section

PACKETS = (1, 16, 256)


def sweep_folder(folder: Path, scale: float, results: bool = False) -> Path:
    """A sweep over the packet size whose point p ran at ``scale * (100 + p)`` FPS; its
    sweep.yaml lists a fourth point that has no row yet (an interrupted sweep). ``results``:
    each point also has a results folder."""
    grid = {"arch.packet_size": list(PACKETS)}
    points = [{"hash": f"h{i:02d}"} for i in range(len(PACKETS) + 1)]
    start(folder, {"sweep": "s3.yaml", "description": "16x16 Cornell RCast", "grid": grid, "points": points})
    rows = []
    for i, p in enumerate(PACKETS):
        fps = scale * (100.0 + p)
        rows.append({"point": i, "hash": f"h{i:02d}", "status": "ok", "arch.packet_size": p, "scene": "cornell",
                     "mode": "rcast", "fps": fps, "cycles.throughput": 6e8 / fps})
        if results:
            write_point(folder, f"h{i:02d}", {"timing": {}, "scene": {"name": "cornell"}, "mode": "rcast", "fps": fps,
                                              "factors": {"arch.packet_size": p}})
    write_rows(folder, rows)
    return folder


def sections(tmp_path: Path, *names: tuple[str, float]):
    """The report's inputs and sweeps section (into ``tmp_path/rep``) of a sweep folder
    ``tmp_path/coll/<name>`` at FPS scale ``scale`` for each ``(name, scale)``."""
    inputs = read([sweep_folder(tmp_path / "coll" / name, scale) for name, scale in names])
    (tmp_path / "rep").mkdir()
    return inputs, sweeps_section(inputs, tmp_path / "rep")


def test_two_sweeps_named_alike_are_told_apart_in_titles_headings_notes_and_findings(tmp_path):
    inputs, sec = sections(tmp_path, ("a/sw", 1.0), ("b/sw", 3.0))
    assert [sw.label for sw in inputs.sweeps] == ["a/sw", "b/sw"]
    assert [f.title for f in sec.figures] == ["a/sw: FPS against arch.packet_size",
                                              "b/sw: FPS against arch.packet_size"]
    assert "<h3>a/sw</h3>" in sec.html and "<h3>b/sw</h3>" in sec.html and "<h3>sw</h3>" not in sec.html
    unfinished = [n for n in sec.notes if "of its 4 points have a row" in n]
    assert [n.split(":")[0] for n in unfinished] == ["a/sw", "b/sw"], sec.notes
    findings = sweep_findings(inputs)
    assert len(findings) == 2
    assert findings[0].startswith("<b>Sweep a/sw</b>") and findings[1].startswith("<b>Sweep b/sw</b>"), findings


def test_a_sweep_named_alone_keeps_its_plain_name(tmp_path):
    inputs, sec = sections(tmp_path, ("a/sw", 1.0), ("b/other", 2.0))
    assert [sw.label for sw in inputs.sweeps] == ["sw", "other"]
    assert sec.figures[0].title == "sw: FPS against arch.packet_size"
    assert "<h3>sw</h3>" in sec.html
    assert sweep_findings(inputs)[0].startswith("<b>Sweep sw</b>")


def test_the_points_of_two_sweeps_named_alike_are_labelled_by_their_sweeps_label(tmp_path):
    a = sweep_folder(tmp_path / "a" / "sw", 1.0, results=True)
    b = sweep_folder(tmp_path / "b" / "sw", 3.0, results=True)
    inputs = read([a, b])
    assert [r.label for r in inputs.runs] == ["a/sw #0", "a/sw #1", "a/sw #2", "b/sw #0", "b/sw #1", "b/sw #2"]
    alone = read([a])
    assert [r.label for r in alone.runs] == ["sw #0", "sw #1", "sw #2"]


def test_path_labels_take_the_shortest_tail_that_differs():
    paths = [Path("/x/a/sw"), Path("/y/a/sw"), Path("/z/c/sw"), Path("/q/other")]
    assert path_labels(paths) == ["x/a/sw", "y/a/sw", "c/sw", "other"]
    assert path_labels([Path("/a/sw"), Path("/b/a/sw")]) == ["/a/sw", "b/a/sw"]  # (one path ends the other)
    assert path_labels([Path("/a/sw"), Path("/a/sw")]) == ["sw", "sw (2)"]  # (one folder read twice)
    assert path_labels([Path("sw")]) == ["sw"]
