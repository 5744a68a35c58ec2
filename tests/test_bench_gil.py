"""benchmarks/bench_gil.py counts a py-spy raw file's samples of the batches, by tlm frame."""

from __future__ import annotations

from pathlib import Path


def test_samples_counts_only_the_batches_by_innermost_tlm_frame(monkeypatch, tmp_path):
    """Only stacks under ``render_batches`` count (the scene load and photon trace before
    them do not); each is booked to its innermost tlm frame and that frame's caller, with
    numpy's and numba's frames below them ignored."""
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_gil

    raw = tmp_path / "raw.txt"
    raw.write_text(
        "<module> (one.py:3);render (tlm/experiments/run.py:184);load_scene (tlm/scenes/load.py:10) 40\n"
        "<module> (one.py:3);render (tlm/experiments/run.py:184);render_batches (tlm/render/batches.py:96);"
        "_run_batch (tlm/render/batches.py:278);emitted (tlm/kernels/shade.py:265);"
        "solve (numpy/linalg/_linalg.py:400) 7\n"
        "<module> (one.py:3);render (tlm/experiments/run.py:184);render_batches (tlm/render/batches.py:96);"
        "_run_batch (tlm/render/batches.py:278);emitted (tlm/kernels/shade.py:270) 5\n"
        "<module> (one.py:3);render (tlm/experiments/run.py:184);render_batches (tlm/render/batches.py:96);"
        "cast (tlm/render/frame.py:208) 2\n"
    )
    total, where = bench_gil.samples(raw)
    assert total == 14
    assert where == {"emitted < _run_batch": 12, "cast < render_batches": 2}
