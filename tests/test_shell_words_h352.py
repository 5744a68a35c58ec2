"""Commands tlm prints for its user to run, and its stderr lines, for a path of bytes not UTF-8 (h352).

A folder ``$'dir_\\xff'`` (Python reads it as ``dir_\\udcff``) was named in a printed command by ``shlex.quote``:
``'dir_\\udcff/sw.yaml'`` on stderr (``'dir_\\xff/...'`` where escaped), which bash takes as those characters, not
the byte, so the command was no command to run. :func:`tlm.errors.shell_word` quotes such a word in bash's ANSI-C
form, ``$'dir_\\xff/sw.yaml'``; a word without one as ``shlex.quote`` does. A ``tlm:`` line on stderr (and any
other text written there) shows the byte as ``\\xff``, as stdout, a CSV cell and a figure do (it was ``\\udcff``).
"""

from __future__ import annotations

import argparse
import io
import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from tlm.cli import main
from tlm.errors import escaped_line, shell_word
from tlm.storage_json import escaped

REPO = Path(__file__).resolve().parents[1]
FF = os.fsdecode(b"dir_\xff")  # (dir_\udcff)
SCENE = ("geometry: [{shape: plane, params: {size: [4, 4]}}]\n"
         "materials: {g: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\ndefault_material: g\n"
         "lights: [{type: point, position: [0, 3, -2], power: [40, 40, 40]}]\n"
         "camera: {eye: [0, 1, -5], target: [0, 0, 0], vfov: 40}\nresolution: [8, 8]\n")
QUIET = ["--no-progress", "--no-report", "--outputs", "images"]
ARGS = "tlm() { printf '%s\\0' \"$@\"; }; "  # (a tlm of bash's that prints the words it was given, each ending NUL)


def _words(line: str, cwd: Path | None = None) -> list[bytes]:
    """The words bash gives ``tlm`` of the command ``line`` (``tlm ...``), as printed: no surrogate in it."""
    assert line == escaped(line), line  # (no surrogate: any stream shows it as it is)
    out = subprocess.run(["bash", "-c", ARGS + line], capture_output=True, check=True, cwd=cwd).stdout
    return out.split(b"\0")[:-1]


@pytest.mark.parametrize("word", [FF + "/sw.yaml", os.fsdecode(b"o'k\\\xe8 z"), "a\tb", "a  b", "new\nline",
                                  os.fsdecode(b"caf\xc3\xa9\xc2\xa0\xe9")])
def test_a_word_shlex_would_not_give_back_as_printed_is_bashs_ansi_c_form(word):
    quoted = shell_word(word)
    assert quoted.startswith("$'") and quoted.endswith("'"), quoted
    for shown in (quoted, escaped_line(quoted)):  # (as it is, and in a tlm: line on stderr)
        assert _words("tlm " + shown) == [os.fsencode(word)]


@pytest.mark.parametrize("word", ["runs/a", "my runs/a.yaml", "it's", "", "scene=[8, 8]", "café/a b"])
def test_another_word_is_quoted_as_shlex_quotes_it(word):
    assert shell_word(word) == shlex.quote(word)
    assert _words("tlm " + escaped_line(shell_word(word))) == [word.encode()]


def test_the_reference_and_report_commands_of_a_folder_not_utf8_give_bash_its_bytes():
    from tlm.cli_report import _report_command
    from tlm.experiments.run import reference_command

    command = reference_command(f"/data/{FF}/c.yaml", [f"scene={FF}/s.yaml", "seed=1"])
    assert _words(command) == [b"reference", b"/data/dir_\xff/c.yaml", b"--set", b"scene=dir_\xff/s.yaml",
                               b"--set", b"seed=1"]
    command = _report_command(argparse.Namespace(formats="png", dpi=None), Path(FF) / "out")
    assert _words(command) == [b"report", b"dir_\xff/out", b"--formats", b"png"]


