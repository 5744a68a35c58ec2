"""A signal while ``tlm run`` writes its report (``OUT/report``) said only ``tlm: terminated
(SIGTERM)``: not that the run was kept, whole, nor how to write its report. Now the line says
both (``tlm report OUT``, with the ``--formats`` and ``--dpi`` given), the exit status is still
128 + the signal, and no report is left half written (it is written beside ``OUT/report`` and
takes its place at the end: :func:`tlm.storage.atomic_folder`); a signal that comes once the
report took its place says that both are complete (:func:`tlm.cli_report._report_interrupted`). So do
``tlm sweep`` and the studies (``tlm thesis``, ``tlm granularity``, ...), each naming what it kept,
and a sweep's earlier report, which stays in its folder until the new one takes its place, is not
taken for the new one. The report a command writes at its end claims ``OUT/report`` as ``tlm
report`` claims its folder: a ``tlm report OUT`` meanwhile is refused at once, not left waiting.

Each run is a fresh Python whose wrapper signals it from inside the report's writing: no timing."""

from __future__ import annotations

import csv
import json
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

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


# the study files of the commands below: each as small as it can be (16x16 pixels, 2 frames)
SMALL = {"resolution": [16, 16], "render": {"spp": 1, "light_samples": 1}, "arch": {"frames": 2, "trace": False}}
STUDIES = {
    "sweep": {"base": str(REPO / "configs" / "cornell.yaml"),
              "set": {"mode": "rcast", "resolution": [16, 16], "render.spp": 1, "render.light_samples": 1,
                      "arch.frames": 2, "arch.trace": False},
              "grid": {"arch.packet_size": [16, 256]}},
    "thesis": {"base": SMALL, "scenes": ["cornell"], "modes": ["rcast"]},
    "granularity": {"base": {**SMALL, "scene": "cornell", "mode": "rcast"}, "packet_sizes": [1, 16]},
}
# what each says it kept (the line's words) and the files it names there
KEPT = {
    "sweep": ("the sweep", "its points, sweep.jsonl and sweep.csv"),
    "thesis": ("the study", "thesis_comparison.csv, thesis_summary.json and a run folder per scene and mode"),
    "granularity": ("the study", "granularity.csv and granularity.jsonl"),
}


def study(tmp_path: Path, command: str, extra: list[str] = ()) -> list[str]:
    """The argv of ``command`` over its small study file (written into ``tmp_path``), into ``out dir``."""
    file = tmp_path / f"{command}.yaml"
    file.write_text(yaml.safe_dump(STUDIES[command]))
    jobs = ["--jobs", "1"] if command == "sweep" else []
    return [command, str(file), "--out", "out dir", "--no-progress", *jobs, *extra]


def rows(path: Path) -> list[dict]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


def study_kept(command: str, out: Path) -> None:
    """What the command said it kept is there, whole: each file its line names, and its rows."""
    for name in re.findall(r"[\w.]+\.(?:csv|jsonl|json)", KEPT[command][1]):
        assert (out / name).is_file(), name
    if command == "sweep":
        table = rows(out / "sweep.csv")
        assert [r["status"] for r in table] == ["ok", "ok"]
        assert len((out / "sweep.jsonl").read_text().splitlines()) == 2
        for r in table:  # its points: each one's results
            assert json.loads((out / "points" / r["hash"] / "results.json").read_text())["mode"] == "rcast"
    elif command == "thesis":
        assert [(r["scene"], r["mode"]) for r in rows(out / "thesis_comparison.csv")][:1] == [("cornell", "rcast")]
        assert json.loads((out / "cornell" / "rcast" / "results.json").read_text())["mode"] == "rcast"
        assert json.loads((out / "thesis_summary.json").read_text())
    else:
        assert [int(r["packet_size"]) for r in rows(out / "granularity.csv")] == [1, 16]
        assert len((out / "granularity.jsonl").read_text().splitlines()) == 2


@pytest.mark.parametrize(("command", "sig", "extra"), [("sweep", "SIGTERM", []),
                                                       ("thesis", "SIGINT", ["--formats", "svg"]),
                                                       ("granularity", "SIGTERM", ["--dpi", "60"])])
def test_a_signal_while_a_sweep_or_study_writes_its_report_says_what_it_kept(tmp_path, monkeypatch, command, sig,
                                                                               extra):
    """Each names what it kept, whole, in its own words, and the command that writes the report."""
    proc = run(tmp_path, study(tmp_path, command, extra), IN_REPORT.format(sig=sig))
    out = tmp_path / "out dir"
    assert proc.returncode == 128 + getattr(signal, sig), proc.stderr
    what, files = KEPT[command]
    typed = "tlm report 'out dir'" + "".join(f" {f}" for f in extra)
    assert proc.stderr.splitlines()[-1] == (
        f"{LINE[sig]} while writing the report: {what} in out dir is kept, whole ({files}); no report was written "
        f"(none is left half-written): write it with: {typed}")
    assert not [p.name for p in out.iterdir() if "report" in p.name]  # (no report, nor a temporary folder of it)
    study_kept(command, out)
    if command == "granularity":  # the command it names writes the report
        monkeypatch.chdir(tmp_path)
        assert main(shlex.split(typed)[1:]) == 0
        assert (out / "report" / "report.html").is_file()


