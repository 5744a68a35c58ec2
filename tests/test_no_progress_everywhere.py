"""``--no-progress`` on every command that runs an experiment or writes a report (a script may
pass it to each; ``tlm plots`` passes it to its steps), an argument a command does not know
said by that command once (``tlm: error: tlm granularity: unrecognized arguments: ...``), and a
bare ``tlm`` listing the commands as ``tlm --help`` does (exit status 0)."""

from pathlib import Path

import pytest

import tlm.cli
from tlm.cli import build_parser, main

# each command with its positional arguments (none of them read: parsing only)
COMMANDS = (["run", "c.yaml"], ["sweep", "s.yaml"], ["reference", "c.yaml"], ["thesis", "t.yaml"],
            ["granularity", "g.yaml"], ["scaling", "runs/sw"], ["error-vs-cost", "e.yaml"], ["extreme", "x.yaml"],
            ["plots"], ["calibrate", "t.yaml"], ["report", "runs/r"])


@pytest.mark.parametrize("argv", COMMANDS, ids=lambda a: a[0])
def test_every_command_that_runs_or_reports_takes_no_progress(argv):
    assert build_parser().parse_args([*argv, "--no-progress"]).no_progress is True
    assert build_parser().parse_args(argv).no_progress is False


def test_plots_passes_no_progress_to_its_steps(tmp_path, monkeypatch):
    seen = []

    def granularity(args):
        seen.append(args.no_progress)
        return 0

    def plots(configs, runs, out, only, *, run_command, **_):
        assert run_command(["granularity", str(tmp_path / "g.yaml"), "--out", str(tmp_path / "g")]) == 0
        return Path(out) / "report.html"

    monkeypatch.setattr(tlm.cli, "_cmd_granularity", granularity)
    monkeypatch.setattr(tlm.cli.api, "plots", plots)
    plots_args = ["plots", "--configs", str(tmp_path), "--runs", str(tmp_path), "--out", str(tmp_path / "p")]
    assert main([*plots_args, "--no-progress"]) == 0
    assert main(plots_args) == 0
    assert seen == [True, False]


@pytest.mark.parametrize(("argv", "line"), [
    (["granularity", "g.yaml", "--bogus"], "tlm: error: tlm granularity: unrecognized arguments: --bogus"),
    (["params", "--no-progress"], "tlm: error: tlm params: unrecognized arguments: --no-progress"),
    (["scene", "list", "--bogus", "x"], "tlm: error: tlm scene list: unrecognized arguments: --bogus x"),
    (["--bogus", "params"], "tlm: error: unrecognized arguments: --bogus"),
])
def test_an_unknown_argument_is_said_by_its_command_once(argv, line, capsys):
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.err.strip() == line and captured.out == ""


def test_a_bare_tlm_lists_the_commands_and_exits_0(capsys):
    assert main([]) == 0
    captured = capsys.readouterr()
    assert captured.out.startswith("usage: tlm") and "granularity" in captured.out and "--version" in captured.out
    assert captured.err == ""
