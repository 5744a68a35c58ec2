"""What the report's notes (tlm/report/tables.py, extreme.py, scaling.py) and the help of the
commands that take an experiment file (tlm/cli.py) tell a user to run works from any folder:
the built-in experiment's name, of the kind the command takes, not only ``configs/...``,
which exists in a checkout alone."""

from __future__ import annotations

import html
import re
from pathlib import Path

import pytest

from tlm import api
from tlm.cli import main
from tlm.report.collect import Inputs, Study
from tlm.report.extreme import extreme_section
from tlm.report.scaling import scaling_section
from tlm.report.tables import Source, table_html

# a command and the kind of experiment file it takes (tlm.api.experiment_command's)
TAKES = {"sweep": "sweep", "reference": "run", "error-vs-cost": "error-vs-cost", "granularity": "granularity",
         "calibrate": "thesis", "thesis": "thesis", "extreme": "extreme"}


def _commands(text: str) -> list[tuple[str, str]]:
    """The ``'tlm COMMAND NAME'`` commands quoted in ``text``."""
    return re.findall(r"'tlm ([a-z-]+) ([^\s']+)'", " ".join(html.unescape(text).split()))


def test_the_reports_notes_name_a_command_that_runs_from_any_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # (no configs/ here)
    empty = Inputs([], studies=[Study("granularity", Path("g"), [])])
    notes = {"extreme": extreme_section(empty, tmp_path).absent,
             "scaling": scaling_section(empty, tmp_path).absent,
             "tables": table_html(Source("runs/x", "cornell", not_comparable=["16×16 pixels (thesis 320×320)"]))}
    for where, text in notes.items():
        found = _commands(text)
        assert found, (where, text)
        for command, name in found:
            assert api.experiment_path(name, command) == api.configs_dir() / f"{name}.yaml", (where, text)
            assert api.experiment_command(name) == TAKES[command], (where, text)


@pytest.mark.parametrize("command", ["sweep", "reference", "error-vs-cost", "granularity", "calibrate"])
def test_the_help_of_a_command_names_a_built_in_experiment_it_takes(command, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main([command, "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    found = re.findall(r"or a built-in experiment's name: ([\w-]+)", text)
    assert len(found) == 1, text
    (name,) = found
    assert api.experiment_path(name, command) == api.configs_dir() / f"{name}.yaml"
    assert api.experiment_command(name) == TAKES[command]
