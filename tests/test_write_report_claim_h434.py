"""``tlm.write_report`` from Python holds its folder's claim while it writes (h434).

``tlm report`` held its ``--out`` (``DIR/report``) for its writing (:func:`tlm.cli_report.report_claimed`, a
report's claim), and the API's studies theirs, but ``tlm.write_report(dirs, out=...)`` called from Python took
none: a second process writing a report into the same folder meanwhile was not refused, and the two ended
last-wins. Now it claims the folder as the command does (:func:`tlm.claims.claimed`, kind ``report``), after the
checks the report makes before it reads anything; from the command line, which holds the folder already, the
claim is that one, shared (one claim file, one lock, two holds in the process), never a second nor refused by
itself.

The other process is a child inside ``tlm.write_report`` (its ``build_report`` replaced by one that says it is
there and waits for its stdin to close): no timing, as in tests/test_folder_claims_h415.py."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import tlm
import tlm.report as report_mod
from tests.test_folder_claims_h415 import beside
from tlm import claims, storage
from tlm.cli import main

REPO = Path(__file__).resolve().parents[1]
WRITING = """
import sys
from pathlib import Path
import tlm, tlm.report

def build_report(dirs, out=None, *a, **k):
    print("writing", flush=True)
    sys.stdin.read()
    return Path(out) / "report.html"

tlm.report.build_report = build_report
print("wrote", tlm.write_report([sys.argv[1]], out=sys.argv[2]), flush=True)
"""


def writing_child(tmp_path: Path, folder: str, out: str) -> subprocess.Popen:
    """A child process inside ``tlm.write_report([folder], out=out)`` (run in ``tmp_path``), once it said so."""
    child = subprocess.Popen([sys.executable, "-c", WRITING, folder, out], cwd=tmp_path, stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env={**os.environ, "PYTHONPATH": str(REPO)})
    line = child.stdout.readline().strip()
    if line != "writing":
        raise AssertionError(f"the child did not begin its report: {line!r} {child.communicate('', timeout=60)}")
    return child


def test_a_report_from_python_into_a_folder_another_write_report_holds_is_refused_naming_it(tmp_path, monkeypatch):
    """The task's case: a child process writing a report with ``tlm.write_report`` into ``o``; the parent's
    ``tlm.write_report`` into ``o`` is refused at once, one line naming the child's process and its command
    (``out: another report is writing into 'o' (process PID on this machine, HOST (python -c ...))``), before
    anything is read or written (was: no claim in the child, the parent went ahead). The child's claim records
    it and a report; it ends well, leaving no claim."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "in").mkdir()
    built = []
    monkeypatch.setattr(report_mod, "build_report", lambda *a, **k: built.append(a))
    child = writing_child(tmp_path, "in", "o")
    try:
        record = [line.strip() for line in beside(tmp_path / "o").read_text().splitlines()]
        assert record == [f"{storage._host()}-{child.pid}", "report"], record
        with pytest.raises(tlm.InputError) as e:
            tlm.write_report(["in"], out="o")
        message = str(e.value)
        assert message.startswith(f"out: another report is writing into 'o' (process {child.pid} on this machine, "), \
            message
        assert message.endswith("wait for it to end, or give another folder"), message
        assert "\n" not in message and "python" in message  # (one line, naming the child's command)
        assert built == [] and not (tmp_path / "o").exists()
    finally:
        out, err = child.communicate("", timeout=120)  # (its stdin closed: it ends its report)
    assert child.returncode == 0, err
    assert out.strip() == f"wrote {Path('o') / 'report.html'}"
    assert not beside(tmp_path / "o").exists()


