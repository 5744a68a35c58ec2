"""Pipes and sweep files (h304).

1. A sweep file was read twice where it is a regular file (``experiment_file``'s check of its kind, then
   the loader), and a piped one skipped that check: ``tlm sweep <(cat configs/cornell.yaml)`` said
   ``scene: unknown key``. The loader now checks the data of its one read (``tlm.api_common.kind_check``),
   the same message for a regular file; a pipe's says to save it to a file (``/dev/fd/63`` names nothing later).
2. With no ``--out``, a piped config's output went to ``runs/63`` (``runs/stdin``): every piped config's one
   folder. A config of no name of its own is refused, one line, exit status 2, nothing read or written; the
   ``tlm reference`` command ``tlm run`` suggests names no ``/dev/fd/63`` either.
3. ``tlm sweep --dry-run`` left out the ``render.threads`` warning (and ``--jobs``') the sweep says.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import pytest

import tlm.kernels.threads
from tlm import api, config
from tlm.api_common import granularity_study
from tlm.cli import _reference_command, main
from tlm.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
CORNELL = ROOT / "configs" / "cornell.yaml"
TINY = "scene: cornell\nmode: rcast\nresolution: [8, 8]\n"
SWEEP = ("base: {scene: cornell, mode: rcast, resolution: [8, 8], render: {threads: 2}}\n"
         "grid:\n  arch.fifo_depth: [1, 2]\n")

needs_dev_fd = pytest.mark.skipif(not os.path.isdir("/dev/fd"), reason="no /dev/fd here")


@pytest.fixture
def reads(monkeypatch):
    """The paths :func:`tlm.config.read_bytes` reads (every YAML read, every ``read_text``), in order."""
    seen: list[str] = []
    real = config.read_bytes

    def counted(path):
        seen.append(str(path))
        return real(path)

    monkeypatch.setattr(config, "read_bytes", counted)
    return seen


def _error(call) -> str:
    with pytest.raises(InputError) as e:
        call()
    return str(e.value)


def test_a_sweep_file_is_read_once(tmp_path, reads):
    sweep = tmp_path / "s.yaml"
    sweep.write_text(SWEEP)
    plan = api.run_sweep(sweep, tmp_path / "o", dry_run=True, jobs=1)
    assert plan.points == 2 and reads.count(str(sweep)) == 1
    cornell = tmp_path / "c.yaml"  # (a run config given to the sweep: its one read says so)
    cornell.write_text(TINY)
    assert _error(lambda: api.run_sweep(cornell, tmp_path / "o2")) == (
        f"{cornell}: a run config (it has scene:), not a sweep file: run it with tlm run {cornell}")
    assert reads.count(str(cornell)) == 1 and not (tmp_path / "o2").exists()


@needs_dev_fd
def test_a_piped_run_config_given_to_the_sweep_names_the_command(tmp_path, piped, capsys):
    pipe = piped(CORNELL.read_text())
    assert main(["sweep", pipe, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.strip() == (f"tlm: error: {pipe}: a run config (it has scene:), not a sweep file: save it to a file "
                           "and run it with tlm run FILE")
    assert not (tmp_path / "o").exists()
    # (a regular file's message as it was; a piped sweep file given to tlm run names tlm sweep)
    assert main(["sweep", str(CORNELL), "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err.strip().endswith("not a sweep file: run it with tlm run cornell")
    assert _error(lambda: api.load_config(piped(SWEEP))).endswith("save it to a file and run it with tlm sweep FILE")


@needs_dev_fd
@pytest.mark.parametrize("command", ["run", "sweep", "thesis", "extreme", "granularity", "error-vs-cost"])
def test_a_piped_config_needs_out(tmp_path, piped, capsys, monkeypatch, command):
    monkeypatch.chdir(tmp_path)
    text = TINY if command == "run" else "base: {resolution: [8, 8]}\nnot_a_key: 1\n"  # (old: its own error)
    pipe = piped(text)
    assert main([command, pipe, "--no-report"] if command != "sweep" else [command, pipe, "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"tlm: error: {pipe}: is a pipe: give --out (")
    assert f"runs/{Path(pipe).name}" in err and not (tmp_path / "runs").exists()
    assert os.read(int(Path(pipe).name), 100) == text.encode()  # (refused before it is read)


@needs_dev_fd
def test_a_file_given_by_a_descriptors_name_needs_out(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    sweep = tmp_path / "s.yaml"
    sweep.write_text(SWEEP)
    fd = os.open(sweep, os.O_RDONLY)  # (/dev/stdin < s.yaml: every such config's name is stdin)
    try:
        assert main(["sweep", f"/dev/fd/{fd}", "--dry-run"]) == 2
    finally:
        os.close(fd)
    assert "is a file descriptor's name: give --out" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()
    assert main(["sweep", str(sweep), "--dry-run"]) == 0  # (a file's own name: runs/s)
    assert "into runs/s:" in capsys.readouterr().out


@needs_dev_fd
def test_the_reference_command_of_a_piped_config_says_to_save_it(piped):
    pipe = piped(TINY)
    line = _reference_command(argparse.Namespace(config=pipe, argv=["run", pipe, "--out", "x"]), ["seed=1"])
    assert line == f"tlm reference FILE --set seed=1 (FILE: the config, saved to a file: {pipe} is a pipe)"
    assert _reference_command(argparse.Namespace(config="c.yaml", argv=["run", "c.yaml"]), []) == \
        "tlm reference c.yaml"


@needs_dev_fd
def test_a_piped_config_given_a_base_is_told_its_paths_start_at_the_working_folder(piped, tmp_path):
    """(h304's patch of tlm/api.py: a pipe's relative paths start at the working folder, not at 'its own')"""
    message = _error(lambda: api.load_config(piped(TINY), base=tmp_path))
    assert f"relative paths start at the working folder ({Path.cwd()}; a pipe is in none), not at base" in message
    assert f"start at its own folder ({CORNELL.parent}), not at base" in _error(
        lambda: api.load_config(CORNELL, base=tmp_path))


def test_a_dry_run_says_the_threads_warnings_of_the_sweep(tmp_path, monkeypatch):
    monkeypatch.setattr(tlm.kernels.threads, "available", lambda: 1)
    sweep = tmp_path / "s.yaml"
    sweep.write_text(SWEEP)
    plan = api.run_sweep(sweep, tmp_path / "o", dry_run=True, jobs=1)
    assert [w for w in plan.warnings if "render.threads = 2 is more than the 1 CPU" in w]
    monkeypatch.setattr(tlm.kernels.threads, "available", lambda: 3)
    plan = api.run_sweep(sweep, tmp_path / "o", dry_run=True, jobs=2)
    assert [w for w in plan.warnings if w.startswith("--jobs: 2 worker processes, each with render.threads = 2")]
    assert not api.run_sweep(sweep, tmp_path / "o", dry_run=True, jobs=1).warnings
    assert not (tmp_path / "o").exists()


@needs_dev_fd
def test_calibrate_of_a_pipe_asks_for_a_table_before_it_reads_the_pipe(piped, capsys):
    text = (ROOT / "configs" / "thesis.yaml").read_text()
    pipe = piped(text)  # (its own table was found by one read, the fit read it again: 'must be a mapping')
    assert main(["calibrate", pipe]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"tlm: error: {pipe}: is a pipe, read once: ")
    assert err.strip().endswith("give --write FILE, or --dry-run")
    assert os.read(int(Path(pipe).name), len(text) + 1) == text.encode()


# (h304's patch of tlm/experiments/study.py: a study file's kind checked on its one read, as a sweep file's)
STUDIES = {"thesis": "a thesis study file", "extreme": "an extreme-cases study file",
           "granularity": "a granularity study file", "error-vs-cost": "an error-vs-cost study file"}


@needs_dev_fd
@pytest.mark.parametrize("command", [*STUDIES, "calibrate"])
def test_a_piped_run_config_given_to_a_study_names_the_command(tmp_path, piped, capsys, command):
    pipe = piped(TINY)
    argv = [command, pipe, *(["--dry-run"] if command == "calibrate" else ["--out", str(tmp_path / "o")])]
    assert main(argv) == 2
    wanted = STUDIES.get(command, "a thesis study file (tlm calibrate fits the programs to a thesis study's scenes)")
    assert capsys.readouterr().err.strip() == (f"tlm: error: {pipe}: a run config (it has scene:), not {wanted}: "
                                               "save it to a file and run it with tlm run FILE")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("command", [*STUDIES, "calibrate"])
def test_a_study_file_is_read_once_and_its_kind_named_as_before(tmp_path, reads, command):
    cornell = tmp_path / "c.yaml"
    cornell.write_text(TINY)
    call = {"thesis": lambda p: api.thesis(p, tmp_path / "o"), "extreme": lambda p: api.extreme(p, tmp_path / "o"),
            "granularity": lambda p: api.granularity(p, tmp_path / "o"),
            "error-vs-cost": lambda p: api.error_vs_cost(p, tmp_path / "o"),
            "calibrate": lambda p: api.calibrate(p)}[command]
    wanted = STUDIES.get(command, "a thesis study file (tlm calibrate fits the programs to a thesis study's scenes)")
    more = f"; to measure its packet sizes, {granularity_study(cornell)}" if command == "granularity" else ""  # (h473)
    assert _error(lambda: call(cornell)) == (f"{cornell}: a run config (it has scene:), not {wanted}: run it with "
                                             f"tlm run {cornell}{more}")
    study = tmp_path / "s.yaml"  # (its own: read once, its own error after the read)
    study.write_text("base: {resolution: [8, 8]}\nnot_a_key: 1\n")
    assert "not_a_key: unknown key" in _error(lambda: call(study))
    assert reads.count(str(cornell)) == 1 and reads.count(str(study)) == 1
