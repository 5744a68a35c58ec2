"""The Traversal PM's FIFO of triangle addresses towards the Intersection PM.

The Traversal PM finds the leaves a packet of rays reaches and puts the addresses of
their triangles into the FIFO; the fixed-function Intersection PM takes them out and
tests the triangles. A full FIFO stalls the Traversal PM (*fifo_full*), an empty one
the Intersection PM (*fifo_empty*): the two run coupled, one phase's two jobs
(:class:`tlm.arch.pm.Traversal`, :class:`tlm.arch.pm.Intersection`).
"""

from __future__ import annotations

from collections import deque

import simpy
from simpy.events import Event

from tlm.arch.events import Signal


class Fifo:
    """The FIFO of one Traversal/Intersection phase: ``depth`` entries of triangle addresses.

    A packet's addresses enter together; a packet with more addresses than the FIFO
    holds enters when the FIFO is empty (the packet is the model's unit of transfer),
    and a packet without addresses takes one entry (its end marker).
    Its space is freed when the Intersection PM has tested the packet.
    """

    def __init__(self, env: simpy.Environment, depth: int):
        self.env = env
        self.depth = depth
        self.level = depth  # free entries
        self.queue: deque[int] = deque()  # packets in the FIFO, in order
        self.pushed = 0
        self.popped = 0
        self.space = Signal(env)  # entries freed (the Traversal PM waits on it while the FIFO is full)
        self.data = Signal(env)  # a packet entered (the Intersection PM waits on it while it is empty)

    @property
    def drained(self) -> bool:
        """Every address pushed was popped and every entry is free again (a run that finished)."""
        return self.pushed == self.popped and self.level == self.depth and not self.queue

    def slots(self, entries: int) -> int:
        """The entries a packet of ``entries`` addresses takes."""
        # a packet without addresses still passes its end-of-packet marker
        return max(1, min(int(entries), self.depth))

    def try_push(self, k: int, slots: int) -> bool:
        """Put packet ``k`` (``slots`` entries) in, if there is room: whether it went in."""
        if self.level < slots:
            return False
        self.level -= slots
        self.queue.append(k)
        ev = self.data.event  # (self.data.fire(), inline: once per packet)
        if ev is not None:
            self.data.event = None
            ev.succeed()
        return True

    def try_pop(self) -> int | None:
        """The packet at the head, taken out; None if the FIFO is empty."""
        return self.queue.popleft() if self.queue else None

    def free(self, slots: int) -> None:
        """The Intersection PM is done with a packet of ``slots`` entries: they are free again."""
        self.level += slots
        ev = self.space.event  # (self.space.fire(), inline: once per packet)
        if ev is not None:
            self.space.event = None
            ev.succeed()

    def space_freed(self) -> Event:
        """An event that fires when entries are next freed."""
        return self.space.wait()

    def data_arrived(self) -> Event:
        """An event that fires when a packet next enters."""
        return self.data.wait()
