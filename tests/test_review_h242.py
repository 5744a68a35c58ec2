"""Review of the bad-input commit and 6e506f9 (h242): what a line of the machine's error names
(a path the user gave, with an escape sequence in it) is shown escaped, as ``one_line``'s are,
not obeyed by the terminal; a missing file that the block writing a folder or a file reads is
its own error, not "the folder takes no new files" (storage.write_problem's ENOENT).
"""

from __future__ import annotations

import os
import re

import pytest

from tlm import storage
from tlm.cli import main
from tlm.cli_signals import escaped, one_line


def _one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tlm: error: "), err
    return lines[0]


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc (a folder that takes no new files)")
def test_a_machine_error_line_shows_the_control_characters_of_a_path_escaped(cache, capsys):
    # (the write fails as the machine's error, exit status 1: its line named the path raw, ESC and BEL and all)
    assert main(["config", "export", "cornell", "/proc/café 日本\x1b[31mred\x07.yaml"]) == 1
    line = _one_error_line(capsys.readouterr().err)
    assert "/proc/café 日本\\x1b[31mred\\x07.yaml: cannot write" in line, line  # (accents, CJK: as they are)
    assert "\x1b" not in line and "\x07" not in line, line
    assert escaped("café 日本語\x1b[2J\tx\x9b") == "café 日本語\\x1b[2J x\\x9b"
    assert one_line(ValueError("")) == "ValueError" and one_line(ValueError("naïve\x00")) == "naïve\\x00"


def test_a_missing_input_read_while_writing_is_not_said_to_be_the_folders_fault(tmp_path, monkeypatch):
    # (the old code: "cannot write: TMP takes no new files" for any ENOENT met inside the block)
    with pytest.raises(FileNotFoundError), storage.atomic_folder(tmp_path / "out", "results.json"):
        (tmp_path / "no" / "such" / "input.txt").read_text()
    with pytest.raises(FileNotFoundError), storage.write_atomic(tmp_path / "x.yaml") as fh:
        fh.write((tmp_path / "input.txt").read_text())  # (a file of the same folder, missing)
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # (nothing left half written)
    real = open  # (a folder that takes no new file, /proc's ENOENT naming the file made: still said so)

    def no_file(path, *a, **k):  # (as /proc answers a new file: ENOENT naming it)
        if str(path).startswith(str(tmp_path)):
            raise FileNotFoundError(2, "No such file or directory", str(path))
        return real(path, *a, **k)

    monkeypatch.setattr(storage, "open", no_file, raising=False)
    with pytest.raises(storage.EnvironmentFailure, match=re.escape(f"cannot write: {tmp_path} takes no new files")):
        storage.write_files([(tmp_path / "a.yaml", "a: 1\n"), (tmp_path / "b.yaml", "b: 1\n")])


def test_numba_threads_below_one_stops_no_command_that_never_imports_numba(tmp_path, monkeypatch, capsys):
    """NUMBA_NUM_THREADS=0 is refused where a command may render; tlm cache never imports numba: it runs."""
    from tlm.cli import main

    monkeypatch.setenv("NUMBA_NUM_THREADS", "0")
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    assert main(["cache", "info"]) == 0
    assert main(["run", "cornell", "--out", str(tmp_path / "r")]) == 2
    assert "NUMBA_NUM_THREADS" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_a_sweep_files_null_key_is_named_as_yaml_writes_it(tmp_path, capsys):
    """A `set:` key written `null` (YAML's None) is named `null`, as the config's keys are, not Python's None."""
    from tlm.cli import main

    sweep = tmp_path / "sw.yaml"
    sweep.write_text("base: cornell\nset: {null: 3}\ngrid: {seed: [1, 2]}\n")
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "o"), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert "null is not a dotted config key" in err and "None" not in err, err
