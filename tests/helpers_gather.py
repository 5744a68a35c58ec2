"""A photon map and gather points at random, for the tests of the photon gathers (numpy and numba)."""

from __future__ import annotations

import numpy as np


def random_gather(seed: int, photons: int, queries: int, levels: int):
    """``photons`` photons uniform in the cube [-1, 1]^3 (power uniform in [0, 1), unit incoming
    directions), the point tree of ``levels`` levels over them, and ``queries`` gather points in
    the cube with unit normals, drawn in that order from ``default_rng(seed)``.

    Returns ``(pos, power, inc, tree, pts, nrm)``, in the order the gathers take them.
    """
    from tlm.kernels.bsp import build_point_tree

    rng = np.random.default_rng(seed)
    pos = rng.uniform(-1.0, 1.0, (photons, 3))
    power = rng.uniform(0.0, 1.0, (photons, 3))
    inc = rng.normal(size=(photons, 3))
    inc /= np.linalg.norm(inc, axis=1, keepdims=True)
    pts = rng.uniform(-1.0, 1.0, (queries, 3))
    nrm = rng.normal(size=(queries, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return pos, power, inc, build_point_tree(pos, levels), pts, nrm
