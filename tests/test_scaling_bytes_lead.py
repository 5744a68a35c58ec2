"""A scaling study (eq. 5.2) of a scene in a folder whose name is bytes not UTF-8 (``dir_\\xff``, as Python reads it
``dir_\\udcff``): ``tlm scaling`` writes its rows (it ended as an internal error: the scene's hash of
``scene.encode("utf-8")``), and ``tlm report`` draws its figure (eq52.csv holds the path escaped, eq52.json as it is:
the fits matched no row and the figure was left out without a word)."""

from __future__ import annotations

import os
from pathlib import Path

from tlm.cli import main

DIR = os.fsdecode(b"dir_\xff")
SCENE = """geometry: [{shape: plane, params: {size: [4, 4]}}]
materials: {g: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}
default_material: g
lights: [{type: point, position: [0, 3, -2], power: [40, 40, 40]}]
camera: {eye: [0, 1, -5], target: [0, 0, 0], vfov: 40}
resolution: [8, 8]
"""
SWEEP = """description: N
base: {scene: s.yaml, mode: rcast, seed: 0, resolution: [8, 8], render: {light_samples: 1, spp: 1},
       arch: {frames: 1, trace: false}}
grid:
  arch.pipelines: [1, 2, 4]
"""


def test_a_scaling_study_of_a_scene_in_a_folder_not_utf8_has_its_figure(tmp_path, cache, monkeypatch):
    d = tmp_path / DIR
    d.mkdir()
    (d / "s.yaml").write_text(SCENE, encoding="utf-8")
    (d / "sw.yaml").write_text(SWEEP, encoding="utf-8")
    monkeypatch.chdir(tmp_path)  # (the scene named from here: dir_\udcff/s.yaml)
    assert main(["sweep", f"{DIR}/sw.yaml", "--out", f"{DIR}/sw", "--no-report", "--no-progress"]) == 0
    assert main(["scaling", f"{DIR}/sw", "--out", f"{DIR}/sc", "--no-report"]) == 0
    assert main(["report", f"{DIR}/sc", "--out", "rep"]) == 0
    assert [p.name for p in Path("rep").glob("scaling_*.png")], sorted(p.name for p in Path("rep").iterdir())
