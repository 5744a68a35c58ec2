"""Radiance to pictures: exposure, the sRGB curve and 8-bit PNG files."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def auto_exposure(radiance: np.ndarray, percentile: float = 99.5) -> float:
    """Scale that maps the given percentile of luminance to 1 (1.0 for a black image, or one whose
    percentile is not finite: infinite radiance there). Quietly: numpy's warnings of inf - inf, in the
    luminance or between the percentile's neighbours, are of NaNs this reads as above."""
    with np.errstate(invalid="ignore"):
        lum = radiance @ np.array([0.2126, 0.7152, 0.0722])
        lit = lum[lum > 0]
        if lit.size == 0:
            return 1.0
        level = float(np.percentile(lit, percentile))
    return 1.0 / level if level > 0 and np.isfinite(level) else 1.0


SRGB_BLOCK = 1 << 16  # values converted together: the temporaries of a block, not of the image


def to_srgb8(radiance: np.ndarray, exposure: float) -> np.ndarray:
    """(H, W, 3) linear radiance -> (H, W, 3) uint8 sRGB, clipped.

    Converted in blocks of :data:`SRGB_BLOCK` values (each value on its own), so a
    1080p frame needs no whole-image float64 temporaries. A value that ``exposure`` takes past the
    largest float (``render.exposure: 1e308``) is white, as any past 1 is, quietly: the run says it once
    (:func:`overflow_line`)."""
    radiance = np.asarray(radiance)
    flat = radiance.reshape(-1)
    out = np.empty(flat.shape[0], dtype=np.uint8)
    for a in range(0, flat.shape[0], SRGB_BLOCK):
        b = min(a + SRGB_BLOCK, flat.shape[0])
        with np.errstate(over="ignore", invalid="ignore"):  # (inf: white, below; inf * 0, NaN: black)
            x = np.clip(np.nan_to_num(flat[a:b] * exposure, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
        s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
        out[a:b] = np.round(s * 255.0).astype(np.uint8)
    return out.reshape(radiance.shape)


def overflow_line(radiance: np.ndarray, exposure: float, auto: np.ndarray | None = None,
                  key: str = "render.exposure") -> str | None:
    """The line a run warns of where ``exposure`` (``key``'s value) takes a pixel of ``radiance`` (H, W, 3) past the
    largest float: how many pixels, shown white (as any past 1 is), and the exposure that would show the image,
    :func:`auto_exposure`'s of ``auto`` (the pixels it sets the exposure by: a run's surfaces; None: all); None
    where none overflows."""
    rad = np.asarray(radiance).reshape(-1, 3)
    with np.errstate(over="ignore", invalid="ignore"):
        over = int(np.count_nonzero(np.isinf(rad.max(axis=1).astype(np.float64) * exposure)))
    if not over:
        return None
    return (f"{key} = {exposure:g} takes the radiance of {over} of {rad.shape[0]} pixels past the largest float: "
            f"they are white in images/*.png, as any past 1 is; an exposure of about "
            f"{auto_exposure(rad if auto is None else np.asarray(auto).reshape(-1, 3)):.3g} "
            f"shows the image (null: that, auto)")


def write_png(path: Path, rgb8: np.ndarray) -> None:
    from PIL import Image

    Image.fromarray(np.ascontiguousarray(rgb8)).save(path, optimize=False)
