"""A signal while ``tlm run`` writes its report (``OUT/report``) said only ``tlm: terminated
(SIGTERM)``: not that the run was kept, whole, nor how to write its report. Now the line says
both (``tlm report OUT``, with the ``--formats`` and ``--dpi`` given), the exit status is still
128 + the signal, and no report is left half written (it is written beside ``OUT/report`` and
takes its place at the end: :func:`tlm.storage.atomic_folder`); a signal that comes once the
report took its place says that both are complete (:func:`tlm.cli._report_interrupted`).

Each run is a fresh Python whose wrapper signals it from inside the report's writing: no timing."""

from __future__ import annotations

import json
import os
import shlex
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tlm.cli import main

REPO = Path(__file__).resolve().parents[1]
LINE = {"SIGINT": "tlm: interrupted", "SIGTERM": "tlm: terminated (SIGTERM)"}
RUN = ["run", str(REPO / "configs" / "cornell.yaml"), "--out", "out dir", "--mode", "rcast", "--no-progress",
       "--no-reference", "--set", "resolution=[16,16]", "--set", "render.spp=1", "--set", "render.light_samples=1",
       "--set", "arch.frames=2", "--set", "arch.trace=false"]

WRAPPER = """
import os, signal, sys
from tlm import api, cli
import tlm.report as report
{patch}
sys.argv[1:] = {argv!r}
sys.exit(cli.main())
"""
# the signal in the middle of the report: its sections written into its temporary folder
IN_REPORT = """
real = report.sections
def sections(inputs, out):
    got = real(inputs, out)
    os.kill(os.getpid(), signal.{sig})
    return got
report.sections = sections
"""
# the signal once the report took its place, before the command printed it
AFTER_REPORT = """
real = api.write_report
def write_report(*args, **kwargs):
    page = real(*args, **kwargs)
    os.kill(os.getpid(), signal.{sig})
    return page
api.write_report = write_report
"""


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py: the in-process report's)
    return cache


def default_sigint() -> None:
    """(In the child, before Python starts: SIGINT as a terminal's shell leaves it. A test
    suite run from a background shell inherits it ignored, and Python then keeps ignoring it.)"""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def run(tmp_path, argv: list[str], patch: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(tmp_path / "cache")}
    code = WRAPPER.format(argv=argv, patch=patch)
    return subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                          preexec_fn=default_sigint, timeout=300)


def run_kept(out: Path) -> None:
    """The run's own files are whole: its results and its images."""
    from PIL import Image

    results = json.loads((out / "results.json").read_text())
    assert results["mode"] == "rcast" and results["plan"]["run"] == ["rcast"]
    images = sorted((out / "images").glob("*.png"))
    assert [p.name for p in images] == ["composite.png", "rcast.png"]
    for p in images:
        with Image.open(p) as im:
            im.load()
            assert im.size == (16, 16)


@pytest.mark.parametrize(("sig", "extra"), [("SIGTERM", []), ("SIGINT", ["--dpi", "60"])])
def test_a_signal_while_the_report_is_written_keeps_the_run_and_says_how_to_write_it(tmp_path, monkeypatch, sig,
                                                                                     extra):
    proc = run(tmp_path, [*RUN, *extra], IN_REPORT.format(sig=sig))
    out = tmp_path / "out dir"
    assert proc.returncode == 128 + getattr(signal, sig), proc.stderr
    last = proc.stderr.splitlines()[-1]
    command = "tlm report 'out dir'" + (" --dpi 60" if extra else "")  # (the folder as given, quoted)
    assert last == (f"{LINE[sig]} while writing the report: the run in out dir is kept, whole (results.json and its "
                    f"files); no report was written (none is left half-written): write it with: {command}")
    assert not (out / "report").exists()
    assert not [p.name for p in out.iterdir() if "report" in p.name]  # (no temporary folder of it either)
    run_kept(out)
    if sig == "SIGTERM":  # the command it names writes the report
        monkeypatch.chdir(tmp_path)
        assert main(shlex.split(command)[1:]) == 0
        assert (out / "report" / "report.html").is_file()


def test_a_signal_once_the_report_took_its_place_says_both_are_complete(tmp_path):
    proc = run(tmp_path, RUN, AFTER_REPORT.format(sig="SIGTERM"))
    out = tmp_path / "out dir"
    assert proc.returncode == 143, proc.stderr
    assert proc.stderr.splitlines()[-1] == ("tlm: terminated (SIGTERM) as its report was written: the run in out dir "
                                            "and its report (out dir/report/report.html) are complete")
    assert (out / "report" / "report.html").is_file()
    run_kept(out)