def test_a_sweep_records_and_a_run_folders_commands_in_a_folder_not_utf8_run_as_printed(tmp_path, cache, capsys,
                                                                                           monkeypatch):
    monkeypatch.chdir(tmp_path)
    folder = Path(FF) / "runs" / "sw"
    folder.mkdir(parents=True)
    (folder / "sweep.yaml").write_text('{"tlm": "sweep/1", "sweep": null, "base_file": "exp.yaml", '
                                       '"base": {"scene": "s.yaml"}, "set": {}, "overrides": ["seed=7"], '
                                       '"grid": {"bsp.levels": [5, 7]}, "zip": null, "points": []}\n')
    assert main(["sweep", str(folder / "sweep.yaml")]) == 2
    err = capsys.readouterr().err
    assert "\\udc" not in err and "tlm: error: dir_\\xff/runs/sw/sweep.yaml:" in err, err  # (the byte as \xff)
    again, read = err.rstrip().split("to run the sweep again, or finish it (the points done are skipped): ")[1] \
        .split(" (SWEEP_FILE: its sweep file, which this record does not name); to read it: ")
    assert _words(again) == [b"sweep", b"SWEEP_FILE", b"--out", b"dir_\xff/runs/sw", b"--set", b"seed=7"]
    assert _words(read) == [b"report", b"dir_\xff/runs/sw"]
    resolved = Path(FF) / "config.resolved.yaml"
    resolved.write_text("scene: s.yaml\n")
    assert main(["run", str(resolved)]) == 2  # (a run folder's config with no --out: the one to give)
    err = capsys.readouterr().err
    assert _words("tlm run x --out " + err.split("give --out, say --out ")[1].split(" (")[0]) == \
        [b"run", b"x", b"--out", b"runs/dir_\xff-again"]


def test_a_run_folders_config_in_a_folder_not_utf8_given_to_tlm_sweep_says_a_tlm_run_that_runs(tmp_path, cache,
                                                                                                monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("s.yaml").write_text(SCENE)
    assert main(["run", "s.yaml", "--out", FF, *QUIET]) == 0
    env = {**os.environ, "PYTHONPATH": str(REPO), "TLM_PY": sys.executable}
    refused = subprocess.run([sys.executable, "-m", "tlm", "sweep", f"{FF}/config.resolved.yaml"],
                             capture_output=True, env=env)
    assert refused.returncode == 2 and b"\\udc" not in refused.stderr, refused.stderr
    command = refused.stderr.decode().rstrip().split("run it with ")[1]
    assert command == "tlm run $'dir_\\xff/config.resolved.yaml' --out $'runs/dir_\\xff-again'", command
    ran = subprocess.run(["bash", "-c", 'tlm() { "$TLM_PY" -m tlm "$@"; }; ' + command + " " + " ".join(QUIET)],
                         capture_output=True, env=env)
    assert ran.returncode == 0, ran.stderr
    assert (tmp_path / "runs" / os.fsdecode(b"dir_\xff-again") / "results.json").is_file()


def test_stderr_shows_a_byte_not_utf8_as_stdout_does(tmp_path, cache, monkeypatch):
    """A tlm: line, a line of cli_signals (an internal error's, naming its traceback file), and any other text
    written to the guarded stderr (a library's warning) show the byte as ``\\xff``, not Python's ``\\udcff``."""
    from tlm import cli_signals, cli_streams

    env = {**os.environ, "PYTHONPATH": str(REPO)}
    failed = subprocess.run([sys.executable, "-m", "tlm", "run", f"{FF}/nope.yaml"], capture_output=True,
                            env=env, cwd=tmp_path)
    assert failed.returncode == 2 and failed.stderr.startswith(b"tlm: error: dir_\\xff/nope.yaml: "), failed.stderr
    assert escaped_line(f"a {FF}\tb") == "a dir_\\xff b"
    raw = io.BytesIO()
    stream = io.TextIOWrapper(raw, encoding="utf-8", errors="backslashreplace", write_through=True)
    guarded = cli_streams._Guarded(stream, "stderr")
    assert guarded.write(f"UserWarning: {FF}\n") == len(f"UserWarning: {FF}\n")
    assert raw.getvalue() == b"UserWarning: dir_\\xff\n"
    said = io.StringIO()
    monkeypatch.setattr(sys, "stderr", said)
    cli_signals._line(f"tlm: internal error: ValueError: x (full traceback in /{FF}/t.txt)")
    assert said.getvalue() == "tlm: internal error: ValueError: x (full traceback in /dir_\\xff/t.txt)\n"
