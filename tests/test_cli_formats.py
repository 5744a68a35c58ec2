"""``--formats`` and ``--dpi`` on every command that writes a report (``tlm run``, ``tlm sweep``,
``tlm plots``, the studies), not only on ``tlm report``: the same values, the same one-line
errors (exit 2), and a bad value fails before any work."""

from __future__ import annotations

import pytest

from tlm import api
from tlm.cli import build_parser, main

# each command that writes a report, with the arguments it needs besides the options
COMMANDS = {
    "run": ["run", "cornell"],
    "sweep": ["sweep", "sweep_fifo"],
    "plots": ["plots"],
    "thesis": ["thesis", "thesis"],
    "scaling": ["scaling", "runs/scaling_cornell"],
    "granularity": ["granularity", "tlm_granularity"],
    "error-vs-cost": ["error-vs-cost", "error_vs_cost"],
    "extreme": ["extreme", "extreme"],
    "report": ["report", "runs/x"],
}
# what each command would call to begin its work: none may be reached with a bad value
WORK = ("run", "run_sweep", "plots", "thesis", "scaling", "granularity", "error_vs_cost", "extreme",
        "write_report")


@pytest.mark.parametrize("command", sorted(set(COMMANDS) - {"report"}))  # (tlm report: the model)
def test_every_command_that_writes_a_report_takes_formats_and_dpi(command):
    args = build_parser().parse_args([*COMMANDS[command], "--formats", "pdf,svg", "--dpi", "220"])
    assert (args.formats, args.dpi) == ("pdf,svg", "220")
    args = build_parser().parse_args(COMMANDS[command])
    assert (args.formats, args.dpi) == (None, None)  # (the report's own defaults: png at 110 dpi)


@pytest.fixture
def no_work(monkeypatch):
    """Every command's first call into the API fails the test: a bad value must stop before it."""
    def work(*args, **kwargs):
        raise AssertionError("the command began its work")

    for name in WORK:
        monkeypatch.setattr(api, name, work)


@pytest.mark.parametrize(("option", "said"), [
    (["--formats", "eps"], "--formats: unknown format 'eps': the formats are png, pdf, svg"),
    (["--formats", "pdf,,svg"], "--formats: an empty format in 'pdf,,svg': the formats are png, pdf, svg, "
                                "separated by commas"),
    (["--dpi", "20"], "--dpi: 20 dots per inch is out of range: from 50 to 1200"),
    (["--dpi", "1.5"], "--dpi: '1.5' is not a whole number of dots per inch (from 50 to 1200)"),
], ids=["format", "empty-format", "dpi-range", "dpi-fraction"])
@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_bad_value_is_one_line_exit_2_before_any_work(command, option, said, tmp_path, monkeypatch, capsys,
                                                         no_work):
    monkeypatch.chdir(tmp_path)
    assert main([*COMMANDS[command], *option]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == f"tlm: error: {said}", err  # (tlm report's line, word for word)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", sorted(set(COMMANDS) - {"plots", "report"}))
def test_formats_with_no_report_is_refused_not_dropped(command, tmp_path, monkeypatch, capsys, no_work):
    monkeypatch.chdir(tmp_path)
    assert main([*COMMANDS[command], "--no-report", "--formats", "svg"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == ("tlm: error: --formats: sets the report's figure files, and --no-report writes "
                       "no report: give one or the other"), err
    assert main([*COMMANDS[command], "--no-report", "--dpi", "200"]) == 2
    assert "tlm: error: --dpi: sets the report's figure files" in capsys.readouterr().err
    assert main([*COMMANDS[command], "--no-report", "--formats", "svg", "--dpi", "200"]) == 2
    assert "tlm: error: --formats and --dpi: set the report's figure files" in capsys.readouterr().err


def test_plots_writes_its_report_as_asked(tmp_path, monkeypatch):
    """``tlm plots --formats --dpi``: the report's figures are written so (the steps write none)."""
    import tlm.report.regenerate as regenerate_mod
    from tlm.report.common import current_output

    seen = []

    def regenerate(configs, runs, out, only, *, run_command, say):
        seen.append(current_output())
        return out / "report.html"

    monkeypatch.setattr(regenerate_mod, "regenerate", regenerate)
    assert main(["plots", "--configs", str(tmp_path), "--out", str(tmp_path / "p"), "--formats", "svg",
                 "--dpi", "75"]) == 0
    assert [(o.formats, o.dpi) for o in seen] == [(("png", "svg"), 75)]
    assert current_output().formats == ("png",)  # (set for the call alone)


@pytest.mark.slow
def test_tlm_run_writes_its_reports_figures_as_svg_too(tmp_path, cache, capsys):
    out = tmp_path / "r"
    assert main(["run", "cornell", "--set", "resolution=[8,8]", "--formats", "svg", "--dpi", "60", "--out",
                 str(out), "--no-progress"]) == 0
    report = out / "report"
    pngs = sorted(p.stem for p in report.glob("*.png"))
    assert pngs and sorted(p.stem for p in report.glob("*.svg")) == pngs  # (each figure beside its PNG)
    assert not list(report.glob("*.pdf"))
    assert "Each figure links to its PNG and SVG files." in (report / "report.html").read_text()
