"""The blur warning of ``tlm error-vs-cost`` (h483): once per study, not once per point.

``tlm run`` warns where its photon-map frame is measured against a reference whose k-NN kernel gathers over
more than :data:`~tlm.experiments.run_warnings.BLUR_RATIO` times the area of the run's on a photon map
(:func:`~tlm.experiments.run_warnings.blur_warnings`: the error may measure the reference's blur more than the
run's noise). A study's points share one reference and differ in their photons and kernels, so
:class:`StudyBlur` weighs each point as that warning does (:func:`~tlm.experiments.run_warnings.widest_map`)
and, once every point ran, says one line: how many points pass the ratio, and the worst of them (its photons,
the map, the ratio and the ``reference.photons`` to give, which brings every point within the ratio).
"""

from __future__ import annotations

import math
from typing import Any

from tlm.config import RunConfig
from tlm.experiments.run_warnings import BLUR_RATIO, reference_share, widest_map


class StudyBlur:
    """Each point's widest map against the study's reference ``key`` (:meth:`add`, as the point's photons are
    traced), and the study's one line on them (:meth:`line`, :meth:`said`). ``scene_photons``: the scene's
    photons, what a null ``reference.photons`` takes. ``off``: no line (a black reference, said so already:
    there is no blur of it to measure)."""

    def __init__(self, scene_photons: int | None, key: str, off: bool = False):
        self.scene_photons, self.key, self.off = scene_photons, key, off
        self.seen = 0  # the points weighed
        self.passed: list[tuple] = []  # (ratio, point, factors, cfg, widest_map's tuple) of each past the ratio

    def add(self, i: int, factors: str, cfg: RunConfig, photons: Any) -> None:
        """Weigh point ``i`` (its ``factors``, its config and the photon maps it traced and gathered)."""
        self.seen += 1
        stats = photons.stats()  # (what results.json's photons records: tlm.experiments.run_warnings.emitted_photons)
        wide = widest_map(cfg, {"emitted": int(stats["emitted"]), "caustic": int(stats["caustic"])},
                          self.scene_photons)
        if wide is not None and wide[0] > BLUR_RATIO:
            self.passed.append((wide[0], i, factors, cfg, wide))

    def line(self) -> str | None:
        """The study's line on the points past the ratio (None: none, or ``off``), naming the worst."""
        if self.off or not self.passed:
            return None
        _, i, factors, cfg, (ratio, name, run, ref, k, how, n_ref, total) = max(self.passed, key=lambda p: p[0])
        count = len(self.passed)
        its = "its" if count == 1 else "their"
        return (f"error-vs-cost: {count} of the {self.seen} points {'is' if count == 1 else 'are'} measured against "
                f"a reference {self.key} whose k-NN rounds gather over more than {BLUR_RATIO}x the area of the "
                f"point's on a photon map, so {its} rmse and rel_mse may measure the reference's blur more than "
                f"{its} noise; the worst, point {i} ({factors}): its {name} map gets {run} of the {total} photons it "
                f"emits, and that map of the reference gets {reference_share(cfg, ref, n_ref)}: each k-NN round of "
                "the reference "
                f"({cfg.reference.k_nearest} photons: reference.k_nearest) "
                + (f"gathers over {float(ratio):.2f}x the area of its gathers of {k} ({how})" if how else
                   f"gathers in a map {float(ratio):.2f}x sparser than its")
                + f"; raise the base's reference.photons to {math.ceil(n_ref * ratio / BLUR_RATIO)} or more (at most "
                f"{BLUR_RATIO}x every point's on its map) and compute it again with 'tlm reference'")

    def said(self, say, rows: list[dict]) -> list[dict]:
        """``rows``, as they are, once ``say`` got :meth:`line` (where there is one): run_study's ``finish``."""
        line = self.line()
        if line is not None:
            say(line)
        return rows
