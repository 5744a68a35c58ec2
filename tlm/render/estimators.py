"""Radiance estimators of the photon-map pass, selected by ``estimate.filter``.

Each estimator is a class registered in :data:`tlm.registry.ESTIMATORS` under the YAML
value that selects it; :func:`tlm.render.pmap.pmap_pass` calls it once per photon map
(the caustic map, then the indirect map) with the gather points. The estimate kernels
themselves (eqs. 3.2–3.5 and the exact reference) are in :mod:`tlm.kernels.estimate`;
a class here only chooses the kernel and hands it the config's knobs. docs/architecture.md
("Adding a radiance estimator") walks through adding one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tlm.kernels import estimate, kvoxel
from tlm.registry import ESTIMATORS


@dataclass(frozen=True)
class Gather:
    """One map's gather at a frame's points: what every estimator is handed."""

    position: np.ndarray  # (photons, 3) the map's photons
    power: np.ndarray  # (photons, 3)
    incoming: np.ndarray  # (photons, 3) directions of arrival
    tree: object  # the map's BSPTree (Algorithm 1), whose leaves the hardware filters search
    points: np.ndarray  # (m, 3) gather points
    normals: np.ndarray  # (m, 3) their shading normals
    radius: float  # the map's search radius
    keys: np.ndarray  # (m,) per-point keys of stochastic filters (pixel and sample, seed-free)
    streams: object  # the Fragment PM's address streams (tlm.kernels.memory.Streams) or None
    stream: str  # the stream this map's leaves are charged to
    kdtree: object  # a prebuilt cKDTree of the photons, or None (exact estimators)
    prepared: object = None  # the map in leaf order (tlm.kernels.estimate.leaf_photons), or None: made here


class Estimator:
    """A radiance estimate at the gather points: an :class:`~tlm.kernels.estimate.Estimate`
    (the reflected flux density, (m, 3), and the per-point work counts the Fragment PM is
    charged: node visits, leaves, photons tested and accepted, probes, page misses).

    ``uses_radius``: whether the fixed search radius applies (False for a k-nearest one,
    whose rows report no radius). The config's ``estimate`` section is ``self.cfg``.
    """

    name = ""
    uses_radius = True

    def __init__(self, cfg, seed: int = 0):
        self.cfg = cfg  # EstimateConfig
        self.seed = seed

    def __call__(self, g: Gather):
        raise NotImplementedError


@ESTIMATORS.register("disk")
class Disk(Estimator):
    """eq. 3.2: every photon of the searched leaves within the disk of radius r."""

    def __call__(self, g: Gather):
        return estimate.disk_estimate(g.position, g.power, g.incoming, g.tree, g.points, g.normals, g.radius,
                                      streams=g.streams, stream=g.stream, prepared=g.prepared)


@ESTIMATORS.register("mvoxel")
class MVoxel(Estimator):
    """eq. 3.3 with Fig. 8: the m-voxel filter, cone-weighted."""

    def __call__(self, g: Gather):
        return estimate.mvoxel_estimate(g.position, g.power, g.incoming, g.tree, g.points, g.normals, g.radius,
                                        cone_k=self.cfg.cone_k, streams=g.streams, stream=g.stream,
                                        prepared=g.prepared)


@ESTIMATORS.register("kvoxel")
class KVoxel(Estimator):
    """eqs. 3.4/3.5: the stochastic k-voxel filter (k photons drawn per searched voxel)."""

    def __call__(self, g: Gather):
        return kvoxel.kvoxel_estimate(g.position, g.power, g.incoming, g.tree, g.points, g.normals, g.radius,
                                      k=self.cfg.k, cone_k=self.cfg.cone_k, seed=self.seed, keys=g.keys,
                                      streams=g.streams, stream=g.stream, prepared=g.prepared)


@ESTIMATORS.register("knn")
class KNearest(Estimator):
    """Jensen's exact k-nearest estimate (the reference; no hardware filter, no radius)."""

    uses_radius = False

    def __call__(self, g: Gather):
        return estimate.knn_estimate(g.position, g.power, g.incoming, g.points, g.normals,
                                     k_nearest=self.cfg.k_nearest, cone_k=self.cfg.cone_k, kdtree=g.kdtree)
