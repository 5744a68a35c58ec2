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

    It keeps its peaks for ``timing.fifo`` (:func:`fifo_peaks`): the most entries
    (``peak_entries``, slots: a packet takes one per address, the whole depth at most, so it
    never passes the depth), triangle addresses (``peak_addresses``: each packet's all, one at
    least, not cut to the depth: a packet of more than the depth counts whole) and packets it
    held at once (pushed, not yet freed), and what tells whether another depth
    would have run it the same (:func:`fifo_depth_alike`), in addresses (a packet's
    triangle addresses, one at least, not cut to the depth): ``peak_shared``, the most
    addresses held with the new packet's among the puts that entered at once a FIFO
    holding packets; ``waited``, the puts that found no room; ``least_waited``, the fewest
    addresses held with the new packet's among those that found one packet there (the
    only one that can free room, so the put waits for the FIFO to empty); and
    ``waited_on_many``, those that found several.
    """

    def __init__(self, env: simpy.Environment, depth: int, pipe: int = 0):
        self.env = env
        self.depth = depth
        self.pipe = pipe  # the pipeline whose Traversal and Intersection PMs it joins
        self.level = depth  # free entries
        self.queue: deque[int] = deque()  # packets in the FIFO, in order
        self.pushed = 0
        self.popped = 0
        self.held = 0  # packets in the FIFO: pushed, not yet freed
        self.addresses = 0  # their addresses, one a packet at least, not cut to the depth
        self.peak_entries = 0  # the most entries (slots) held at once: the depth at most
        self.peak_addresses = 0  # the most addresses held at once (one a packet at least, not cut to the depth)
        self.peak_packets = 0  # the most packets held at once
        self.peak_shared = 0  # the most addresses held with a packet that entered beside others
        self.waited = 0  # puts that found no room
        self.least_waited = 0  # the fewest addresses held with a waiting put's, one packet held (0: none)
        self.waited_on_many = 0  # puts that found no room with several packets held
        self._refused = -1  # the last packet refused (a put's retries count once)
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

    def try_push(self, k: int, slots: int, entries: int | None = None) -> bool:
        """Put packet ``k`` (``slots`` entries; ``entries`` addresses, ``slots`` if not
        given) in, if there is room: whether it went in."""
        level = self.level
        own = slots if entries is None or entries < 1 else entries
        if level != self.depth:  # packets are held: this put's addresses with theirs
            want = self.addresses + own
            if level < slots:
                if k != self._refused:
                    self._refused = k
                    self.waited += 1
                    if self.held > 1:
                        self.waited_on_many += 1
                    elif want < self.least_waited or not self.least_waited:
                        self.least_waited = want
                return False
            if want > self.peak_shared:
                self.peak_shared = want
        level -= slots
        self.level = level
        addresses = self.addresses = self.addresses + own
        if addresses > self.peak_addresses:
            self.peak_addresses = addresses
        if self.depth - level > self.peak_entries:
            self.peak_entries = self.depth - level
        held = self.held = self.held + 1
        if held > self.peak_packets:
            self.peak_packets = held
        self.queue.append(k)
        ev = self.data.event  # (self.data.fire(), inline: once per packet)
        if ev is not None:
            self.data.event = None
            ev.succeed()
        return True

    def try_pop(self) -> int | None:
        """The packet at the head, taken out; None if the FIFO is empty."""
        return self.queue.popleft() if self.queue else None

    def free(self, slots: int, entries: int | None = None) -> None:
        """The Intersection PM is done with a packet of ``slots`` entries (``entries``
        addresses, as pushed): they are free again."""
        self.level += slots
        self.held -= 1
        self.addresses -= slots if entries is None or entries < 1 else entries
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


PEAKS = ("peak_entries", "peak_addresses", "peak_packets", "peak_shared", "waited", "waited_on_many")
MOST = PEAKS[:4]  # the most of the FIFOs'; the rest summed


def fifo_peaks(fifos: list[Fifo], depth: int, pipelines: int) -> dict:
    """``timing.fifo`` of results.json: ``depth`` (``arch.fifo_depth``), ``fifos`` (the FIFOs
    the frames filled: one a Traversal/Intersection phase a tile a frame) and, over them all
    and per pipeline (``pipelines``: its Intersection PM's input), the peaks of :class:`Fifo`:
    ``peak_entries`` (slots, the depth at most), ``peak_addresses`` (triangle addresses, one a
    packet at least, not cut to the depth) and ``peak_packets`` held at once and ``peak_shared``
    (each the most of its FIFOs'), ``least_waited`` (the fewest; None where no put waited for the one packet
    held), ``waited`` and ``waited_on_many`` (summed)."""
    per = [{**dict.fromkeys(PEAKS, 0), "least_waited": None} for _ in range(pipelines)]
    for f in fifos:
        row = per[f.pipe]
        for key in MOST:
            if getattr(f, key) > row[key]:
                row[key] = getattr(f, key)
        row["waited"] += f.waited
        row["waited_on_many"] += f.waited_on_many
        if f.least_waited and (row["least_waited"] is None or f.least_waited < row["least_waited"]):
            row["least_waited"] = f.least_waited
    least = [row["least_waited"] for row in per if row["least_waited"] is not None]
    return {"depth": depth, "fifos": len(fifos),
            **{key: max((row[key] for row in per), default=0) for key in MOST},
            **{key: sum(row[key] for row in per) for key in PEAKS[len(MOST):]},
            "least_waited": min(least, default=None), "pipelines": per}


def fifo_depth_alike(peaks: dict, depth: int, other: int) -> bool:
    """Whether a run whose FIFOs showed ``peaks`` (:func:`fifo_peaks`, at ``depth``) runs the
    same at the depth ``other``, every put entering the cycle it did: a put into an empty
    FIFO enters at any depth (its packet cut to the depth if larger); one that entered
    beside other packets would at ``other`` too where their addresses fit in it
    (``peak_shared`` <= ``other``); one that waited for the one packet held would wait for
    it at ``other`` too where the two do not fit in it together (``least_waited`` >
    ``other``; cut to ``other`` entries each, two packets of a and b addresses, one at least
    each, overflow it exactly where a + b > ``other``); one that waited with several held is
    not judged (none may have). Where it holds, the run at ``other`` is this run in every cycle,
    stall, event and frame time (``tests/test_fifo_depth_h425.py`` simulates both)."""
    if not peaks or peaks.get("depth") != depth or peaks.get("waited_on_many"):
        return False
    least = peaks.get("least_waited")
    return peaks["peak_shared"] <= other and (least is None or least > other)


def fifo_held(peaks: dict) -> str:
    """The most the FIFOs of ``peaks`` (``timing.fifo``) held at once, in words: packets, entries
    (slots, the depth at most) and triangle addresses (not cut to the depth; a results.json
    written before they were recorded: left out). Worded so that runs differing in these counts
    differ in numbers only (the report lists such lines as one kind: no 'entry' beside 'entries')."""
    n, e, depth, a = peaks["peak_packets"], peaks["peak_entries"], peaks["depth"], peaks.get("peak_addresses")
    held = (f"{n} packet{'s' if n != 1 else ''}, entries {e} of {depth} (an entry a triangle address, a packet "
            "the whole FIFO at most)")
    if a is None:
        return held.replace(", ", " or ", 1)
    return f"{held} or triangle addresses {a} (not cut to the depth)"
