"""``tlm plots`` holds its ``--out`` while it runs (h439).

Every writer claimed its folder (:func:`tlm.claims.claimed`): ``tlm run``, the studies, ``tlm report`` and
``tlm.write_report``; ``tlm plots`` / ``tlm.plots`` ran its steps into ``--runs`` (each claiming its own folder)
and then wrote the report into ``--out``, which nobody claimed: two ``tlm plots`` into one ``--out`` ended
last-wins, and a ``tlm report --out plots`` meanwhile was not refused. Now it holds ``--out`` (a report's claim)
from after the checks it makes before the first step to its report written; another process's ``tlm plots`` or
``tlm report`` into it is refused at once, naming it, exit 2, before any step runs; the claim goes as it ends.

The other process is a child inside ``tlm.plots`` (its one step waits for its stdin to close): no timing, as in
tests/test_write_report_claim_h434.py."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import tlm.cli
from tests.test_folder_claims_h415 import beside
from tests.test_plots_cli import EXTREME, _configs
from tlm import claims, storage
from tlm.cli import main
from tlm.report.regenerate import regenerate

REPO = Path(__file__).resolve().parents[1]
PLOTTING = """
import sys
from pathlib import Path
import tlm, tlm.report

def build_report(dirs, out=None, *a, **k):
    return Path(out) / "report.html"

def step(argv):
    Path(argv[argv.index("--out") + 1]).mkdir(parents=True, exist_ok=True)
    print("running", flush=True)
    sys.stdin.read()
    return 0

tlm.report.build_report = build_report
print("wrote", tlm.plots(sys.argv[1], sys.argv[2], sys.argv[3], "extreme", run_command=step), flush=True)
"""


def plotting_child(tmp_path: Path, out: str) -> subprocess.Popen:
    """A child process inside ``tlm.plots("configs", "runs", out, "extreme")`` (run in ``tmp_path``), in its step."""
    child = subprocess.Popen([sys.executable, "-c", PLOTTING, "configs", "runs", out], cwd=tmp_path,
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env={**os.environ, "PYTHONPATH": str(REPO)})
    line = child.stdout.readline().strip()
    if line != "running":
        raise AssertionError(f"the child did not begin its step: {line!r} {child.communicate('', timeout=60)}")
    return child


def test_a_plots_or_report_into_the_out_another_plots_holds_is_refused_naming_it(tmp_path, monkeypatch, capsys):
    """The task's case: a child in ``tlm.plots`` into ``o``; the parent's ``tlm plots --only extreme --out o`` is
    refused, exit 2, one line naming the child's process, before any step runs (no step called, no --runs made),
    and without saying the report left in ``o`` is an earlier one (another process writes it now); ``tlm report
    --out o`` too. The child's claim records a report; it ends well, leaving no claim."""
    monkeypatch.chdir(tmp_path)
    _configs(tmp_path, extreme=EXTREME)
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "report.html").write_text("earlier")
    (tmp_path / "in").mkdir()
    ran = []
    monkeypatch.setattr(tlm.cli, "_cmd_extreme", lambda args: ran.append(args) or 0)
    child = plotting_child(tmp_path, "o")
    try:
        record = [line.strip() for line in beside(tmp_path / "o").read_text().splitlines()]
        assert record == [f"{storage._host()}-{child.pid}", "report"], record
        capsys.readouterr()
        assert main(["plots", "--configs", "configs", "--runs", "runs2", "--out", "o", "--only", "extreme"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1, err
        assert err[0].startswith(f"tlm: error: --out: another report is writing into 'o' (process {child.pid} on "
                                 "this machine, "), err
        assert err[0].endswith("wait for it to end, or give another folder") and "python" in err[0], err
        assert ran == [] and not (tmp_path / "runs2").exists()
        assert main(["report", "in", "--out", "o", "--no-progress"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert err[-1].startswith(f"tlm: error: --out: another report is writing into 'o' (process {child.pid} "), err
        assert (tmp_path / "o" / "report.html").read_text() == "earlier"
    finally:
        out, err = child.communicate("", timeout=120)  # (its stdin closed: its step ends, then its report)
    assert child.returncode == 0, err
    assert out.strip() == f"wrote {Path('o') / 'report.html'}"
    assert not beside(tmp_path / "o").exists()


def test_plots_holds_one_report_claim_through_its_steps_and_report_and_none_after(tmp_path, monkeypatch):
    """In this process: ``out`` is held (a report's claim, once) during each step and the report; none is left
    after a run that ends well, one whose step stops on bad input, and one stopped by an interrupt."""
    out = tmp_path / "plots"
    seen = []

    def held(where: str) -> None:
        taken = claims._CLAIMS[os.fsdecode(out.resolve())]
        seen.append((where, taken[3], beside(out).read_text().splitlines()[1].strip()))

    def build(dirs, where, *a, **k):
        held("report")
        return where / "report.html"

    def run(argv):
        held(argv[0])
        (tmp_path / "runs" / "extreme").mkdir(parents=True, exist_ok=True)
        return 0

    monkeypatch.setattr("tlm.report.build_report", build)
    assert regenerate(REPO / "configs", tmp_path / "runs", out, ["extreme"], run_command=run,
                      say=lambda line: None) == out / "report.html"
    assert seen == [("extreme", 1, "report"), ("report", 1, "report")]
    assert not beside(out).exists() and not claims.holding()

    def stopped(error):
        def step(argv):
            held(argv[0])
            raise error
        return step

    for error, caught in ((tlm.cli.InputError("a bad case", key="cases"), tlm.cli.InputError),
                          (KeyboardInterrupt(), KeyboardInterrupt)):
        seen.clear()
        with pytest.raises(caught):
            regenerate(REPO / "configs", tmp_path / "runs", out, ["extreme"], run_command=stopped(error),
                       say=lambda line: None)
        assert seen == [("extreme", 1, "report")]
        assert not beside(out).exists() and not claims.holding()


def test_a_normal_plots_run_leaves_no_claim(tmp_path, capsys):
    """``tlm plots --only extreme`` (its one case differs from its expectation, nothing rendered) writes its
    report and leaves no claim beside ``--out`` nor held in the process."""
    configs = _configs(tmp_path, extreme=EXTREME)
    assert main(["plots", "--configs", str(configs), "--runs", str(tmp_path / "runs"), "--out",
                 str(tmp_path / "plots"), "--only", "extreme"]) == 1
    assert (tmp_path / "plots" / "report.html").is_file()
    left = [p for p in tmp_path.rglob("*") if p.name.endswith(".tlm-running")]
    assert left == [] and not claims.holding()


def test_an_out_that_is_a_steps_folder_is_refused_before_any_step(tmp_path):
    """``--out runs/thesis``: the thesis step would write it under this process's own claim (shared, not
    refused) and the report replace it; refused before the first step, nothing claimed."""
    called = []
    with pytest.raises(tlm.cli.InputError) as e:
        regenerate(REPO / "configs", tmp_path / "runs", tmp_path / "runs" / "thesis", ["extreme"],
                   run_command=called.append, say=lambda line: None)
    assert "is step thesis's folder under --runs" in str(e.value) and str(e.value).startswith("--out: ")
    assert called == [] and not (tmp_path / "runs").exists() and not claims.holding()
