"""The two-machine flow shop of a Traversal/Intersection phase, compiled with numba.

:func:`flow_shop` returns what ``tlm.arch.granularity.flow_shop``'s Python loop returns (the
reference, run with ``TLM_KERNELS=numpy``), cycle for cycle: packet k costs ``t[k]`` on
the Traversal PM and ``i[k]`` on the Intersection PM and takes ``max(1, min(entries[k],
depth))`` entries of the FIFO (one each where ``has_entries`` is false). The Traversal PM
works packet k once it has put packet k - 1 into the FIFO, and puts it in once the
packets before the first one that leaves room have been tested; the Intersection PM
tests packet k once it is in the FIFO and packet k - 1 is tested.

The first packet that leaves room, ``w``, only moves forward with k (the entries taken
so far only grow), so it is followed by a pointer instead of the reference's
``searchsorted`` over every packet; of the cycles the packets were tested at, only the
last ``min(depth, n)`` + 1 are kept, in a ring (packet k looks back ``depth`` packets
at most: each takes an entry at least). Integer arithmetic only (int64: the model's
cycle counts), so nothing can differ but the speed. Lives in the kernels layer, which
never imports the timing model: the model (``tlm.arch.model``) calls it.
"""

from __future__ import annotations

import numpy as np

from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)


@njit(cache=True, nogil=True, inline="always")
def _slots(entries, k, has_entries, depth):
    """Packet k's FIFO entries: ``max(1, min(entries[k], depth))``, one where ``has_entries`` is false."""
    if not has_entries:
        return np.int64(1)
    s = np.int64(entries[k])
    if s < 1:
        return np.int64(1)
    return depth if s > depth else s


@njit(cache=True, nogil=True)
def flow_shop(t, i, entries, has_entries, depth):
    """The cycles from the phase's start to its last packet tested (0 without packets).

    t, i : (n,) int64 cycles per packet on the Traversal and the Intersection PM;
    entries : (n,) int64 FIFO entries per packet (read only where ``has_entries``);
    depth : the FIFO's entries, >= 1.
    """
    n = t.shape[0]
    if n == 0:
        return np.int64(0)
    depth = np.int64(depth)
    ring = np.int64(min(depth, np.int64(n))) + 1
    tested = np.zeros(ring, dtype=np.int64)  # tested[x % ring]: the cycle packet x - 1 was tested (x = 0: 0)
    ends = np.int64(0)  # entries of packets 0..k
    before = np.int64(0)  # entries of the packets before w
    w = 0  # the first packet m with ends - before[m] <= depth: packet k fits once the packets before it are tested
    pushed = np.int64(0)  # the cycle the Traversal PM put the previous packet in
    last = np.int64(0)  # the cycle the previous packet was tested
    for k in range(n):
        ends += _slots(entries, k, has_entries, depth)
        while before < ends - depth:
            before += _slots(entries, w, has_entries, depth)
            w += 1
        pushed += t[k]  # worked
        room = tested[w % ring]
        if room > pushed:
            pushed = room  # (fifo_full until then)
        if pushed > last:
            last = pushed  # (fifo_empty until it is in)
        last += i[k]
        tested[(k + 1) % ring] = last
    return last
