"""The seam between the layers: a run's work, packet by packet, for the timing model.

docs/design.md, "Two layers, one seam": a PM process takes a packet of work (rays or pixels), gets the kernels'
work counts for it, and turns them into cycles. Because every kernel gives exactly the
same per-ray and per-pixel results and counts whatever packet it runs on (tested bit
for bit), the counts of a packet are the sums of its pixels' counts in the whole-image
run: the functional layer runs once, and the timing model can cut its work into
packets of any size afterwards, or simulate another architecture without rerunning a
kernel.

Packets are consecutive runs of ``packet_size`` pixels in row-major order (photons:
in emission order); the last packet may be short. Vertex PM work is per image: the
geometry BSP's and the photon BSP's :class:`~tlm.kernels.bsp.LevelWork` totals.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from tlm.kernels.bsp import BSPTree


@dataclass(frozen=True)
class Packets:
    """One frame's work in packets.

    sizes : (packets,) int64, pixels (or photons) per packet.
    counts : work key -> (packets,) int64, the packet's summed work.
    """

    name: str
    packet_size: int
    sizes: np.ndarray
    counts: dict[str, np.ndarray]

    @property
    def n(self) -> int:
        return int(self.sizes.shape[0])

    def totals(self) -> dict[str, int]:
        return {k: int(v.sum()) for k, v in self.counts.items()}


def split(name: str, work: Mapping[str, np.ndarray], packet_size: int) -> Packets:
    """Cut per-item work (arrays of any shape, read row-major) into packets.

    ``work``: a render's dict, or one of the seam's typed work classes
    (:class:`~tlm.arch.functional.RayPassWork`, ..., which read as mappings).
    """
    if isinstance(packet_size, bool) or not isinstance(packet_size, (int, np.integer)) or packet_size < 1:
        raise ValueError(f"packet_size (={packet_size!r}) must be a whole number >= 1")
    flat = {k: np.asarray(v).reshape(-1) for k, v in work.items()}
    n = next(iter(flat.values())).shape[0] if flat else 0
    if any(v.shape[0] != n for v in flat.values()):
        raise ValueError(f"work arrays of {name!r} differ in length")
    starts = np.arange(0, n, packet_size, dtype=np.int64)
    sizes = np.diff(np.append(starts, n))
    counts = {}
    for k, v in flat.items():
        # integer sums in item order: exact, and the same as summing each packet alone
        counts[k] = np.add.reduceat(v.astype(np.int64, copy=False), starts) if n else np.zeros(0, np.int64)
    return Packets(name, int(packet_size), sizes.astype(np.int64), counts)


def tree_work(tree: BSPTree) -> dict[str, int]:
    """The Vertex PM's work items for one BSP build (Algorithm 1, all levels)."""
    w = tree.work
    return {
        "elements": tree.n_elements,
        "levels": len(w),
        "com_reads": sum(x.elements_in for x in w),
        "storage_reads": sum(x.storage_reads for x in w),
        "writes": sum(x.elements_out for x in w),
        "expansion_copies": sum(x.expansion_copies for x in w),
        "nodes": tree.n_nodes,
    }


@dataclass(frozen=True)
class FrameWork:
    """Everything the timing model charges for one image of a run."""

    geometry: dict[str, int]  # Vertex PM: the geometry BSP
    passes: tuple[Packets, ...]  # per rendered pass, in plan order
    photon_trace: Packets | None  # photons traced (Traversal and Intersection PMs)
    photon_tree: dict[str, int] | None  # Vertex PM: the photon BSP


def frame_work(res, packet_size: int) -> FrameWork:
    """The work of a :class:`~tlm.experiments.run.RenderResult` in packets."""
    passes = tuple(split(name, res.work[name], packet_size) for name in res.plan.run_names)
    traced = getattr(res, "photons", None)
    return FrameWork(
        geometry=tree_work(res.accel.tree),
        passes=passes,
        photon_trace=None if traced is None else split("photons", traced.work, packet_size),
        photon_tree=None if traced is None else {k: sum(tree_work(m.tree)[k] for m in traced.photons.maps)
                                                 for k in tree_work(traced.photons.maps[0].tree)},
    )
