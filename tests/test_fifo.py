"""The Traversal/Intersection FIFO (:mod:`tlm.arch.fifo`): entries a packet takes, room,
order, and the two wake-ups (data arrived, space freed) that couple the two PMs."""

from __future__ import annotations

import simpy

from tlm.arch.fifo import Fifo


def test_a_packet_takes_its_addresses_at_least_one_at_most_the_depth():
    fifo = Fifo(simpy.Environment(), depth=4)
    assert [fifo.slots(n) for n in (0, 1, 3, 4, 5, 100)] == [1, 1, 3, 4, 4, 4]


def test_push_takes_room_in_order_and_refuses_when_full():
    fifo = Fifo(simpy.Environment(), depth=4)
    assert fifo.drained and fifo.try_pop() is None
    assert fifo.try_push(7, 3) and fifo.level == 1
    assert not fifo.try_push(8, 2) and fifo.level == 1 and list(fifo.queue) == [7]  # no room: nothing changes
    assert fifo.try_push(9, 1) and fifo.level == 0
    assert not fifo.try_push(10, fifo.slots(0))  # even an end marker needs an entry
    assert fifo.try_pop() == 7 and fifo.try_pop() == 9 and fifo.try_pop() is None
    assert fifo.level == 0 and not fifo.drained  # popped, but not yet tested: the entries stay taken
    fifo.free(3)
    fifo.free(1)
    fifo.pushed = fifo.popped = 2
    assert fifo.level == 4 and fifo.drained
    fifo.pushed = 3  # one address pushed and not popped: not a finished run
    assert not fifo.drained


def test_an_oversized_packet_enters_an_empty_fifo_only():
    fifo = Fifo(simpy.Environment(), depth=4)
    big = fifo.slots(10)
    assert fifo.try_push(1, 1) and not fifo.try_push(2, big)
    fifo.try_pop()
    fifo.free(1)
    assert fifo.try_push(2, big) and fifo.level == 0


def test_the_waits_wake_on_push_and_on_free_at_the_cycle_they_happen():
    """A consumer waiting on an empty FIFO resumes the cycle a packet enters; a producer
    waiting on a full one resumes the cycle entries are freed; a push or free with
    nobody waiting makes no event."""
    env = simpy.Environment()
    fifo = Fifo(env, depth=2)
    log = []

    def producer():
        for k in range(3):
            while not fifo.try_push(k, 2):
                yield fifo.space_freed()
            log.append(("push", k, env.now))
            yield env.timeout(1)

    def consumer():
        yield env.timeout(5)
        while len([e for e in log if e[0] == "pop"]) < 3:
            k = fifo.try_pop()
            if k is None:
                yield fifo.data_arrived()
                continue
            log.append(("pop", k, env.now))
            yield env.timeout(10)  # testing the packet's triangles
            fifo.free(2)

    env.process(producer())
    env.process(consumer())
    env.run()
    # the producer waits from cycle 1 for the space freed at 15; the consumer, finding the
    # FIFO empty at 15, takes the packet pushed in that same cycle
    assert log == [("push", 0, 0), ("pop", 0, 5), ("push", 1, 15), ("pop", 1, 15),
                   ("push", 2, 25), ("pop", 2, 25)]
    assert fifo.level == 2 and fifo.space.event is None and fifo.data.event is None
