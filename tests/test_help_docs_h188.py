"""Help texts and messages that agree with the code (a docs probe's findings, h185): each command's
``--set`` example is one it takes, ``tlm thesis`` says its cells' warnings once after its table,
``tlm params`` keeps its values in their column, the API's ``overrides=`` error names the shape it
wants, and ``tlm run SCENE.yaml``'s note goes to stderr."""

from __future__ import annotations

import io
import json
import re
import shlex
import sys
from pathlib import Path

import pytest
import yaml

import tlm
from tlm import api
from tlm.cli import build_parser, main

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _subcommands() -> dict:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "cmd")
    return dict(sub.choices)


def _set_example(command: str) -> str | None:
    """The ``--set`` example the command's help gives (``e.g. --set ...``), as the shell passes it."""
    action = next((a for a in _subcommands()[command]._actions if "--set" in a.option_strings), None)
    if action is None:
        return None
    found = re.search(r"e\.g\. --set ('[^']*'|[^\s),;]+)", action.help or "")
    return shlex.split(found[1])[0] if found else None


def _loader(command: str):
    from tlm.experiments.error_cost import load_experiment
    from tlm.experiments.extreme import load_cases
    from tlm.experiments.granularity import load_granularity
    from tlm.experiments.sweep_file import load_sweep
    from tlm.experiments.thesis import load_study

    return {"sweep": load_sweep, "thesis": load_study, "granularity": load_granularity, "extreme": load_cases,
            "error-vs-cost": load_experiment}.get(command)


STUDIES = ("sweep", "thesis", "granularity", "extreme", "error-vs-cost")


@pytest.mark.parametrize("command", STUDIES)
def test_each_commands_set_example_is_taken_by_its_built_in_experiments(command):
    """``tlm extreme --help`` gave ``--set 'resolution=[64, 64]'``, which extreme refuses (its cases set
    resolution): each study's example is one its --set check takes, with every built-in experiment
    of that command."""
    example = _set_example(command)
    assert example is not None and "=" in example, command
    names = [n for n in api.list_experiments() if api.experiment_command(n) == command]
    assert names, command
    for name in names:
        _loader(command)(api.experiment_path(name, command), (example,))  # (refused: an InputError)


def test_run_and_reference_set_examples_are_taken():
    for command in ("run", "reference"):
        example = _set_example(command)
        if example is not None:
            api.load_config("cornell_pmap", [example])


@pytest.mark.parametrize("command, words", [
    ("reference", "cached where it is better than a cached one"),  # (was: cached all the same)
    ("error-vs-cost", "default: 4096"),  # --truth-spp
    ("plots", "the sweep steps run with --no-progress always"),
])
def test_a_commands_help_says_what_it_does(command, words):
    text = " ".join(_subcommands()[command].format_help().split())
    assert words in text, text


def test_the_top_level_help_names_what_report_reads_and_plots_runs():
    text = " ".join(build_parser().format_help().split())
    assert "granularity, error-vs-cost or extreme folders" in text  # (extreme was left out)
    assert "cornell_pmap run, not the other single-scene run configs" in text  # (was: every committed experiment)


def _tiny_study(tmp_path: Path) -> Path:
    study = tmp_path / "th.yaml"
    study.write_text(yaml.safe_dump({
        "scenes": ["cornell"], "modes": ["rcast", "pmap"],
        "base": {"resolution": [12, 8], "photons": {"count": 2000}, "render": {"light_samples": 1},
                 "estimate": {"final_gather": 0}, "reference": {"auto": False},
                 "arch": {"frames": 1, "trace": False, "packet_size": 32}}}))
    return study


SHORT = "arch.frames=1 is too short for a steady-state throughput"


def test_tlm_thesis_says_each_warning_of_its_cells_once_after_its_table(tmp_path, capsys, monkeypatch):
    """Its cells' warnings were only in their results.json and the report: said once each, with the
    cells, on stderr after the table (here stdout and stderr into one stream, to see the order)."""
    both = io.StringIO()
    monkeypatch.setattr(sys, "stdout", both)
    monkeypatch.setattr(sys, "stderr", both)
    out = tmp_path / "th"
    assert main(["thesis", str(_tiny_study(tmp_path)), "--out", str(out), "--no-report", "--no-progress",
                 "--set", "photons.count=1500"]) == 0
    lines = both.getvalue().splitlines()
    said = [i for i, line in enumerate(lines) if SHORT in line]
    assert len(said) == 1, lines
    assert lines[said[0]].startswith(f"tlm: warning: all 2 cells: {SHORT}"), lines[said[0]]
    table = next(i for i, line in enumerate(lines) if line.startswith("wrote ") and "thesis_comparison.csv" in line)
    unread = [i for i, line in enumerate(lines) if "--set photons.count=1500 changes nothing in 1 of 2 cells" in line]
    assert table < said[0] and len(unread) == 1 and table < unread[0], lines  # (after its table, each once)
    for mode in ("rcast", "pmap"):  # (the cells keep their own lines)
        assert any(SHORT in w for w in json.loads((out / "cornell" / mode / "results.json").read_text())["warnings"])


