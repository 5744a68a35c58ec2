"""h457, a review of h450 (an interrupted sweep's line says how many of its points its folder keeps) and h453 (the
blur and period warnings).

(A) The line's numbers are the rows the folder's ``sweep.jsonl`` holds (tests/test_signals.py's ``tlm_lines``) in
every stage of the sweep: before it claimed its folder they were the points done in ``points/`` (an earlier run's
failed row left uncounted: 2 of 5 said, 3 rows kept), its ``--reference`` step and its summary after its rows were
written said a bare ``tlm: interrupted``.
(B) ``tlm granularity`` leaves the blur line out of its ``granularity: ...`` lines, as the reference's other lines.
"""

from __future__ import annotations

import json
import os
import signal

import pytest

import tlm.experiments.sweep as sweep_mod
from tlm.cli import main

from .test_signals import rows, sweep_file, tlm_lines
from .test_sweep_interrupt_line_h450 import _signalled_at


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _sweep(path, out, *more: str) -> int:
    return main(["sweep", str(path), "--out", str(out), "--jobs", "1", "--no-report", "--no-progress", *more])


def _signal_in(monkeypatch, name: str, sig: int = signal.SIGINT) -> None:
    """The sweep's ``name`` (a function of tlm.experiments.sweep) signalled as it is called."""
    real = getattr(sweep_mod, name)

    def signalled(*a, **k):
        os.kill(os.getpid(), sig)
        return real(*a, **k)

    monkeypatch.setattr(sweep_mod, name, signalled)


def _earlier_run(tmp_path, monkeypatch, capsys, n: int = 5):
    """A sweep of ``n`` points interrupted at its 4th, its 2nd failed: 3 rows kept, one failed."""
    path, out = sweep_file(tmp_path, n=n), tmp_path / "o"
    _signalled_at(monkeypatch, 4, signal.SIGINT, fails=(2,))
    assert _sweep(path, out) == 130
    assert tlm_lines(capsys.readouterr().err, out, n)[0].startswith("tlm: interrupted with 3 of 5 points finished "
                                                                     "(1 failed, to run again)")
    monkeypatch.undo()
    return path, out


def test_before_the_folder_is_claimed_the_line_counts_its_rows_failed_ones_too(tmp_path, monkeypatch, capsys):
    path, out = _earlier_run(tmp_path, monkeypatch, capsys)
    _signal_in(monkeypatch, "open_executor", signal.SIGTERM)  # (the rerun: its workers starting)
    assert _sweep(path, out) == 143
    assert tlm_lines(capsys.readouterr().err, out, 5) == [
        f"tlm: terminated (SIGTERM) with 3 of 5 points finished (1 failed, to run again) and kept in {out}; run the "
        "same command to go on"]
    assert sorted(r["status"] for r in rows(out)) == ["failed", "ok", "ok"]


def test_a_signal_during_the_reference_step_says_what_the_folder_keeps(tmp_path, monkeypatch, capsys):
    path, out = _earlier_run(tmp_path, monkeypatch, capsys)
    _signal_in(monkeypatch, "sweep_references")
    assert _sweep(path, out, "--reference") == 130
    assert tlm_lines(capsys.readouterr().err, out, 5) == [
        f"tlm: interrupted with 3 of 5 points finished (1 failed, to run again) and kept in {out}; run the same "
        "command to go on"]


def test_a_signal_after_every_row_is_written_says_so(tmp_path, monkeypatch, capsys):
    path, out = sweep_file(tmp_path, n=3), tmp_path / "o"
    _signal_in(monkeypatch, "other_names")  # (the sweep's summary, after its rows)
    assert _sweep(path, out) == 130
    assert tlm_lines(capsys.readouterr().err, out, 3) == [
        f"tlm: interrupted with all 3 points finished and kept in {out}"]


# (B) a granularity study of a photon-map frame whose reference has 5x fewer photons a round
TINY = {"mode": "pmap", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1}, "photons": {"count": 2000},
        "reference": {"k_nearest": 20, "spp": 1, "min_rounds": 2, "max_rounds": 4, "photons": 400},
        "arch": {"frames": 2}}


def test_granularity_leaves_the_blur_line_out(tmp_path, capsys):
    """(A guard the review asked for: the filter held before it, rendered and cached alike.)"""
    import tlm

    cfg = tlm.load_config({"scene": "cornell", **TINY})
    ran = tlm.run(cfg, tmp_path / "r", outputs="images")  # (its reference computed and cached)
    assert any("measure the reference's blur more" in w for w in ran["warnings"])
    study = tmp_path / "g.yaml"
    study.write_text(json.dumps({"base": {"scene": "cornell", **TINY}, "packet_sizes": [16, 64]}))
    for _ in range(2):  # (the frame rendered, then read from the cache)
        assert main(["granularity", str(study), "--out", str(tmp_path / "g"), "--no-report"]) == 0
        err = capsys.readouterr().err
        assert "blur" not in err and "granularity: the photon-map" not in err, err
    said = json.loads((tmp_path / "g" / "granularity_summary.json").read_text())["warnings"]
    assert not any("blur" in w for w in said), said


def test_no_blur_line_where_no_kernel_of_the_run_follows_its_photons():
    """A run whose every radius is fixed: its 4.02x the reference's photons make none of its kernels narrower, so
    the line's premise does not hold. Final gathering's global map is gathered within that fixed radius too
    (tlm.render.pmap.global_radius: radius_fraction given), so it adds no kernel of its density (h465; h457 took
    it for one); the caustic map's density rule does."""
    from tlm.config import config_from_dict
    from tlm.experiments.run_warnings import blur_warnings

    error = {"available": True, "reference": "k"}
    fixed = {"radius_fraction": 0.02, "caustic_radius_fraction": 0.01, "final_gather": 0}
    for key, value, lines in ((None, None, 0), ("final_gather", 16, 0), ("caustic_radius_fraction", None, 1)):
        cfg = config_from_dict({"scene": "cornell", "mode": "pmap", "estimate": {**fixed, key: value} if key else
                                fixed}, "t")
        assert len(blur_warnings(error, cfg, 482000, 120000)) == lines, key
