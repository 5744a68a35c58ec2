"""The ground truth's own noise in an error-vs-cost study's ``truth_*`` columns: Mitsuba 3's path
tracer at ``--truth-spp`` samples per pixel is a Monte Carlo estimate itself, so each ``truth_*`` error
holds its noise beside the composite's error. Below :data:`TRUTH_SPP_LOW` samples that noise may be most
of ``truth_rel_mse`` (which then falls with more truth samples alone): the study warns
(:func:`truth_noise_words`), and the report says the truth's samples wherever it quotes a ``truth_*``.

The ground truth itself (:class:`Truth`: the cached one, without Mitsuba where it is cached, or computed
now) and a composite's ``truth_*`` errors (:func:`truth_error`) are here too, moved out of error_cost.py,
which imports them from here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tlm.errors import InputError

TRUTH_SPP_LOW = 1024  # samples per pixel of the ground truth below which its noise is said (the default: 4096)
# A ground truth whose luminance peaks below this is scaled, with the composite, to a brightest value of 1 before FLIP:
# flip_evaluator ends the whole process (C++ abort, "Start exposure must be smaller than stop exposure!") on a
# reference whose luminance Y (FLIP_LUMINANCE) peaks below 2**-23, where its start exposure log2(x / Y_max) passes its
# stop exposure log2(x / max(Y_median, 2**-23)) (h394). Only such a truth: HDR-FLIP is not the same for both images
# scaled where that median is held at 2**-23 (half the truth dark: a faint truth's exposure range is shorter), so a
# truth FLIP measures as it is keeps FLIP's own number (h397); twice the bound, for float32's rounding of Y
FLIP_FAINT = 2.0 ** -22
FLIP_LUMINANCE = (0.2126729, 0.7151522, 0.0721750)  # (linear sRGB's Y, as flip_evaluator computes it)


def truth_noise_words(spp) -> str:
    """A sentence on the ground truth's noise where ``spp`` (its samples per pixel) is below
    :data:`TRUTH_SPP_LOW`, else ""."""
    if isinstance(spp, bool) or not isinstance(spp, int | float) or not 0 < spp < TRUTH_SPP_LOW:
        return ""
    return (f"The ground truth has only {int(spp)} samples per pixel: its own noise is part of every truth_* error, "
            f"and at so few may be most of it (truth_rel_mse would fall with more truth samples alone); "
            f"--truth-spp {TRUTH_SPP_LOW} or more (the default, 4096) keeps it small.")


@dataclass(frozen=True)
class Truth:
    """What the composites are measured against besides our own reference: Mitsuba 3's
    path tracer (:mod:`tlm.oracle.mitsuba`) at ``spp`` samples per pixel, or nothing
    (``spp`` 0, or none cached and Mitsuba not installed: ``reason`` says which). A cached one
    is used without Mitsuba; FLIP needs ``flip-evaluator``, without which ``truth_flip`` alone is
    empty (``flip_missing`` says why)."""

    spp: int = 4096

    def load(self, frame, g, progress=None) -> tuple[np.ndarray | None, dict]:
        """The ground truth of the frame's scene (:func:`tlm.oracle.mitsuba.composite_truth`:
        the path tracer, with the particle tracer at the diffuse pixels where a point
        light's caustics would be missing), or None and why not. ``progress`` gets a line: that
        it is computing now (it may take minutes) and whether it is then cached, or that it was
        found cached; and one where FLIP cannot be measured."""
        from tlm.caches import cache_problem
        from tlm.oracle import mitsuba as oracle
        from tlm.render.passes import diffuse_pixels

        scene = frame.scene
        if self.spp <= 0:  # (tlm.error_vs_cost's note: truth_spp=0)
            return None, {"available": False, "reason": "not asked for (--truth-spp 0)"}
        diffuse = diffuse_pixels(frame, g).reshape(scene.camera.height, scene.camera.width)
        what = f"Mitsuba 3 path tracer, {self.spp} spp" + (
            f", and its particle tracer at the diffuse pixels ({oracle.PTRACER_FACTOR * self.spp} light paths per "
            "pixel)" if oracle.needs_light_tracing(scene) else "")
        found = oracle.composite_truth(scene, diffuse, spp=self.spp, compute=False)  # (no Mitsuba needed)
        if found is None:
            try:
                oracle.mitsuba_version()  # (computing it needs Mitsuba)
            except InputError as e:
                return None, {"available": False, "reason": f"{e}, and none is cached for this scene at {self.spp} spp"}
            if progress is not None:  # (a cache that cannot be written: tlm.caches says which, and why)
                why = cache_problem(oracle.cache_dir())
                kept = ("it is then cached for every later study of this scene at this spp" if why is None
                        else f"the cache cannot take it ({why}): it is computed for this study only")
                progress(f"computing the ground truth (not cached): {what}; this may take minutes; {kept}")
            found = oracle.composite_truth(scene, diffuse, spp=self.spp)
        elif progress is not None:
            progress(f"ground truth: {what}, found cached in {oracle.cache_dir()}")
        image, meta = found
        meta = {"available": True, **meta}
        missing = flip_missing()
        if missing is not None:
            meta["flip_missing"] = missing
            if progress is not None:
                progress(f"the truth_flip column is empty: {missing}; truth_rmse and truth_rel_mse are filled")
        return np.asarray(image, dtype=np.float64), meta


def black_lines(reference: np.ndarray, truth: np.ndarray | None, key: str) -> list[str]:
    """A warning line for our reference (of key ``key``) and for the ground truth where either is black (every
    pixel 0), which leaves a column empty in every row, said rather than left unsaid (h394: a camera that sees
    nothing lit; ``tlm run`` of the base says why, as its own warnings)."""
    lines = []
    if not np.any(reference):
        lines.append(f"the photon-map reference {key} is black (every pixel 0): every row's rel_mse is empty (no "
                     "squared reference to divide by); 'tlm run' of the base says why (its warnings)")
    if truth is not None and not np.any(truth > 0):
        lines.append("the ground truth is black (every pixel 0): every row's truth_rel_mse and truth_flip are empty; "
                     "'tlm run' of the base says why (its warnings)")
    return lines


def flip_missing() -> str | None:
    """Why FLIP cannot be measured (its optional package ``flip_evaluator`` does not import), or None."""
    from tlm.oracle.mitsuba import INSTALL_HINT

    try:
        import flip_evaluator  # noqa: F401
    except ImportError:
        return f"FLIP needs the optional package flip-evaluator ({INSTALL_HINT})"
    return None


def truth_error(composite: np.ndarray, truth: np.ndarray | None, keep: np.ndarray,
                flip: bool = True) -> dict[str, float | None]:
    """The composite's RMSE, relative MSE (sum of squared error over sum of squared truth, as
    ``rel_mse`` against our reference) over the pixels ``keep`` ((height, width) bool: away
    from the lights seen directly or across the pixel's square, :func:`tlm.oracle.mitsuba.truth_mask`) and mean
    HDR-FLIP over the whole image (:func:`tlm.oracle.mitsuba.flip`: ``flip_evaluator``'s HDR mode, its
    exposure range from the truth, ACES tone mapper, 67 pixels per degree; None where ``flip`` is
    False: :func:`flip_missing`), against the ground truth (None without one)."""
    if truth is None:
        return {"truth_rmse": None, "truth_rel_mse": None, "truth_flip": None}
    from tlm.experiments.reference import image_error
    from tlm.oracle import mitsuba as oracle

    img = composite.reshape(truth.shape)
    err = image_error(img[keep], truth[keep])  # the same measures as against our own reference
    return {"truth_rmse": err["rmse"], "truth_rel_mse": err["rel_mse"],
            "truth_flip": _flip(img, truth, oracle.flip) if flip else None}


def _flip(img: np.ndarray, truth: np.ndarray, flip) -> float | None:
    """``flip(img, truth)``, or None where the truth is black (FLIP has no exposure range to take from
    it); a truth too faint for FLIP (its luminance peaking below :data:`FLIP_FAINT`) is scaled, with ``img``, so
    that its brightest value is 1 first."""
    lit = np.maximum(truth, 0.0)
    peak = float(np.max(lit, initial=0.0))
    if peak == 0.0:  # (a camera that sees nothing lit: flip_evaluator would abort the process)
        return None
    if float(np.max(lit @ np.array(FLIP_LUMINANCE), initial=0.0)) >= FLIP_FAINT:
        return flip(img, truth)
    return flip(img / peak, truth / peak)

