"""The numpy reference walk of the Traversal PM (:mod:`tlm.kernels.traverse`, §III.B.2).

What :func:`~tlm.kernels.traverse.closest_hit` and :func:`~tlm.kernels.traverse.any_hit`
run under ``TLM_KERNELS=numpy`` (and for the float64 fallback of rays whose float32
answer failed its check), both phases vectorized over a packet's rays: the root clipped
to each ray's segment (:func:`_clip_root`), the leaf lists level by level, near child
first (:func:`_leaf_lists`), then the leaves in batches grouped by leaf, one block test
per leaf, the sequential stopping rule applied afterwards (:func:`_loop_numpy`). The
compiled engine does the same in :mod:`tlm.kernels._jit`, with the same results.
"""

from __future__ import annotations

import numpy as np

from tlm.kernels.bsp import BSPTree
from tlm.kernels.intersect import closest_slots, closest_slots64

CHUNK_PAIRS = 1 << 17  # (slot, ray) pairs per block: fewer, longer numpy calls


def _clip_root(tree: BSPTree, o, d, tmin, tmax):
    """Slab test against the root box; the entry and exit distances and 1/d per ray.

    A zero direction component (either sign) never crosses its slab: the ray is inside
    it for all t when its origin is (closed box), outside for all t otherwise.
    """
    lo, hi = tree.lo[0], tree.hi[0]
    ta, tb = tmin.copy(), tmax.copy()
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        for k in range(3):
            oc = o[:, k]
            t0 = (lo[k] - oc) * inv[:, k]
            t1 = (hi[k] - oc) * inv[:, k]
            near = np.minimum(t0, t1)
            far = np.maximum(t0, t1)
            zero = np.flatnonzero(d[:, k] == 0.0)
            if zero.shape[0]:
                inside = (oc[zero] >= lo[k]) & (oc[zero] <= hi[k])
                near[zero] = np.where(inside, -np.inf, np.inf)
                far[zero] = np.where(inside, np.inf, -np.inf)
            np.maximum(ta, near, out=ta)
            np.minimum(tb, far, out=tb)
    return ta, tb, inv


def _leaf_lists(tree: BSPTree, o, d, inv, ta, tb, record: bool):
    """Phase 1: every ray's crossed leaves, near to far. Pairs are sorted by ray."""
    r = o.shape[0]
    ray = np.flatnonzero(ta <= tb)
    node = np.zeros(ray.shape[0], dtype=np.int64)
    a, b = ta[ray], tb[ray]
    node_visits = np.zeros(r, dtype=np.int64)
    rec = []
    id_type = np.int32 if tree.n_nodes <= np.iinfo(np.int32).max else np.int64
    cols = [(np.ascontiguousarray(o[:, k]), np.ascontiguousarray(d[:, k]), np.ascontiguousarray(inv[:, k]))
            for k in range(3)]
    for j in range(tree.levels):
        oc, dc, ic = cols[j % 3]
        level_visits = np.bincount(ray, minlength=r)
        if record:  # kept small: the level's nodes (rays are sorted) and visits per ray
            rec.append((node.astype(id_type), level_visits.astype(np.int32)))
        node_visits += level_visits
        s = tree.split[node]
        oa = oc[ray]
        da = dc[ray]
        with np.errstate(invalid="ignore"):
            ts = (s - oa) * ic[ray]
        flat = da == 0.0
        # near child by the direction bit (d > 0: left first); a flat ray: its own side
        near_right = np.where(flat, oa >= s, da < 0.0)
        near_b = np.where(flat, b, np.minimum(b, ts))
        far_a = np.where(flat, np.inf, np.maximum(a, ts))
        keep_near = a <= near_b
        keep_far = far_a <= b
        n_child = keep_near.view(np.int8) + keep_far.view(np.int8)
        pos = np.cumsum(n_child, dtype=np.int64)
        total = int(pos[-1]) if pos.shape[0] else 0
        pos -= n_child
        near_at = pos[keep_near]
        far_at = (pos + keep_near)[keep_far]
        left = 2 * node + 1
        new_node = np.empty(total, dtype=np.int64)
        new_a = np.empty(total)
        new_b = np.empty(total)
        new_node[near_at] = (left + near_right)[keep_near]
        new_node[far_at] = (left + ~near_right)[keep_far]
        new_a[near_at] = a[keep_near]
        new_a[far_at] = far_a[keep_far]
        new_b[near_at] = near_b[keep_near]
        new_b[far_at] = b[keep_far]
        ray = np.repeat(ray, n_child)
        node, a, b = new_node, new_a, new_b
    touched_nodes = None
    if record:  # the visits in ray-major order (levels in order), placed without a sort
        ptr = np.zeros(r + 1, dtype=np.int64)
        np.cumsum(node_visits, out=ptr[1:])
        ids = np.empty(int(ptr[-1]), dtype=id_type)
        free = ptr[:-1].copy()  # where each ray's next level goes
        rays = np.arange(r, dtype=np.int64)
        for node_j, level_visits in rec:
            # entry i of the level (ray q) goes to free[q] + i - (q's first entry in the level)
            first = np.cumsum(level_visits, dtype=np.int64)
            first -= level_visits
            at = (free - first)[np.repeat(rays, level_visits)]
            at += np.arange(node_j.shape[0], dtype=np.int64)
            ids[at] = node_j
            free += level_visits
        touched_nodes = (ptr, ids)
    leaf = node - tree.leaf_offset
    return ray, leaf, b, node_visits, touched_nodes


