"""A last read's smaller findings (h309).

1. A named FIFO (``mkfifo c``) was called "a pipe", and ``tlm run c`` said ``runs/c`` was "a name not its own":
   it has a name and a folder of its own (tlm.config.file_folder), but is read once, so --out is still asked.
2. ``tlm run``'s progress bar said "5 frames" while a dynamic stream of two images in flight runs on, up to 64.
3. ``tlm scaling`` said a two-N fit's eq. 5.2 "not both determined" where only its slowest-pipeline variant was:
   each fit is judged alone now, by the report's rule (tlm.report.scaling.untested_why).
4. tlm.scenes.compose.plain_path, an alias of tlm.scenes.meshes.shown_path, is gone.
"""

from __future__ import annotations

import os
from contextlib import contextmanager, nullcontext, suppress
from types import SimpleNamespace

import pytest

from tlm.api_common import nameless
from tlm.arch.model import settling
from tlm.cli import main
from tlm.cli_tables import print_scaling
from tlm.config import ArchConfig, file_folder
from tlm.experiments import run as run_module
from tlm.registry import SCHEDULERS
from tlm.report.scaling import error_text
from tlm.scenes import compose


@pytest.fixture
def fifo(tmp_path):
    path = tmp_path / "c"
    os.mkfifo(path)  # (no writer: whatever opened it to read would wait; the refusals read nothing)
    return path


def test_a_named_fifo_is_said_as_one_and_asks_for_out_with_its_own_name(fifo, tmp_path, monkeypatch, capsys):
    assert nameless(fifo) == "a named FIFO" and file_folder(fifo) == tmp_path  # (its relative paths: its folder)
    monkeypatch.chdir(tmp_path)
    assert main(["run", "c", "--no-report"]) == 2
    err = capsys.readouterr().err
    assert err == ("tlm: error: c: is a named FIFO, read once: give --out (runs/c, the default, would be the folder of "
                   "every config written to it, one replacing another)\n"), err
    assert not (tmp_path / "runs").exists()


def test_an_anonymous_pipe_is_still_a_pipe():
    r, w = os.pipe()
    try:
        assert nameless(f"/dev/fd/{r}") == "a pipe"
    finally:
        os.close(r)
        os.close(w)


def _postfix(monkeypatch, arch: ArchConfig) -> str:
    """The postfix simulate_run's progress bar shows for ``arch`` (the model itself not run)."""
    said = {}

    @contextmanager
    def bar(progress, **kwargs):
        said.update(kwargs)
        yield SimpleNamespace(update=lambda *a: None)

    monkeypatch.setattr(run_module, "progress_bar", bar)
    monkeypatch.setattr(run_module, "Ticking", lambda b: nullcontext())
    monkeypatch.setattr(run_module, "simulate", lambda *a: None)
    monkeypatch.setattr(run_module, "release_memory", lambda: None)
    run_module.simulate_run(SimpleNamespace(cfg=SimpleNamespace(arch=arch), functional=lambda: None), None)
    return said["postfix"]


def test_the_progress_bar_says_a_settling_stream_runs_past_arch_frames(monkeypatch):
    dynamic = ArchConfig(scheduler="dynamic", images_in_flight=2, frames=5)
    assert _postfix(monkeypatch, dynamic) == "5 to 64 frames, until it settles"
    assert _postfix(monkeypatch, ArchConfig(scheduler="dynamic", images_in_flight=2, frames=80)) == "80 frames"
    for name in SCHEDULERS:  # (the bar's rule is the model's: tlm.arch.model.settling)
        for k in (1, 2):
            arch = ArchConfig(scheduler=name, images_in_flight=k, frames=5)
            assert ("to 64" in _postfix(monkeypatch, arch)) == settling(SimpleNamespace(scheduler=name), arch)


def test_tlm_scaling_judges_each_two_n_fit_alone_as_the_report_does(tmp_path, capsys):
    fit = {"scene": "ring", "mode": "rcast", "scheduler": "static", "target": "throughput", "A": 1.0, "B": 1.0,
           "pipelines": [1, 4], "max_abs_rel_error": 2.25, "slowest": {"max_abs_rel_error": 0.0}}
    print_scaling({"notes": [], "fits": [fit]}, tmp_path)
    line = capsys.readouterr().out.splitlines()[1]
    assert line.endswith("(N = 1, 4 alone, a test of nothing: eq. 5.2 A and B not both determined; slowest-pipeline "
                         "variant: exact by construction)"), line
    from tlm.report.scaling import untested_why  # (the one rule, the report's captions': h309)

    rows = [{"pipelines": 1}, {"pipelines": 4}]
    eq52, slowest = error_text({**fit, "rows": rows}), error_text({**fit["slowest"], "rows": rows})
    assert eq52 == f"225.0% (N = 1 and 4 alone: {untested_why(2.25)})" and f"eq. 5.2 {untested_why(2.25)};" in line
    assert slowest == f"0.0% (N = 1 and 4 alone: {untested_why(0.0)})" and line.endswith(f"{untested_why(0.0)})")
    for a, b in ((0.0, 0.5), (0.5, 0.5)):  # (the command's words and the report's: one rule)
        print_scaling({"notes": [], "fits": [{**fit, "max_abs_rel_error": a, "slowest": {"max_abs_rel_error": b}}]},
                      tmp_path)
        line = capsys.readouterr().out.splitlines()[1]
        assert line.endswith(f"eq. 5.2 {untested_why(a)}; slowest-pipeline variant: {untested_why(b)})"), line


def test_the_mesh_path_alias_is_gone():
    assert not hasattr(compose, "plain_path") and "plain_path" not in compose.__all__


def test_calibrate_of_a_named_fifo_asks_for_a_table_before_it_reads_it(fifo, capsys):
    """(with /tmp/h309/cli.patch: tlm/cli.py's check named "a pipe" alone, so a named FIFO was read for its own
    table and then again for the fit, which waited for a writer that never came)"""
    import threading
    import time

    def unblock():  # (where the FIFO is opened to read after all: an end of file, not a wait without end)
        time.sleep(10)
        with suppress(OSError):
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))

    threading.Thread(target=unblock, daemon=True).start()
    assert main(["calibrate", str(fifo)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"tlm: error: {fifo}: is a named FIFO, read once: "), err
    assert err.strip().endswith("give --write FILE, or --dry-run")
