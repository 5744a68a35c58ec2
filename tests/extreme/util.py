"""Helpers of the extreme-case suite: scenes built in memory, rendering them, checks."""

from __future__ import annotations

import math
from pathlib import Path
from unittest import mock

import numpy as np

from tlm.config import config_from_dict
from tlm.experiments.run import RenderResult, render
from tlm.scenes.loader import scenes_dir
from tlm.scenes.model import Camera, Light, Material, Scene
from tlm.scenes.normals import crease_normals

WHITE = Material("white", "lambertian", albedo=(0.8, 0.8, 0.8))


def make_scene(parts: list[tuple[np.ndarray, Material]], lights: list[Light], eye, target, up=(0.0, 1.0, 0.0),
               vfov: float = 40.0, resolution=(16, 16), photons: int = 1000, name: str = "extreme",
               crease_angle: float = 0.0) -> Scene:
    """A scene from (triangles, material) parts; part ``i`` is named ``p<i>``.

    Materials are shared by name (the first part that uses a name defines it). Flat
    shading by default (``crease_angle`` 0): the analytic answers here are the facets'.
    """
    materials: list[Material] = []
    tri, mat_index, part = [], [], []
    for i, (t, m) in enumerate(parts):
        t = np.asarray(t, dtype=np.float64).reshape(-1, 3, 3)
        names = [x.name for x in materials]
        if m.name not in names:
            materials.append(m)
            names.append(m.name)
        tri.append(t)
        mat_index.append(np.full(t.shape[0], names.index(m.name), dtype=np.int32))
        part.append(np.full(t.shape[0], i, dtype=np.int32))
    camera = Camera(tuple(map(float, eye)), tuple(map(float, target)), tuple(map(float, up)), float(vfov),
                    int(resolution[0]), int(resolution[1]))
    return Scene(
        name=name,
        triangles=np.concatenate(tri),
        material_index=np.concatenate(mat_index),
        materials=tuple(materials),
        part=np.concatenate(part),
        part_names=tuple(f"p{i}" for i in range(len(parts))),
        normals=crease_normals(np.concatenate(tri), np.concatenate(part), crease_angle),
        lights=tuple(lights),
        camera=camera,
        photons=photons,
    )


def render_scene(scene: Scene, **cfg) -> RenderResult:
    """``tlm.experiments.run.render`` on an in-memory scene (the loader is bypassed)."""
    settings = {"spp": 1, **cfg.pop("render", {})}  # one eye ray through each pixel's centre unless asked
    config = config_from_dict({"scene": scene.name, "render": settings, **cfg})
    with mock.patch("tlm.experiments.loading.load_scene", return_value=scene):
        return render(config)


def cornell_copy(tmp_path: Path, transform: str | None = None, name: str = "cornell") -> Path:
    """``scenes/cornell.yaml`` copied into ``tmp_path`` with ``geometry: {builder: cornell}``
    and an optional ``transform:`` mapping (YAML flow text)."""
    lines = (scenes_dir() / "cornell.yaml").read_text().splitlines()
    out, skip = [], False
    for line in lines:
        if line.startswith("geometry:"):
            out.append("geometry: {builder: cornell}")
            skip = True
            continue
        if skip and line.startswith("  "):
            continue
        skip = False
        out.append(line)
    if transform is not None:
        out.append(f"transform: {transform}")
    path = tmp_path / f"{name}.yaml"
    path.write_text("\n".join(out) + "\n")
    return path


def rel_rms(a: np.ndarray, b: np.ndarray) -> float:
    """RMS of ``a - b`` over the RMS of ``b``."""
    return float(np.sqrt(np.mean((a - b) ** 2)) / max(np.sqrt(np.mean(b**2)), np.finfo(float).tiny))


def assert_clean(res: RenderResult) -> None:
    """Every frame finite and non-negative, every work count a non-negative int32 or int64."""
    for name, rad in res.radiance.items():
        assert np.isfinite(rad).all(), f"{name}: {(~np.isfinite(rad)).sum()} non-finite values"
        assert (rad >= 0.0).all(), f"{name}: negative radiance"
    assert np.isfinite(res.composite).all()
    for name, counts in res.work.items():
        for k, v in counts.items():
            assert v.dtype in (np.int32, np.int64) and (v >= 0).all(), f"{name}.{k}"


def point_light_radiance(points: np.ndarray, normals: np.ndarray, albedo: float, position, power: float):
    """Analytic direct radiance of a Lambertian point lit by an unoccluded point light:
    ``albedo / pi * P / (4 pi) * max(cos, 0) / d**2`` (normals facing the viewer's side)."""
    to = np.asarray(position, dtype=np.float64) - points
    d2 = np.sum(to * to, axis=1)
    cos = np.sum(to * normals, axis=1) / np.sqrt(d2)
    return albedo / math.pi * power / (4.0 * math.pi) * np.maximum(cos, 0.0) / d2


def rotation(axis, angle_deg: float) -> np.ndarray:
    """3x3 rotation matrix about ``axis`` (right-handed)."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    t = math.radians(angle_deg)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(t) * k + (1.0 - math.cos(t)) * (k @ k)


def no_nan_hits(h) -> None:
    for a in (h.t, h.u, h.v):
        assert not np.isnan(a).any()
    for f in ("node_visits", "leaves_crossed", "leaf_visits", "tri_tests"):
        c = getattr(h.counts, f)
        assert c.dtype == np.int64 and (c >= 0).all()
