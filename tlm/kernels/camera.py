"""Primary ray generation: a pinhole look-at camera, one ray through each pixel centre.

Pixel ids are row-major from the top-left corner: ``pixel = row * width + col``. Any
subset of pixel ids (a packet) gives exactly the rays it gives inside the full image.
"""

from __future__ import annotations

import math

import numpy as np

from tlm.scenes.model import Camera


def camera_basis(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit forward, right and up vectors of the camera (right-handed, up = image up)."""
    eye = np.asarray(camera.eye, dtype=np.float64)
    fwd = np.asarray(camera.target, dtype=np.float64) - eye
    fwd = fwd / np.linalg.norm(fwd)
    right = np.cross(fwd, np.asarray(camera.up, dtype=np.float64))
    right = right / np.linalg.norm(right)
    up = np.cross(right, fwd)
    return fwd, right, up


def primary_rays(camera: Camera, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eye rays through the centres of ``pixels``.

    pixels : (p,) int64 pixel ids.
    Returns ``origins`` (p, 3) (all the eye) and unit ``directions`` (p, 3).
    """
    pixels = np.asarray(pixels, dtype=np.int64)
    w, h = camera.width, camera.height
    row, col = np.divmod(pixels, w)
    half_h = math.tan(math.radians(camera.vfov) / 2.0)
    half_w = half_h * w / h
    x = (2.0 * (col + 0.5) / w - 1.0) * half_w
    y = (1.0 - 2.0 * (row + 0.5) / h) * half_h
    fwd, right, up = camera_basis(camera)
    d = fwd[None, :] + x[:, None] * right[None, :] + y[:, None] * up[None, :]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(np.asarray(camera.eye, dtype=np.float64), d.shape).copy()
    return o, d
