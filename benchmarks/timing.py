"""Shared timing helper of the benchmarks (run them as ``python benchmarks/bench_*.py``)."""

from __future__ import annotations

import time
from collections.abc import Callable


def best_of(fn: Callable[[], object], repeat: int) -> float:
    """The shortest wall time of ``repeat`` calls of ``fn``, in seconds."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


_FAILED: list[str] = []


def verdict(ok: bool, text: str, indent: str = "") -> str:
    """Print ``PASS: text`` or ``FAIL: text`` (and remember a failure for :func:`exit_status`)."""
    line = f"{indent}{'PASS' if ok else 'FAIL'}: {text}"
    print(line)
    if not ok:
        _FAILED.append(text)
    return line


def exit_status() -> None:
    """Exit 1 if any bar failed, 0 otherwise (a crash exits non-zero on its own)."""
    raise SystemExit(1 if _FAILED else 0)
