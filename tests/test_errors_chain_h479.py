"""h479: one walk of an exception's chain of causes and contexts, :func:`tlm.errors.chain`, where five loops of
their own walked it (``memory_problem``, ``thread_problem``, ``settle_landed``, ``interrupted_by`` and the CLI's
``_stopped_compute``, reached through :func:`tlm.cli_report.reference_cut_short`). The tests of ``chain`` itself
fail before (it was missing); those of its callers passed before and pass after, each with a loop of contexts
(which ends) and a chain deeper than any recursion would go (which is walked to its end): their behaviour kept."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from tlm import errors
from tlm.cli_report import reference_cut_short
from tlm.cli_signals import Interrupted

DEEP = 5000  # (links: beyond Python's recursion limit, so a walk that recursed would fail)


def linked(*chain: BaseException, last: BaseException | None = None, cause: bool = False) -> BaseException:
    """``chain[0]``, each exception of ``chain`` linked to the next (by ``__cause__`` where ``cause``, else by
    ``__context__``), the last one to ``last`` where given (the first, for a loop), else left as it is."""
    for e, after in zip(chain, (*chain[1:], last) if last is not None else chain[1:]):
        if cause:
            e.__cause__ = after
        else:
            e.__context__ = after
    return chain[0]


def deep(end: BaseException, *, cause: bool = False) -> BaseException:
    """A chain of :data:`DEEP` ValueErrors that ends with ``end``."""
    return linked(*(ValueError(f"wrapped {i}") for i in range(DEEP)), end, cause=cause)


def loop(*inside: BaseException) -> BaseException:
    """A ValueError whose contexts come back to it, through ``inside``."""
    head = ValueError("head")
    return linked(head, *inside, ValueError("tail"), last=head)


# chain itself (missing before h479)


def test_chain_yields_the_exception_then_its_cause_before_its_context():
    a, b, c, d = ValueError("a"), KeyError("b"), OSError("c"), TypeError("d")
    a.__cause__, a.__context__ = b, c
    b.__context__ = d  # (no cause: its context)
    assert list(errors.chain(a)) == [a, b, d]
    assert list(errors.chain(c)) == [c]


def test_chain_follows_a_raise_from_inside_a_handler_by_its_cause():
    try:
        try:
            raise KeyError("handled")
        except KeyError:
            try:
                raise OSError("the cause")
            except OSError as cause:
                raise ValueError("raised") from cause
    except ValueError as e:
        raised = e
    assert [type(e) for e in errors.chain(raised)] == [ValueError, OSError, KeyError]  # (the cause's context last)
    assert isinstance(raised.__context__, OSError) and isinstance(raised.__cause__, OSError)


def test_chain_takes_the_context_where_there_is_no_cause():
    try:
        try:
            raise KeyError("first")
        except KeyError:
            raise ValueError("second")  # noqa: B904 (the context is the point)
    except ValueError as e:
        raised = e
    assert [type(e) for e in errors.chain(raised)] == [ValueError, KeyError]


def test_chain_ends_at_a_loop_giving_each_exception_once():
    a, b = ValueError("a"), KeyError("b")
    a.__context__, b.__context__ = b, a
    assert list(errors.chain(a)) == [a, b]
    assert list(errors.chain(b)) == [b, a]
    c = OSError("c")
    c.__cause__ = c  # (its own cause)
    assert list(errors.chain(c)) == [c]


def test_chain_of_none_is_empty_and_a_deep_chain_is_walked_whole():
    assert list(errors.chain(None)) == []
    end = KeyError("end")
    walked = list(errors.chain(deep(end, cause=True)))
    assert len(walked) == DEEP + 1 and walked[-1] is end
    assert len({id(e) for e in walked}) == DEEP + 1


def test_chain_reads_the_next_link_after_its_caller_is_done_with_an_exception():
    """(As the loops did: settle_landed's caller may change an exception it was given before the walk goes on.)"""
    a, b, c = ValueError("a"), KeyError("b"), OSError("c")
    a.__context__ = b
    walk = errors.chain(a)
    assert next(walk) is a
    a.__cause__ = c
    assert list(walk) == [c]


# its callers: the same answers before and after h479


@pytest.mark.parametrize("cause", [False, True])
def test_memory_problem_finds_a_memory_error_deep_in_the_chain_and_none_in_a_loop(monkeypatch, cause):
    monkeypatch.setattr(errors, "address_space_limit", lambda: None)
    e = deep(MemoryError("Unable to allocate 8.24 MiB for an array"), cause=cause)
    assert errors.memory_problem(e) == "out of memory: Unable to allocate 8.24 MiB for an array"
    assert errors.memory_problem(loop(KeyError("k"), OSError("o"))) is None
    assert errors.memory_problem(loop(MemoryError("in the loop"))) == "out of memory: in the loop"
    assert errors.memory_problem(None) is None


def test_memory_problem_stops_at_a_library_unmapped_under_a_limit_and_names_it(monkeypatch):
    unmapped = f"libfoo.so: {errors.UNMAPPED}"
    monkeypatch.setattr(errors, "address_space_limit", lambda: None)  # (no limit: not memory's)
    assert errors.memory_problem(deep(ImportError(unmapped))) is None
    assert errors.memory_problem(loop(OSError(unmapped))) is None
    monkeypatch.setattr(errors, "address_space_limit", lambda: 512 * 2**20)
    limited = " (the address space of this process is limited to 512 MiB: ulimit -v)"
    # the first found is named: the unmapped library, before a MemoryError further along
    assert errors.memory_problem(deep(linked(ImportError(unmapped), MemoryError("later")))) == \
        f"out of memory: {unmapped}{limited}"
    assert errors.memory_problem(loop(OSError(unmapped))) == f"out of memory: {unmapped}{limited}"
    assert errors.memory_problem(loop(KeyError("k"))) is None


@pytest.mark.parametrize("cause", [False, True])
def test_thread_problem_finds_a_refused_thread_deep_in_the_chain_and_none_in_a_loop(cause):
    found = errors.thread_problem(deep(RuntimeError(errors.THREAD_REFUSED), cause=cause))
    assert found is not None and found.startswith(f"no new thread could be started: {errors.THREAD_REFUSED}")
    assert errors.thread_problem(loop(RuntimeError("another runtime error"))) is None
    assert errors.thread_problem(loop(RuntimeError(errors.THREAD_REFUSED))) is not None
    assert errors.thread_problem(deep(RuntimeError("another runtime error"))) is None
    assert errors.thread_problem(None) is None


@pytest.mark.parametrize("cause", [False, True])
def test_interrupted_by_finds_the_interrupt_deep_in_the_chain_and_none_in_a_loop(cause):
    interrupt = KeyboardInterrupt()
    assert errors.interrupted_by(deep(interrupt, cause=cause)) is interrupt
    in_loop = KeyboardInterrupt()
    assert errors.interrupted_by(loop(in_loop)) is in_loop
    assert errors.interrupted_by(loop(KeyError("k"), TypeError("no interrupt"))) is None
    assert errors.interrupted_by(None) is None


def made_of_interrupt() -> TypeError:
    """An error a C extension made of an interrupt (nanobind's words), raised in a frame a signal landed in."""
    errors.signal_landed(sys._getframe())
    try:
        raise TypeError("could not export nb::ndarray: ... KeyboardInterrupt")
    except TypeError as e:
        return e


@pytest.mark.parametrize("shape", ["deep", "loop"])
def test_settle_landed_marks_an_error_made_of_an_interrupt_deep_in_the_chain_or_in_a_loop(shape):
    try:
        made = made_of_interrupt()
        e = deep(made) if shape == "deep" else loop(made)
        errors.settle_landed(e)
        errors.settle_landed(loop(KeyError("k")))  # (a loop of none: ends)
    finally:
        errors.forget_landed()
    assert isinstance(errors.interrupted_by(e), KeyboardInterrupt)  # (by its mark: no signal landed now)
    assert errors.interrupted_by(loop(TypeError("could not export: KeyboardInterrupt"))) is None  # (unmarked)


class Partial:
    """A reference compute's saved rounds, as :mod:`tlm.experiments.reference_resume` leaves them on an error."""

    path = Path("references/key.partial.npz")
    saved = off = held_off = 0

    def kept(self) -> int:
        return 3

    def others(self) -> int:
        return 0


@pytest.mark.parametrize("shape", ["deep", "loop"])
def test_reference_cut_short_finds_the_saved_rounds_deep_in_the_chain_or_in_a_loop(shape):
    stopped = ValueError("stopped")
    stopped.reference_partial = Partial()
    interrupt = KeyboardInterrupt()
    e = linked(interrupt, deep(stopped)) if shape == "deep" else linked(interrupt, loop(stopped))
    with pytest.raises(Interrupted) as raised, reference_cut_short():
        raise e
    assert "its 3 rounds are kept in references/key.partial.npz; run the same command to resume from round 3" in \
        str(raised.value)
    assert raised.value.__cause__ is interrupt
    none_saved = linked(KeyboardInterrupt(), loop(KeyError("k")))
    with pytest.raises(KeyboardInterrupt) as bare, reference_cut_short():  # (none saved: the interrupt as it is)
        raise none_saved
    assert bare.value is none_saved


def test_a_forked_worker_that_ended_abruptly_under_an_address_space_limit_is_out_of_memory(monkeypatch):
    """(h485: at ulimit -v 452000 a forked worker died and the command said an internal error, with a traceback.)"""
    from concurrent.futures.process import BrokenProcessPool

    broken = BrokenProcessPool("A process in the process pool was terminated abruptly while the future was running")
    monkeypatch.setattr(errors, "address_space_limit", lambda: 452000 * 1024)
    line = errors.memory_problem(broken)
    assert line == ("out of memory: a forked worker process ended abruptly (A process in the process pool was "
                    "terminated abruptly while the future was running) (the address space of this process is "
                    "limited to 441 MiB: ulimit -v)")
    monkeypatch.setattr(errors, "address_space_limit", lambda: None)  # (no limit: a worker's crash is tlm's own)
    assert errors.memory_problem(broken) is None
