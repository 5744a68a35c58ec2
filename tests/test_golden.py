"""Speed-ups change nothing: images, hits, work counts and cycles equal the golden file.

``tests/data/golden.json`` was written (``python -m tests.golden --write``) before the
performance work of issue [7 of 7] (its ``cycles.throughput`` entries again when TThru
became a steady-state measure); every case here recomputes one entry and compares
it exactly (SHA-256 of the arrays' bytes, integers as they are).

numpy's float64 ``sin``/``cos``/``exp``/``log`` differ in the last bit between CPUs with
AVX512_SKX (SVML) and without, so the ``run:`` entries are kept per CPU class
(:func:`tests.golden.math_class`): ``golden.json`` (AVX512_SKX) and ``golden.avx2.json``.
"""

from __future__ import annotations

import json

import pytest

from tests import golden

GOLDEN = golden.load()


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(GOLDEN))
def test_same_as_golden(name, tmp_path, monkeypatch):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))  # render, never read a cache
    now = golden.compute([name.split(":", 1)[1] if name.startswith("run:") else name])
    diff = golden.differences(GOLDEN[name], now[name])
    assert not diff, f"{name} differs from tests/data/{golden.GOLDEN.name}:\n" + "\n".join(diff[:20])


def test_a_change_is_caught():
    """The comparison sees a changed hash, a changed count and a missing entry."""
    a = {"x": {"t": "00aa", "n": 3}, "y": 1}
    assert golden.differences(a, a) == []
    assert golden.differences(a, {"x": {"t": "00ab", "n": 3}, "y": 1}) == ["x.t: '00aa' -> '00ab'"]
    assert golden.differences(a, {"x": {"t": "00aa", "n": 4}}) == ["x.n: 3 -> 4", "y: missing"]


def test_classes_share_the_kernels():
    """Both CPU classes' files hold the same entries, and traversal, intersection and the
    BSP (no transcendental function) have the same fingerprints in both."""
    files = [golden.DATA / "golden.json", golden.DATA / "golden.avx2.json"]
    a, b = (json.loads(f.read_text()) for f in files)
    assert sorted(a) == sorted(b)
    kernels = [k for k in a if k.startswith("kernel:")]
    assert kernels and all(a[k] == b[k] for k in kernels)