def _loop_numpy(accel, o, d, inv, ta, tb, o_t, d_t, tmin_t, tmax_t, ignore, record, first_only, batch,
                shared_origin, exact64):
    """Both phases, vectorized: leaf lists level by level, then the leaves in batches
    grouped by leaf (one block test per leaf), the stopping rule applied afterwards."""
    tree = accel.tree
    r = o.shape[0]
    pray, pleaf, pexit, node_visits, touched_nodes = _leaf_lists(tree, o, d, inv, ta, tb, record)
    npairs = pray.shape[0]
    cnt = np.bincount(pray, minlength=r)
    start = np.cumsum(cnt) - cnt

    best_t = np.full(r, np.inf)
    best_slot = np.full(r, -1, dtype=np.int64)
    last_k = cnt - 1  # index of the stopping leaf on each ray's list
    done = cnt == 0
    pt = np.full(npairs, np.inf, dtype=np.float64 if exact64 else np.float32)
    pslot = np.full(npairs, -1, dtype=np.int64)
    test, tri = (closest_slots64, accel.soa64) if exact64 else (closest_slots, accel.soa)
    ign = ignore if (ignore >= 0).any() else None
    lf, ll = accel.leaf_first, accel.leaf_last
    # small integer leaf numbers sort by radix (stable) instead of by merge
    sort_leaf = pleaf.astype(np.int16) if tree.n_leaves <= np.iinfo(np.int16).max else pleaf
    k0 = 0
    while True:
        act = np.flatnonzero(~done & (cnt > k0))
        if act.shape[0] == 0:
            break
        nb = np.minimum(cnt[act] - k0, batch)
        rep = np.repeat(act, nb)
        within = np.arange(rep.shape[0]) - np.repeat(np.cumsum(nb) - nb, nb)
        idx = start[rep] + k0 + within  # pair indices tested in this batch
        leaves = sort_leaf[idx]
        order = np.argsort(leaves, kind="stable")
        idx = idx[order]
        leaves = leaves[order]
        bounds = np.flatnonzero(np.diff(leaves)) + 1
        group_start = np.concatenate([[0], bounds])
        group_end = np.concatenate([bounds, [leaves.shape[0]]])
        for g0, g1 in zip(group_start.tolist(), group_end.tolist(), strict=True):
            leaf = int(leaves[g0])
            s0, s1 = int(lf[leaf]), int(ll[leaf])
            if s1 <= s0:
                continue
            step = max(1, CHUNK_PAIRS // (s1 - s0))
            for c0 in range(g0, g1, step):
                p = idx[c0 : min(c0 + step, g1)]
                rays = pray[p]
                pslot[p], pt[p] = test(
                    o_t[:, :1] if shared_origin else o_t[:, rays], d_t[:, rays], tmin_t[rays], tmax_t[rays],
                    None if ign is None else ign[rays], tri, s0, s1, shared_origin,
                )
        # the sequential stopping rule over the batch's leaves
        for k in range(k0, k0 + batch):
            live = act[(~done[act]) & (cnt[act] > k)]
            if live.shape[0] == 0:
                break
            p = start[live] + k
            if first_only:
                stop = pslot[p] >= 0
            else:
                better = pt[p] < best_t[live]
                upd = live[better]
                pb = p[better]
                best_t[upd], best_slot[upd] = pt[pb], pslot[pb]
                stop = best_t[live] <= pexit[p]
            stopped = live[stop]
            if first_only:
                best_slot[stopped] = pslot[p[stop]]
            last_k[stopped] = k
            done[stopped] = True
        k0 += batch

    return best_slot, last_k, pray, pleaf, cnt, node_visits, touched_nodes
