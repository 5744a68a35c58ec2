"""Schedulers of a frame's tiled stages, selected by ``arch.scheduler``.

A scheduler says how many tiles a stage is cut into (:meth:`Scheduler.tiles`) and how
the pipelines take them. Each is a class registered in :data:`tlm.registry.SCHEDULERS`
under the YAML value that selects it; docs/architecture.md ("Adding a scheduler")
walks through adding one.
"""

from __future__ import annotations

from tlm.registry import SCHEDULERS


class Scheduler:
    """How a tiled stage's tiles go to the pipelines."""

    name = ""

    def tiles(self, arch) -> int:
        """The number of tiles a tiled stage is cut into under ``arch`` (ArchConfig)."""
        raise NotImplementedError


@SCHEDULERS.register("static")
class Static(Scheduler):
    """One tile per pipeline (quadrants for 4), fixed before the frame starts."""

    def tiles(self, arch) -> int:
        return arch.pipelines


@SCHEDULERS.register("dynamic")
class Dynamic(Scheduler):
    """A shared queue of ``tiles_per_pipeline x pipelines`` tiles; an idle pipeline takes the next."""

    def tiles(self, arch) -> int:
        return arch.pipelines * arch.tiles_per_pipeline