def test_tlm_thesis_in_python_returns_its_warnings_and_passes_them_to_warn(tmp_path, capsys):
    """Returned, not printed (as tlm.run_sweep's), and given to warn= where one is."""
    done = tlm.thesis(_tiny_study(tmp_path), tmp_path / "th", overrides=["photons.count=1500"])
    assert [w for w in done["warnings"] if w.startswith(f"all 2 cells: {SHORT}")], done["warnings"]
    assert "warning" not in capsys.readouterr().err
    got = []
    again = tlm.thesis(_tiny_study(tmp_path), tmp_path / "th", warn=got.append)
    assert got == again["warnings"] and [w for w in got if SHORT in w] and "warning" not in capsys.readouterr().err


def test_cell_warning_lines_name_the_cells():
    from tlm.experiments.thesis import cell_warning_lines

    said = {"a": ["cornell pmap"], "b": ["thesis/ring pmap", "cornell pmap"], "c": ["x rcast", "x pmap"],
            "d": ["x rcast"]}
    assert cell_warning_lines(said, 2, {"d"}) == [
        "cell cornell pmap: a", "all 2 cells: b", "all 2 cells: c"]
    assert cell_warning_lines({"b": ["thesis/ring pmap", "cornell pmap"]}, 12) == [
        "2 of 12 cells (thesis/ring pmap, cornell pmap): b"]


def test_tlm_params_keeps_each_value_in_its_column(capsys):
    """A key longer than 24 characters (estimate.caustic_radius_photons) pushed its value out of its column."""
    assert main(["params"]) == 0
    lines = capsys.readouterr().out.splitlines()
    keys = [key for key, _, _ in api.params()]
    assert len(lines) == len(keys) and max(map(len, keys)) > 24
    wide = max(map(len, keys))  # (the key column as wide as the longest key, each value right-aligned after it)
    for line, key in zip(lines, keys, strict=True):
        assert line.startswith(f"{key:{wide}s} "), line
        assert line[wide + 1 + 10:wide + 1 + 12] == "  ", line


@pytest.mark.parametrize("given, wanted", [
    ("render.spp=2", "overrides: 'render.spp=2': overrides are a list of dotted.key=value strings, not one string: "
                     "put it in a list, ['render.spp=2']"),
    ({"render.spp": 2}, "overrides: a dict: overrides are a list of dotted.key=value strings, not a mapping"),
    (3, "overrides: 3: overrides are a list of dotted.key=value strings, not an int"),
])
def test_the_apis_overrides_error_names_the_shape_wanted_and_given(tmp_path, given, wanted):
    """It said 'as overrides takes them' (the --set of its text renamed for Python): circular."""
    with pytest.raises(tlm.InputError) as e:
        tlm.thesis("thesis", tmp_path / "x", overrides=given)
    assert str(e.value).startswith(wanted), str(e.value)
    assert "takes them" not in str(e.value)


def test_a_scene_files_note_is_said_once_its_config_loads(tmp_path, capsys):
    """Bad input with a scene file is its one line on stderr, and no note ahead of it on stdout (the note was said
    before the config loaded); a good run says the note on stdout, where a run's lines go (stderr holds a warning
    or an error alone: tests/test_stiff_inputs.py, tests/test_builder_param_keys.py)."""
    example = REPO / "scenes" / "examples" / "mesh_on_floor.yaml"
    assert main(["run", str(example), "--out", str(tmp_path / "bad"), "--set", "render.spp=-1",
                 "--no-report", "--no-progress"]) == 2
    got = capsys.readouterr()
    assert got.out == "" and got.err.count("\n") == 1 and "render.spp" in got.err, got
    assert not (tmp_path / "bad").exists()
    assert main(["run", str(example), "--out", str(tmp_path / "run"), "--set", "resolution=[16,12]", "--mode",
                 "rcast", "--outputs", "images", "--no-report", "--no-progress"]) == 0
    got = capsys.readouterr()
    assert got.out.startswith(f"{example} is a scene file: rendering it with the default settings"), got.out
    assert "is a scene file" not in got.err
