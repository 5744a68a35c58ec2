"""The ground truth's own noise in an error-vs-cost study's ``truth_*`` columns: Mitsuba 3's path
tracer at ``--truth-spp`` samples per pixel is a Monte Carlo estimate itself, so each ``truth_*`` error
holds its noise beside the composite's error. Below :data:`TRUTH_SPP_LOW` samples that noise may be most
of ``truth_rel_mse`` (which then falls with more truth samples alone): the study warns
(:func:`truth_noise_words`), and the report says the truth's samples wherever it quotes a ``truth_*``.
"""

from __future__ import annotations

TRUTH_SPP_LOW = 1024  # samples per pixel of the ground truth below which its noise is said (the default: 4096)


def truth_noise_words(spp) -> str:
    """A sentence on the ground truth's noise where ``spp`` (its samples per pixel) is below
    :data:`TRUTH_SPP_LOW`, else ""."""
    if isinstance(spp, bool) or not isinstance(spp, int | float) or not 0 < spp < TRUTH_SPP_LOW:
        return ""
    return (f"The ground truth has only {int(spp)} samples per pixel: its own noise is part of every truth_* error, "
            f"and at so few may be most of it (truth_rel_mse would fall with more truth samples alone); "
            f"--truth-spp {TRUTH_SPP_LOW} or more (the default, 4096) keeps it small.")
