"""The built-in experiments as an installed copy has them (the tests of installed-copy words'
common set-up), and the one line a command says on stderr."""

from __future__ import annotations

import shutil
from pathlib import Path

import tlm.builtin

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def installed_configs(tmp_path: Path, monkeypatch) -> Path:
    """A copy of configs/ in a package folder of its own (``tlm/_configs``, what
    :func:`tlm.builtin.configs_dir` names), and a working folder without configs/ or scenes/."""
    folder = tmp_path / "site-packages" / "tlm" / "_configs"
    shutil.copytree(CONFIGS, folder)
    monkeypatch.setattr(tlm.builtin, "configs_dir", lambda: folder)
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    return folder


def one_error(capsys) -> str:
    """The one non-blank line on stderr (fails where there are more or none)."""
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1, err
    return err[0]
