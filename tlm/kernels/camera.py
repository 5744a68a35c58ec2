"""Primary ray generation: a pinhole look-at camera, ``spp`` rays per pixel.

Pixel ids are row-major from the top-left corner: ``pixel = row * width + col``. Any
subset of pixel ids (a packet) gives exactly the rays it gives inside the full image.

With one sample per pixel the ray goes through the pixel's centre (the thesis's ray
casting). With ``spp > 1`` the pixel is a box filter of ``spp`` jittered sub-samples:
stratified on a ``g x g`` grid when ``spp = g * g`` is a square, else uniform in the
pixel; the jitter is a hash of (pixel, sample) (:func:`tlm.kernels.shade.hash_uniform`), so a
pixel's rays never depend on its packet, nor on the run's seed (every run of a scene, and
its references, see the same sub-pixel positions; the seed varies light samples and photons).
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


def subpixel_offsets(pixels: np.ndarray, spp: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(p * spp,) x and y offsets in [0, 1) inside each pixel, pixel-major (a pixel's samples
    consecutive): the centre for ``spp == 1``, stratified jitter for a square ``spp``."""
    from tlm.kernels.shade import hash_uniform

    pixels = np.asarray(pixels, dtype=np.int64)
    if spp == 1:
        half = np.full(pixels.shape[0], 0.5)
        return half, half.copy()
    s = np.tile(np.arange(spp, dtype=np.int64), pixels.shape[0])
    pix = np.repeat(pixels, spp)
    ju = hash_uniform(seed, pix, s, 0x5A)
    jv = hash_uniform(seed, pix, s, 0x5B)
    g = math.isqrt(spp)
    if g * g == spp:
        return ((s % g) + ju) / g, ((s // g) + jv) / g
    return ju, jv


def primary_rays(camera: Camera, pixels: np.ndarray, spp: int = 1, seed: int = 0x5EED) -> tuple[np.ndarray, np.ndarray]:
    """Eye rays of ``pixels``: through the centres (``spp == 1``) or ``spp`` sub-samples each.

    pixels : (p,) int64 pixel ids.
    Returns ``origins`` (p * spp, 3) (all the eye) and unit ``directions`` (p * spp, 3),
    pixel-major.
    """
    pixels = np.asarray(pixels, dtype=np.int64)
    w, h = camera.width, camera.height
    fx, fy = subpixel_offsets(pixels, spp, seed)
    row, col = np.divmod(np.repeat(pixels, spp), w)
    half_h = math.tan(math.radians(camera.vfov) / 2.0)
    half_w = half_h * w / h
    x = (2.0 * (col + fx) / w - 1.0) * half_w
    y = (1.0 - 2.0 * (row + fy) / h) * half_h
    fwd, right, up = camera_basis(camera)
    d = fwd[None, :] + x[:, None] * right[None, :] + y[:, None] * up[None, :]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(np.asarray(camera.eye, dtype=np.float64), d.shape).copy()
    return o, d
