"""Review of 3bcbe83, 31bc60b and b34d6ae (paths of bytes not UTF-8, h355).

``tlm config export NAME FILE`` writes the built-in experiment's comment commands (``tlm sweep configs/NAME.yaml
--out ...``) with ``FILE`` in place of its checkout path. 3bcbe83 wrote a folder of bytes not UTF-8 there as
``dir_\\xff`` unquoted, which bash reads as ``dir_xff``: no command to run as shown (and a path with a space was two
words; one with a newline ended the comment, its rest a line of YAML). It is quoted as every command tlm prints is
(:func:`tlm.errors.shell_word`).
"""

from __future__ import annotations

import os
import subprocess

import pytest
import yaml

from tlm.builtin import configs_dir
from tlm.cli import main

ARGS = "tlm() { printf '%s\\0' \"$@\"; }; "  # (a tlm of bash's that prints the words it was given, each ending NUL)


def _comment_command(text: str) -> str:
    """The ``tlm sweep ... --out runs/sweep_fifo`` command of sweep_fifo's comment, as the copy shows it."""
    line = next(line for line in text.splitlines() if line.startswith("#   tlm sweep "))
    return line[len("#   "):].split("   ->")[0].rstrip()


@pytest.mark.parametrize("folder", [b"dir_\xff", b"my runs", b"new\nline"])
def test_an_exported_experiments_comment_command_gives_bash_the_copys_path(tmp_path, folder):
    where = tmp_path / os.fsdecode(folder)
    where.mkdir()
    copy = where / "x.yaml"
    assert main(["config", "export", "sweep_fifo", str(copy)]) == 0
    text = copy.read_text(encoding="utf-8")
    source = (configs_dir() / "sweep_fifo.yaml").read_text(encoding="utf-8")
    assert yaml.safe_load(text) == yaml.safe_load(source)  # (a newline in the name: still one comment line)
    assert len(text.splitlines()) == len(source.splitlines())
    words = subprocess.run(["bash", "-c", ARGS + _comment_command(text)], capture_output=True,
                           check=True).stdout.split(b"\0")[:-1]
    assert words == [b"sweep", os.fsencode(copy), b"--out", b"runs/sweep_fifo"], words

