"""Schedulers of a frame's tiled stages, selected by ``arch.scheduler``.

A scheduler says how many tiles a stage is cut into (:meth:`Scheduler.tiles`) and how
the pipelines take them (:meth:`Scheduler.run_stage`). Each is a class registered in
:data:`tlm.registry.SCHEDULERS` under the YAML value that selects it; the control unit
(:mod:`tlm.arch.model`) calls the selected one for every tiled stage of every frame, so
a new scheduler is one class here and one YAML value. docs/architecture.md ("Adding a
scheduler") walks through adding one.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Generator
from typing import Protocol

import simpy
from simpy.events import Event

from tlm.arch.events import CycleEnd, Priority, all_done
from tlm.registry import SCHEDULERS


class Frame(Protocol):
    """What a scheduler sees of a frame in flight (the control unit's ``_Frame``)."""

    env: simpy.Environment
    cycle_end: CycleEnd  # the end-of-cycle events of the model (tlm.arch.events)

    def chain(self, pipe: int, phases, gate: list) -> Event:
        """Queue a tile's phases on pipeline ``pipe``'s PMs, the first behind ``gate``
        ([(event, cause, what)]); the event fires when the last phase is done."""

    def compose(self, pipe: int, tile) -> Generator:
        """A process step: copy ``tile``'s pixels from pipeline ``pipe`` to the top-level unit."""

    def returned(self, pipe: int, words: int) -> None:
        """Pipeline ``pipe`` has ``words`` more to send back to pipeline 0 after the stage."""


class Scheduler:
    """How a tiled stage's tiles go to the pipelines."""

    name = ""
    pinned = False  # each stage's tile p runs on one fixed pipeline, the same for every stage (static tiles)
    # the completions mostly repeat from the warm-up on with two images in flight (static tiles: where the asked
    # frames' gaps do not, the stream runs on as the dynamic one does, tlm.arch.steady.repeats_from_warmup); else the
    # model runs the stream past arch.frames until they do (the dynamic queue settles after a transient)
    periodic_from_warmup = False

    def tiles(self, arch) -> int:
        """The number of tiles a tiled stage is cut into under ``arch`` (ArchConfig)."""
        raise NotImplementedError

    def run_stage(self, frame: Frame, stage, gates: list[list]) -> tuple[Event, list[Event]]:
        """Hand ``stage``'s tiles (``stage.tiles``) to the pipelines of ``frame``.

        A tile that starts on pipeline ``p`` first waits for ``gates[p]`` ([(event, cause,
        what)]: the previous stage and the stage's data on that pipeline). Each tile's
        chain reports its words for pipeline 0 (``frame.returned``) once done, and a tile
        with pixels sends them to the top-level unit (``frame.compose``). Returns the
        stage's semaphore, which fires when every tile's chain is done (the next stage
        waits for it), and the events the frame waits for at its end besides (compose
        copies that need not hold the next stage back).
        """
        raise NotImplementedError


@SCHEDULERS.register("static")
class Static(Scheduler):
    """One tile per pipeline (quadrants for 4), fixed before the frame starts.

    Pipeline ``p`` runs tile ``p``; its pixels go to the top-level unit once it is done,
    while the next stage may start.
    """

    pinned = True
    periodic_from_warmup = True

    def tiles(self, arch) -> int:
        return arch.pipelines

    def run_stage(self, frame: Frame, stage, gates: list[list]) -> tuple[Event, list[Event]]:
        env = frame.env
        dones, tails = [], []
        for p, tile in enumerate(stage.tiles):
            chain = frame.chain(p, tile.phases, gates[p])
            dones.append(chain)
            chain.callbacks.append(lambda _ev, p=p, tile=tile: frame.returned(p, tile.returns))
            if tile.pixels:
                tails.append(env.process(self._compose(frame, p, tile, chain)))
        return all_done(env, dones), tails

    @staticmethod
    def _compose(frame: Frame, pipe: int, tile, chain: Event):
        yield chain
        yield from frame.compose(pipe, tile)


@SCHEDULERS.register("dynamic")
class Dynamic(Scheduler):
    """A shared queue of ``tiles_per_pipeline x pipelines`` tiles; an idle pipeline takes the next.

    The first tiles go out at once, in pipeline order; a pipeline done with its tile
    sends its pixels to the top-level unit and asks the queue (:class:`TileQueue`) for
    the next, until the queue is empty.
    """

    def tiles(self, arch) -> int:
        return arch.pipelines * arch.tiles_per_pipeline

    def run_stage(self, frame: Frame, stage, gates: list[list]) -> tuple[Event, list[Event]]:
        env = frame.env
        queue = TileQueue(env, stage.tiles, frame.cycle_end)
        workers = []
        for p, gate in enumerate(gates):  # the first tiles go out at once, in pipeline order
            tile = queue.take()
            if tile is None:
                break
            chain = frame.chain(p, tile.phases, gate)
            workers.append(env.process(self._worker(frame, p, queue, tile, chain)))
        return all_done(env, workers), []

    @staticmethod
    def _worker(frame: Frame, pipe: int, queue: TileQueue, tile, chain: Event):
        """Pipeline ``pipe`` takes the next waiting tile when it is free."""
        while tile is not None:
            yield chain
            frame.returned(pipe, tile.returns)
            if tile.pixels:  # the tile's pixels leave the pipeline's module before it takes the next tile
                yield from frame.compose(pipe, tile)
            tile = yield queue.request(pipe)
            if tile is not None:
                chain = frame.chain(pipe, tile.phases, [])


class TileQueue:
    """The dynamic scheduler's shared queue of one frame's tiled stage.

    A pipeline that is done with its tile asks for the next one; the requests of a cycle
    are served together once every other event of the cycle has run
    (:attr:`Priority.DISPATCH`), in pipeline order, so which pipeline gets which tile does
    not depend on the order of same-cycle events.
    """

    def __init__(self, env: simpy.Environment, tiles, cycle_end: CycleEnd):
        self.env = env
        self.tiles = deque(tiles)
        self.cycle_end = cycle_end
        self.waiting: dict[int, Event] = {}
        self.scheduled = False

    def take(self):
        """The next tile, taken off the queue; None if it is empty."""
        return self.tiles.popleft() if self.tiles else None

    def request(self, pipe: int) -> Event:
        """An event whose value is pipeline ``pipe``'s next tile (None: the queue is empty)."""
        ev = self.env.event()
        self.waiting[pipe] = ev
        if not self.scheduled:
            self.cycle_end.event(Priority.DISPATCH).callbacks.append(self._dispatch)
            self.scheduled = True
        return ev

    def _dispatch(self, _ev) -> None:
        self.scheduled = False
        for p in sorted(self.waiting):
            self.waiting.pop(p).succeed(self.take())