def test_a_default_report_folder_is_held_too(tmp_path, monkeypatch):
    """``tlm.write_report(["in"])`` (no ``out``: ``in/report``) holds ``in/report``: another process's report
    into it (``tlm report in``) is refused naming the report folder, exit 2."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "in").mkdir()
    child = writing_child(tmp_path, "in", str(Path("in") / "report"))
    try:
        got = subprocess.run([sys.executable, "-m", "tlm", "report", "in", "--no-progress"], cwd=tmp_path,
                             capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONPATH": str(REPO)})
        assert got.returncode == 2, got.stderr
        last = got.stderr.strip().splitlines()[-1]
        assert last.startswith("tlm: error: in: another report is writing into its report folder 'in/report' "
                               f"(process {child.pid} on this machine, "), last
    finally:
        child.communicate("", timeout=120)
    assert child.returncode == 0
    assert not beside(tmp_path / "in" / "report").exists()


def test_write_report_holds_one_report_claim_while_it_writes_and_none_after(tmp_path, monkeypatch):
    """In this process: while the report is built, its folder's claim is held once, recording a report; gone
    after, and after a report that fails."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "in").mkdir()
    out = tmp_path / "o"
    seen = []

    def build(dirs, where=None, *a, **k):
        taken = claims._CLAIMS[os.fsdecode(out.resolve())]
        seen.append((taken[1], taken[3], beside(out).read_text().splitlines()[1].strip()))
        if len(seen) == 2:
            raise tlm.InputError("no run, sweep or study in it", source="in")
        return out / "report.html"

    monkeypatch.setattr(report_mod, "build_report", build)
    assert tlm.write_report(["in"], out="o", lock=True) == out / "report.html"
    with pytest.raises(tlm.InputError, match="no run, sweep or study"):
        tlm.write_report("in", out="o")
    assert seen == [(beside(out).resolve(), 1, "report")] * 2
    assert not beside(out).exists() and not claims.holding()


def test_what_the_report_refuses_before_reading_is_refused_before_the_claim(tmp_path, monkeypatch):
    """A folder not there, a bad dpi, an ``out`` that is an input: the report's own error, as before, and
    nothing made for a claim (no claim file, no folder on the way)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "in").mkdir()
    with pytest.raises(tlm.InputError, match=r"not found|no such"):
        tlm.write_report(["nofolder"], out="a/o")
    with pytest.raises(tlm.InputError, match="dpi"):
        tlm.write_report(["in"], out="a/o", dpi=3)
    with pytest.raises(tlm.InputError, match="an input of the report"):
        tlm.write_report(["in"], out="in")
    assert sorted(os.listdir(tmp_path)) == ["in"] and os.listdir(tmp_path / "in") == []


@pytest.mark.parametrize("given", [["--out", "rep"], []])
def test_tlm_report_calling_the_api_holds_one_claim_shared(tmp_path, monkeypatch, capsys, given):
    """``tlm report in [--out rep]`` holds its folder (:func:`tlm.cli_report.report_claimed`) and calls
    ``tlm.api.write_report``, which holds it too: one claim (taken once), held twice in this process, never
    refused by itself; the command ends well, no claim left."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "in").mkdir()
    out = tmp_path / ("rep" if given else "in/report")
    real, taken, seen = claims._take_claim, [], []

    def take(where, *a, **k):
        taken.append(where)
        return real(where, *a, **k)

    def build(dirs, where=None, *a, **k):
        held = claims._CLAIMS[os.fsdecode(out.resolve())]
        seen.append((held[1], held[3]))
        return out / "report.html"

    monkeypatch.setattr(claims, "_take_claim", take)
    monkeypatch.setattr(report_mod, "build_report", build)
    assert main(["report", "in", *given, "--no-progress"]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {out / 'report.html'}"
    assert taken == [out.resolve()] and seen == [(beside(out).resolve(), 2)]
    assert not beside(out).exists() and not claims.holding()


RUN = ["run", str(REPO / "configs" / "cornell.yaml"), "--out", "r", "--mode", "rcast", "--no-progress",
       "--no-reference", "--set", "resolution=[16,16]", "--set", "render.spp=1", "--set", "render.light_samples=1",
       "--set", "arch.frames=1", "--set", "arch.trace=false"]


@pytest.mark.slow
def test_a_run_and_its_reports_write_whole_with_one_claim_each(tmp_path, monkeypatch, capsys, cache):
    """End to end: ``tlm run`` writes its report (``r/report``: the command's claim and the API's, one), then
    ``tlm report r --out rep`` and ``tlm.write_report("r", out="rep2")`` write theirs; no claim is left."""
    monkeypatch.chdir(tmp_path)
    assert main(RUN) == 0
    assert (tmp_path / "r" / "report" / "report.html").is_file()
    assert main(["report", "r", "--out", "rep", "--no-progress"]) == 0
    assert (tmp_path / "rep" / "report.html").is_file()
    assert tlm.write_report("r", out="rep2") == Path("rep2") / "report.html"
    assert (tmp_path / "rep2" / "report.html").is_file()
    left = [p for p in tmp_path.rglob("*") if p.name.endswith(".tlm-running")]
    assert left == [] and not claims.holding()
