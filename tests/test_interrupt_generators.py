"""A Ctrl-C during numba's install of a registry, in an API call: held to the install's end, as
one during an import (tlm/whole_imports.py). numba streams each registry's new entries to a
context through a generator (``numba.core.utils.stream_list``); a KeyboardInterrupt raised in it
finishes it, and every later refresh of that context (every compile) failed with ``RuntimeError:
generator raised StopIteration``. A Ctrl-C held to the end of numba's import of
``numba.np.arraymath`` was raised in that refresh about one time in six
(tests/test_api_interrupt.py). Here the Ctrl-C is sent from inside the generator itself: the
registry's list of entries sends it when the generator reads its length."""

from __future__ import annotations

import itertools
import signal
from typing import ClassVar

import pytest

from tlm import whole_imports
from tlm.whole_imports import imports_whole

pytest.importorskip("numba")

from numba.core import types
from numba.core.typing import context, signature, templates


class SignallingList(list):
    """A registry's list of entries that sends ``times`` SIGINTs the first time its length is read
    (by ``stream_list``, in the generator's own frame, at each install of the registry)."""

    def __init__(self, items: list, times: int):
        super().__init__(items)
        self.times = times

    def __len__(self) -> int:
        times, self.times = self.times, 0
        for _ in range(times):
            signal.raise_signal(signal.SIGINT)
        return super().__len__()


_NAMES = (f"tlm_test_function_{i}" for i in itertools.count())


def _template(registry: templates.Registry) -> str:
    """A template registered in ``registry``, of a function of its own: its key."""

    class Template(templates.ConcreteTemplate):
        key = next(_NAMES)
        cases: ClassVar = [signature(types.int64, types.int64)]

    return registry.register(Template).key


@pytest.fixture
def sigint():
    before = signal.signal(signal.SIGINT, signal.default_int_handler)  # (a test runner's worker may ignore it)
    yield
    signal.signal(signal.SIGINT, before)


def _install(times: int):
    """``(call, ctx, registry, keys)``: ``call()``, an API call, installs ``registry`` (three
    templates, whose list sends ``times`` SIGINTs at its first install) into ``ctx``, a fresh
    typing context (numba's own stay untouched)."""
    ctx = context.Context()
    registry = templates.Registry()
    keys = [_template(registry) for _ in range(3)]
    registry.functions = SignallingList(registry.functions, times)

    @imports_whole
    def call() -> None:
        ctx.install_registry(registry)

    return call, ctx, registry, keys


def test_a_ctrl_c_in_numbas_install_of_a_registry_is_held_to_its_end(sigint):
    call, ctx, registry, keys = _install(1)
    with pytest.raises(KeyboardInterrupt):  # the Ctrl-C still stops the call ...
        call()
    assert all(key in ctx._functions for key in keys)  # ... once the install is whole
    keys.append(_template(registry))  # and the registry's loader still streams what is added to it
    ctx.install_registry(registry)  # (was: RuntimeError: generator raised StopIteration)
    assert keys[-1] in ctx._functions
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_second_ctrl_c_in_numbas_install_of_a_registry_says_to_restart(sigint, monkeypatch):
    """Two Ctrl-C in one install: the second goes through (the user insists) and breaks the
    registry's loader; the next API call says in one line that the process must be restarted,
    rather than ``generator raised StopIteration`` in numba's refresh."""
    monkeypatch.setattr(whole_imports, "_CUT_REGISTRIES", set(), raising=False)  # (later calls here work)
    call, _, _, _ = _install(2)
    with pytest.raises(KeyboardInterrupt):
        call()
    for _ in range(2):
        with pytest.raises(RuntimeError) as error:
            call()
        message = str(error.value)
        assert message.startswith("a Ctrl-C (pressed twice) interrupted numba's install of its registries"), message
        assert "restart the Python process" in message and "\n" not in message
