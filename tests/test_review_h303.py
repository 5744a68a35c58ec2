"""Review of 11bb5b8 (h303): a copied project's cached frame and its warnings.

1. A cached frame read by a copy of its project in another folder has the scene's notes moved to the copy's
   folders (tlm.experiments.frame_scenes.moved_line, tlm.experiments.frames._here), and no other line: a
   material's name that holds a path above the scene's folder (an MTL's ``newmtl /proj/rig/wood``) is the
   copy's material's name too, and 11bb5b8 moved it (``'/proj/deeper/rig/wood'``, a material no file names).
   The cached summary counts the notes it begins with (``notes``).
2. A cached line with a NUL mark of no folder (a sidecar's) is kept, not an IndexError.
3. The marks of a scene's folder are made once, not once per note (5,000 notes 8 folders deep: 0.32 s, 8x the
   hash of 300k triangles; 0.05 s now).
4. A programs table from a pipe is read once in a process (tlm.arch.costs.load_programs): each case of
   ``tlm extreme`` read it again, and found it empty.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tlm.arch.costs import DEFAULT_PATH, load_programs
from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.experiments import frame_scenes, frames
from tlm.experiments.frame_scenes import marked_line, moved_line

ELL = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nf 2 3 4 5 6 1\n"


def _project(root: Path, material: str) -> Path:
    """``root/a/s.yaml``, its mesh ``../m/ell.obj`` (a note: a concave face) of the MTL material ``material``
    (its texture not rendered: a warning naming the material)."""
    (root / "a").mkdir(parents=True)
    (root / "m").mkdir()
    (root / "m" / "ell.obj").write_text(f"mtllib ell.mtl\nusemtl {material}\n{ELL}")
    (root / "m" / "ell.mtl").write_text(f"newmtl {material}\nKd 0.5 0.5 0.5\nmap_Kd wood.png\n")
    (root / "a" / "s.yaml").write_text(yaml.safe_dump({
        "geometry": [{"mesh": "../m/ell.obj"}],
        "lights": [{"type": "point", "position": [0.3, 0.3, 2.0], "power": [1.0] * 3}],
        "camera": {"eye": [0.3, 0.3, 3.0], "target": [0.3, 0.3, 0.0], "up": [0, 1, 0], "vfov": 40.0},
        "resolution": [8, 8]}))
    return root / "a" / "s.yaml"


def test_a_copy_s_cached_frame_moves_only_the_scene_s_notes_not_a_material_name_holding_a_path(tmp_path, cache):
    """11bb5b8: the copy's warning named the material ``<tmp>/deeper/rig/wood`` (a folder above its scene's,
    moved as a note's path is); its material is ``<tmp>/rig/wood``, as the first copy's."""
    material = f"{tmp_path}/rig/wood"
    got = []
    for p in ("p1", "deeper/p2"):
        cfg = config_from_dict({"scene": str(_project(tmp_path / p, material)), "mode": "rcast",
                                "resolution": [8, 8]})
        got.append(frames.cached_render(cfg))
    assert [g.cached for g in got] == [False, True]
    for g, p in zip(got, ("p1", "deeper/p2")):
        (note,) = [w for w in g.summary["warnings"] if "not convex" in w]
        assert note.startswith(f"{tmp_path}/{p}/m/ell.obj: "), note  # (the note: moved to the copy's mesh)
        (said,) = [w for w in g.summary["warnings"] if "what tlm does not render" in w]
        assert f"({material!r})" in said, said
    assert [g.summary["notes"] for g in got] == [1, 1]
    side = json.loads((frames.cache_dir() / f"{got[0].key}.json").read_text())
    assert side["notes"] == 1 and "not convex" in side["warnings"][0]


def test_a_sidecar_whose_notes_count_is_no_count_of_its_warnings_is_damaged():
    summary = {"scene": {}, "plan": {}, "primary": {}, "work": {}, "photons": None, "error": None,
               "warnings": ["a"], "host_seconds": {}, "pmap": None}
    assert frames.summary_problem(summary) is None  # (an entry of before the count: its lines all moved)
    for bad in (-1, 2, True, "1"):
        assert frames.summary_problem({**summary, "notes": bad}) is not None, bad
    assert frames.summary_problem({**summary, "notes": 1}) is None


def test_a_cached_line_with_a_mark_of_no_folder_is_kept():
    """11bb5b8: IndexError (mark 9 of a folder two deep)."""
    assert moved_line("x \x009s\x00 y /a/s/q", "/a/s", "/b/c/s") == "x \x009s\x00 y /b/c/s/q"


def test_the_marks_of_a_folder_are_made_once_for_all_its_notes(monkeypatch):
    """11bb5b8 showed each folder above the scene's again for each note (8 x 2 x 1,000 calls here)."""
    calls = []
    shown = frame_scenes.path_shown
    monkeypatch.setattr(frame_scenes, "path_shown", lambda p: calls.append(p) or shown(p))
    folder = "/h303/u/projects/thesis/data/scenes/big/a"
    lines = [f"{folder}/../m/part{i}.obj: note {i}, /h303/u/x{i}.obj" for i in range(1000)]
    assert [marked_line(s, folder, tagged=False) for s in lines] == \
        [f"\0{0}\0../m/part{i}.obj: note {i}, \0{6}\0x{i}.obj" for i in range(1000)]
    assert len(calls) <= 2 * 8, len(calls)


# ------------------------------------------------------------------ a programs table from a pipe, read once


def test_a_programs_table_from_a_pipe_is_read_once_and_given_again(pipes):
    """11bb5b8 read the pipe again for each case of a study (``tlm extreme <(...) --set arch.programs=<(...)``:
    its second case 'vertex: missing section', the pipe's text gone)."""
    given = pipes(DEFAULT_PATH.read_text())
    first, again, default = load_programs(given), load_programs(given), load_programs()
    assert (again.jobs, again.scale, again.source) == (first.jobs, first.scale, first.source) == \
        (default.jobs, default.scale, str(given))
    other = pipes(DEFAULT_PATH.read_text().replace("calibration", "calibration_typo", 1))
    with pytest.raises(InputError, match="calibration_typo"):  # (another pipe: read, not the first one's)
        load_programs(other)


def test_an_extreme_study_with_a_programs_table_from_a_pipe_runs_each_case(tmp_path, monkeypatch, cache, pipes):
    from tlm.cli import main

    monkeypatch.chdir(tmp_path)
    case = "{{name: {0}, category: geometry, expect: x, config: {{scene: cornell, mode: rcast, resolution: [8, 8], " \
           "render: {{spp: {1}}}}}, checks: [finite]}}"
    (tmp_path / "x.yaml").write_text(f"cases:\n  - {case.format('a', 1)}\n  - {case.format('b', 2)}\n")
    assert main(["extreme", "x.yaml", "--set", f"arch.programs={pipes(DEFAULT_PATH.read_text())}", "--out", "o",
                 "--no-progress", "--no-report"]) == 0
