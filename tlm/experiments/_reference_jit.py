"""The reference's k-nearest photon estimate, compiled with numba (:func:`knn_grid`).

The same estimate as :func:`tlm.experiments.reference.knn_density` (Jensen's k nearest
photons, cone filter), found on a uniform grid of the photons instead of a ``cKDTree``:
the query visits shells of cells around its own until the k-th nearest photon found is
nearer than every cell not yet visited, keeping the k nearest in a max-heap, then sums
the cone-weighted powers of those arriving from the front, one query per thread. Exact:
the same k photons (up to ties in distance) and so the same density, to rounding.
"""

from __future__ import annotations

import math

import numpy as np

from tlm.kernels._numba_cache import njit, prange  # (numba's, with the cache stamped on every compiled file)

MAX_CELLS = 1 << 22  # cells of the grid at most (its size grows until they fit)


@njit(cache=True, error_model="numpy", inline="always")
def _sift_up(hd, hi, i):
    while i > 0:
        p = (i - 1) // 2
        if hd[i] <= hd[p]:
            break
        hd[i], hd[p] = hd[p], hd[i]
        hi[i], hi[p] = hi[p], hi[i]
        i = p


@njit(cache=True, error_model="numpy", inline="always")
def _sift_down(hd, hi, n):
    i = 0
    while True:
        c = 2 * i + 1
        if c >= n:
            break
        if c + 1 < n and hd[c + 1] > hd[c]:
            c += 1
        if hd[c] <= hd[i]:
            break
        hd[i], hd[c] = hd[c], hd[i]
        hi[i], hi[c] = hi[c], hi[i]
        i = c


@njit(parallel=True, cache=True, error_model="numpy")
def _knn_grid(pos, power, incoming, start, lo, h, dims, pts, nrm, k, cone_k, out):
    nx, ny, nz = dims[0], dims[1], dims[2]
    reach = max(nx, max(ny, nz))
    area = (1.0 - 2.0 / (3.0 * cone_k)) * math.pi
    for j in prange(pts.shape[0]):
        hd = np.empty(k)
        hi = np.empty(k, dtype=np.int64)
        cnt = 0
        px, py, pz = pts[j, 0], pts[j, 1], pts[j, 2]
        cx = min(max(math.floor((px - lo[0]) / h), 0), nx - 1)
        cy = min(max(math.floor((py - lo[1]) / h), 0), ny - 1)
        cz = min(max(math.floor((pz - lo[2]) / h), 0), nz - 1)
        ring = 0
        while True:
            for ix in range(max(cx - ring, 0), min(cx + ring, nx - 1) + 1):
                for iy in range(max(cy - ring, 0), min(cy + ring, ny - 1) + 1):
                    for iz in range(max(cz - ring, 0), min(cz + ring, nz - 1) + 1):
                        if abs(ix - cx) != ring and abs(iy - cy) != ring and abs(iz - cz) != ring:
                            continue  # an inner shell's cell: visited
                        c = (ix * ny + iy) * nz + iz
                        for t in range(start[c], start[c + 1]):
                            dx = pos[t, 0] - px
                            dy = pos[t, 1] - py
                            dz = pos[t, 2] - pz
                            d2 = dx * dx + dy * dy + dz * dz
                            if cnt < k:
                                hd[cnt] = d2
                                hi[cnt] = t
                                _sift_up(hd, hi, cnt)
                                cnt += 1
                            elif d2 < hd[0]:
                                hd[0] = d2
                                hi[0] = t
                                _sift_down(hd, hi, k)
            if ring >= reach:
                break  # every cell visited
            # every photon not visited lies outside the box of the visited cells
            bx = min(px - (lo[0] + (cx - ring) * h), lo[0] + (cx + ring + 1) * h - px)
            by = min(py - (lo[1] + (cy - ring) * h), lo[1] + (cy + ring + 1) * h - py)
            bz = min(pz - (lo[2] + (cz - ring) * h), lo[2] + (cz + ring + 1) * h - pz)
            b = min(bx, min(by, bz))
            if cnt == k and b > 0.0 and hd[0] <= b * b:
                break
            ring += 1
        if cnt == 0 or hd[0] <= 0.0:
            continue
        rk = math.sqrt(hd[0])  # the heap's root: the k-th nearest
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        for s in range(cnt):
            t = hi[s]
            if incoming[t, 0] * nrm[j, 0] + incoming[t, 1] * nrm[j, 1] + incoming[t, 2] * nrm[j, 2] < 0.0:
                w = 1.0 - math.sqrt(hd[s]) / (cone_k * rk)
                s0 += w * power[t, 0]
                s1 += w * power[t, 1]
                s2 += w * power[t, 2]
        norm = area * hd[0]
        out[j, 0] = s0 / norm
        out[j, 1] = s1 / norm
        out[j, 2] = s2 / norm


class PhotonGrid:
    """The photons sorted into a uniform grid of cells about ``cell`` wide (wider when
    the photons' box would need more than :data:`MAX_CELLS` cells)."""

    def __init__(self, position: np.ndarray, power: np.ndarray, incoming: np.ndarray, cell: float):
        lo, hi = position.min(axis=0), position.max(axis=0)
        extent = hi - lo
        h = max(float(cell), float(extent.max()) / 1e6, np.finfo(float).tiny)
        while True:
            dims = np.maximum(1, np.floor(extent / h).astype(np.int64) + 1)
            if int(dims.prod()) <= MAX_CELLS:
                break
            h *= 1.25
        idx = np.minimum(np.floor((position - lo) / h).astype(np.int64), dims - 1)
        cid = (idx[:, 0] * dims[1] + idx[:, 1]) * dims[2] + idx[:, 2]
        order = np.argsort(cid, kind="stable")
        self.start = np.zeros(int(dims.prod()) + 1, dtype=np.int64)
        np.cumsum(np.bincount(cid, minlength=int(dims.prod())), out=self.start[1:])
        self.position = np.ascontiguousarray(position[order])
        self.power = np.ascontiguousarray(power[order])
        self.incoming = np.ascontiguousarray(incoming[order])
        self.lo, self.h, self.dims = lo.astype(np.float64), h, dims

    def density(self, points: np.ndarray, normals: np.ndarray, k: int, cone_k: float) -> np.ndarray:
        """(q, 3) flux densities at ``points`` from the ``k`` nearest photons (fewer when there are fewer)."""
        out = np.zeros((points.shape[0], 3))
        k = min(int(k), self.position.shape[0])
        if k == 0 or points.shape[0] == 0:
            return out
        _knn_grid(self.position, self.power, self.incoming, self.start, self.lo, self.h, self.dims,
                  np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(normals, dtype=np.float64),
                  k, float(cone_k), out)
        return out
