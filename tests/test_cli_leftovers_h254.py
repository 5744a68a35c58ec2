"""CLI output and bad input, the last session's leftovers (h254): ``render.threads`` past the CPUs
available to the process is warned of, once, in a run's warnings (run_warnings.threads_warning), and
not for null or a count no more than them; ``tlm: warning:`` and ``tlm: plots:`` lines escape their
control characters as ``tlm: error:`` lines do (an escape sequence in a name is shown, not obeyed;
accents and CJK as they are); a tab or a newline in a path an error names is shown as ``\\t``, ``\\n``,
not as a space (errors.path_shown, InputError's and EnvironmentFailure's ``source``); and a folder's
YAML that ``tlm report`` reads (config.resolved.yaml) whose aliases expand it past the limit a
config's loader keeps is refused in one line naming it, exit status 2, at once."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

import tlm
from tlm.cli import main
from tlm.errors import EnvironmentFailure, InputError, escaped_line, path_shown
from tlm.experiments import run_warnings
from tlm.kernels import threads
from tlm.report.checks import read_yaml

SMALL = {"mode": "rcast", "resolution": [8, 8], "render.spp": 1, "render.light_samples": 1,
         "arch.packet_size": 16, "arch.frames": 2}
SMALL_SETS = ["--set", "mode=rcast", "--set", "resolution=[8,8]", "--set", "render.spp=1", "--set",
              "render.light_samples=1", "--set", "arch.packet_size=16", "--set", "arch.frames=2"]
RED = "scene \x1b[31mred\x1b[0m café 日本"  # (an escape sequence, accents and CJK in a name)


def _threads_lines(lines: list[str]) -> list[str]:
    return [w for w in lines if w.startswith("render.threads")]


# 1. render.threads past the CPUs available

def test_threads_past_the_cpus_are_warned_of_naming_both():
    cfg = tlm.load_config("cornell", {"render.threads": 5}).settings
    (line,) = run_warnings.threads_warning(cfg, cpus=4)
    assert line.startswith("render.threads = 5 is more than the 4 CPUs available to this process"), line
    assert run_warnings.threads_warning(cfg, cpus=5) == []  # (as many as the CPUs: no line)
    assert run_warnings.threads_warning(cfg, cpus=8) == []
    assert "the 1 CPU available" in run_warnings.threads_warning(cfg, cpus=1)[0]
    null = tlm.load_config("cornell", {}).settings
    assert null.render.threads is None and run_warnings.threads_warning(null, cpus=1) == []  # (the default)


def test_a_run_says_threads_past_the_cpus_once(tmp_path, cache, monkeypatch, capsys):
    monkeypatch.setattr(threads, "available", lambda: 1)  # (the CPUs this process may run on, as a 1-CPU machine's)
    out = tmp_path / "r"
    assert main(["run", "cornell", "--out", str(out), "--no-report", "--outputs", "images", *SMALL_SETS,
                 "--set", "render.threads=2"]) == 0
    err = capsys.readouterr().err
    said = [ln for ln in err.splitlines() if "render.threads = 2" in ln]
    assert said == ["tlm: warning: render.threads = 2 is more than the 1 CPU available to this process (its affinity "
                    "mask, within a control group's CPU quota): the kernels' threads take turns on them, which is "
                    "slower, not faster (images, work and cycles are the same for every count); leave render.threads "
                    "null for the CPUs available"], err
    import json
    assert len(_threads_lines(json.loads((out / "results.json").read_text())["warnings"])) == 1
    for given in (None, 1):  # (the default, the CPUs available; and as many as them: no line)
        results = tlm.run(tlm.load_config("cornell", {**SMALL, "render.threads": given}), tmp_path / str(given),
                          outputs="images")
        assert _threads_lines(results["warnings"]) == [], (given, results["warnings"])


# 2. warning and plots lines escaped as error lines are

def test_a_sweeps_warning_line_shows_an_escape_sequence(monkeypatch, capsys):
    from types import SimpleNamespace

    from tlm import api

    plan = SimpleNamespace(lines=lambda: ["a plan"], record=dict, warnings=[f"{RED}: a warning naming it"])
    monkeypatch.setattr(api, "run_sweep", lambda *args, **kwargs: plan)
    assert main(["sweep", str(Path(__file__).parents[1] / "configs" / "sweep_fifo.yaml"), "--dry-run"]) == 0
    err = capsys.readouterr().err
    assert "\x1b" not in err, err
    assert "tlm: warning: scene \\x1b[31mred\\x1b[0m café 日本: a warning naming it" in err.splitlines(), err


def test_a_plots_line_shows_an_escape_sequence(tmp_path, monkeypatch, capsys):
    from tlm import api
    from tlm.errors import StepsFailed

    def failed(*args, **kwargs):
        raise StepsFailed(tmp_path / "pl\x1b[31mots" / "index.html", ["thesis"])

    monkeypatch.setattr(api, "plots", failed)
    assert main(["plots", "--configs", str(tmp_path), "--runs", str(tmp_path), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert "\x1b" not in err, err
    assert [ln for ln in err.splitlines() if ln.startswith("tlm: plots: ")] == [
        f"tlm: plots: step thesis reported failures (exit status 1, see above); the report was written all the "
        f"same: {tmp_path}/pl\\x1b[31mots/index.html"], err


# 5. a tab or a newline in a path: shown escaped, not as a space

def test_a_path_with_a_tab_or_a_newline_is_named_escaped():
    assert path_shown("a\tb\nc\rd\x1be é日") == "a\\tb\\nc\\rd\\x1be é日"
    assert escaped_line(RED) == "scene \\x1b[31mred\\x1b[0m café 日本"  # (a line: accents and CJK as they are)
    assert escaped_line("a\x00b\x07c\x9bd\te") == "a\\x00b\\x07c\\x9bd e"  # (its whitespace one space)
    assert str(InputError("file not found", source="a\tb.yaml")) == "a\\tb.yaml: file not found"
    assert str(EnvironmentFailure("cannot write", source="x\ny")) == "x\\ny: cannot write"
    e = InputError("bad", source="a\tb.yaml", key="scene")
    assert e.source == "a\tb.yaml" and str(e) == "a\\tb.yaml: scene: bad"  # (the source kept as given)


@pytest.mark.parametrize("name", ["a\tb.yaml", "a\nb.yaml"])
def test_an_error_line_shows_a_tab_or_newline_of_a_config_path(tmp_path, monkeypatch, capsys, name):
    monkeypatch.chdir(tmp_path)
    (tmp_path / name).write_text("scene: nosuch\n")
    assert main(["run", name, "--no-report"]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    shown = name.replace("\t", "\\t").replace("\n", "\\n")
    assert line.startswith(f"tlm: error: {shown}: scene: 'nosuch' is not a built-in scene"), line
    gone = name.replace(".yaml", "_gone.yaml")  # (a file not there: named so too)
    assert main(["run", gone, "--no-report"]) == 2
    said = capsys.readouterr().err.splitlines()
    assert said == [f"tlm: error: {shown.replace('.yaml', '_gone.yaml')}: file not found"], said


# 3. a folder's YAML with an alias bomb, refused at once

BOMB = "\n".join(["a0: &a0 [x, x, x, x, x, x, x, x, x, x]",
                  *(f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 9))]) + "\n"


@pytest.mark.parametrize("pad", [0, 3000])  # (short: libyaml's loader; a long line: PyYAML's own, C_DEPTH)
def test_read_yaml_refuses_an_alias_bomb(tmp_path, pad):
    path = tmp_path / "config.resolved.yaml"
    path.write_text(BOMB + (f"# {'x' * pad}\n" if pad else ""))
    t0 = time.perf_counter()
    with pytest.raises(InputError) as got:
        read_yaml(path)
    assert time.perf_counter() - t0 < 10
    assert str(got.value) == (f"{path}: its aliases (*name) expand it to more than 1,000,000 values: a damaged or "
                              "edited copy (tlm writes it whole, without aliases)")
    few = tmp_path / "few.yaml"  # (aliases within the limit: read as before)
    few.write_text("a: &a [1, 2]\nb: *a\n")
    assert read_yaml(few) == {"a": [1, 2], "b": [1, 2]}


def test_tlm_report_refuses_a_run_whose_config_is_an_alias_bomb(tmp_path, cache, capsys):
    run = tmp_path / "r"
    tlm.run(tlm.load_config("cornell", SMALL), run, outputs="images")
    (run / "config.resolved.yaml").write_text(BOMB)
    t0 = time.perf_counter()
    assert main(["report", str(run), "--out", str(tmp_path / "rep")]) == 2
    assert time.perf_counter() - t0 < 60  # (was: minutes, walking a billion values)
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"tlm: error: {run / 'config.resolved.yaml'}: its aliases (*name) expand it to more "
                           "than 1,000,000 values"), line
    assert not (tmp_path / "rep").exists()
