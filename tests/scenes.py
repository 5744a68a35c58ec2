"""Small scenes that tests build in ``tmp_path``."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import trimesh

from tlm.scenes.shapes import uv_sphere


def sphere_scene(tmp_path: Path, albedo: float = 0.5, n_seg: int = 48, n_rings: int = 24) -> Path:
    """A closed diffuse unit sphere around a point light of intensity pi (power 4 pi^2)."""
    tri = uv_sphere((0.0, 0.0, 0.0), 1.0, n_seg, n_rings)
    mesh = trimesh.Trimesh(vertices=tri.reshape(-1, 3), faces=np.arange(tri.shape[0] * 3).reshape(-1, 3),
                           process=False)
    mesh.export(tmp_path / "sphere.ply")
    p = 4.0 * math.pi**2
    (tmp_path / "furnace.yaml").write_text(f"""
name: furnace
geometry: {{mesh: sphere.ply}}
materials: {{grey: {{type: lambertian, albedo: [{albedo}, {albedo}, {albedo}]}}}}
default_material: grey
lights: [{{type: point, position: [0.0, 0.0, 0.0], power: [{p}, {p}, {p}]}}]
camera: {{eye: [0.0, 0.0, 0.0], target: [0.0, 0.0, 1.0], up: [0.0, 1.0, 0.0], vfov: 60.0}}
resolution: [24, 24]
photons: 20000
""")
    return tmp_path / "furnace.yaml"