def test_a_sweeps_earlier_report_is_not_taken_for_the_one_a_signal_stopped(tmp_path):
    """A sweep run again into its folder keeps the earlier report there until the new one takes
    its place: a signal before that says the earlier one is left as it was (not that the new one is
    complete); one after it, that the new one is."""
    argv = study(tmp_path, "sweep")
    out = tmp_path / "out dir"
    first = run(tmp_path, argv, "")
    assert first.returncode == 0, first.stderr
    page = out / "report" / "report.html"
    earlier = page.stat().st_ino
    proc = run(tmp_path, argv, IN_REPORT.format(sig="SIGTERM"))
    assert proc.returncode == 143, proc.stderr
    assert proc.stderr.splitlines()[-1] == (
        "tlm: terminated (SIGTERM) while writing the report: the sweep in out dir is kept, whole (its points, "
        "sweep.jsonl and sweep.csv); no report was written (none is left half-written; the earlier report in "
        "out dir/report is left as it was): write it with: tlm report 'out dir'")
    assert page.stat().st_ino == earlier
    assert sorted(p.name for p in out.iterdir() if "report" in p.name) == ["report"]
    proc = run(tmp_path, argv, AFTER_REPORT.format(sig="SIGTERM"))
    assert proc.returncode == 143, proc.stderr
    assert proc.stderr.splitlines()[-1] == ("tlm: terminated (SIGTERM) as its report was written: the sweep in out "
                                            "dir and its report (out dir/report/report.html) are complete")
    assert page.stat().st_ino != earlier
    study_kept("sweep", out)


# the report paused once its sections are written, until the test lets it go on
PAUSED = """
import time
real = report.sections
def sections(inputs, out):
    got = real(inputs, out)
    open({ready!r}, "w").close()
    while not os.path.exists({go!r}):
        time.sleep(0.02)
    return got
report.sections = sections
"""


def refusal(folder: str) -> str:
    return rf"tlm: error: --out: another report is writing into '{re.escape(folder)}' \(process \d+ on this machine, "


def test_a_tlm_report_while_a_run_writes_its_own_report_is_refused_at_once(tmp_path):
    """The run's report claims ``OUT/report`` as ``tlm report`` claims its folder: a ``tlm report
    OUT`` meanwhile is refused at once, exit 2, naming the run's process (it used to wait for the
    run's lock and then write the same report again); the run's report is then written, whole."""
    ready, go = tmp_path / "ready", tmp_path / "go"
    env = {**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(tmp_path / "cache")}
    code = WRAPPER.format(argv=RUN, patch=PAUSED.format(ready=str(ready), go=str(go)))
    child = subprocess.Popen([sys.executable, "-c", code], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, preexec_fn=default_sigint)
    try:
        deadline = time.monotonic() + 300
        while not ready.exists():  # (the run's report, paused in its writing)
            assert child.poll() is None and time.monotonic() < deadline, child.communicate()
            time.sleep(0.05)
        try:
            second = subprocess.run([sys.executable, "-m", "tlm", "report", "out dir"], cwd=tmp_path, env=env,
                                    capture_output=True, text=True, timeout=120)
        except subprocess.TimeoutExpired:
            pytest.fail("tlm report waited for the run's report to end")
        assert second.returncode == 2, second.stderr
        assert re.match(r"tlm: error: out dir: another report is writing into its report folder 'out dir/report' "
                        r"\(process \d+ on this machine, .*\): wait for it to end, or give another folder with --out$",
                        second.stderr.strip()), second.stderr  # (DIR, as given: no --out was)
        assert f"process {child.pid} " in second.stderr
    finally:
        go.touch()
        stdout, stderr = child.communicate(timeout=300)
    assert child.returncode == 0, stderr
    assert (tmp_path / "out dir" / "report" / "report.html").is_file()
    assert "report: out dir/report/report.html" in stdout


def test_a_runs_report_waits_for_one_another_process_is_writing_and_says_so(tmp_path, monkeypatch):
    """The other way round: a run that ends while another process writes a report into its
    ``OUT/report`` (a ``tlm report`` begun before; two sweeps of the same points into one folder
    both end so) waits for it, saying so, and then writes its own, of the run it just wrote. The
    other process here holds the claim alone, as a report does in its last instant."""
    monkeypatch.chdir(tmp_path)
    assert main([*RUN, "--no-report"]) == 0  # (an earlier run, whose report the other process writes)
    env = {**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(tmp_path / "cache")}
    hold = ("import sys\nfrom pathlib import Path\nfrom tlm import claims\n"
            "with claims.claimed(Path('out dir') / 'report', 'report'):\n    print('held', flush=True)\n"
            "    sys.stdin.read()\n")
    holder = subprocess.Popen([sys.executable, "-c", hold], cwd=tmp_path, env=env, stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    child = None
    try:
        assert holder.stdout.readline() == "held\n"
        child = subprocess.Popen([sys.executable, "-c", WRAPPER.format(argv=RUN, patch="")], cwd=tmp_path, env=env,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        said = []
        while not (said and said[-1].startswith("tlm: note: another report")):
            line = child.stderr.readline()
            assert line, f"the run ended without waiting: {said}"  # (its report written beside the claim)
            said.append(line)
        assert re.match(rf"tlm: note: another report is writing into 'out dir/report' \(process {holder.pid} on "
                        r"this machine, .*\): the report of the run in out dir waits for it to end$", said[-1]), said
        assert child.poll() is None and not (tmp_path / "out dir" / "report").exists()
    finally:
        holder.communicate("", timeout=60)  # (the other report ends)
        stdout, stderr = child.communicate(timeout=300) if child is not None else ("", "")
    assert child.returncode == 0, stderr
    assert "report: out dir/report/report.html" in stdout
    assert (tmp_path / "out dir" / "report" / "report.html").is_file()
    run_kept(tmp_path / "out dir")
