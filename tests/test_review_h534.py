"""Review of h526 (fed0ba5): the ``--set`` strings of the ``tlm reference`` command results.json records
(``error.command``, :func:`tlm.config_read.rerun_sets`) name a relative scene file absolutely, so that the command runs
from any folder. A folder whose name holds a byte not UTF-8 (``d\\xff``), which ``--set`` reads (the path opens), was
read by plain YAML, which refuses it: the path was kept relative; and an absolute path that YAML reads as another value
(``/x/a: b #1/s.yaml``, a mapping) was kept relative too. Both now come back absolute, and read as that path."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import pytest

from tlm.config import apply_overrides, read_set_value


def _folder(parent, name: bytes):
    """The folder ``name`` (bytes) in ``parent``, made; skipped where the file system refuses such a name."""
    path = os.path.join(os.fsencode(parent), name)
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as e:
        pytest.skip(f"this file system refuses the name {name!r}: {e}")
    return os.fsdecode(path)


def _words(command: str) -> list[str]:
    """The words bash reads ``command`` as (its ``$'...'`` form too), as bytes decoded as Python names files."""
    done = subprocess.run(["bash", "-c", 'eval "set -- $1"; printf "%s\\0" "$@"', "bash", command],
                          capture_output=True, check=True)
    return [os.fsdecode(w) for w in done.stdout.split(b"\0")[:-1]]


@pytest.mark.skipif(sys.platform == "darwin" or shutil.which("bash") is None, reason="APFS refuses names not UTF-8")
@pytest.mark.parametrize("name", [b"d\xff", b"a: b #1"])
def test_a_relative_scene_file_of_any_name_comes_back_absolute_and_reads_as_itself(tmp_path, monkeypatch, name):
    from tlm import api
    from tlm.experiments.run import skipped_reference

    work, other = tmp_path / "wd", tmp_path / "other"
    work.mkdir()
    other.mkdir()
    folder = _folder(work, name)
    with open(os.path.join(folder, "s.yaml"), "w") as f:
        f.write("extends: cornell\n")
    (work / "c.yaml").write_text("scene: cornell\nmode: pmap\n")
    relative = os.fsdecode(os.path.join(name, b"s.yaml"))
    given = f"scene='{relative}'"  # (as a user quotes it for --set)
    monkeypatch.chdir(work)
    assert read_set_value(given.partition("=")[2]) == relative  # (what the run read)
    cfg = api.load_config("c.yaml", [given, "seed=3"])
    command = skipped_reference(cfg.settings, "c.yaml", [given, "seed=3"])["command"]  # (results.json error.command)
    words = _words(command)
    sets = [w for i, w in enumerate(words) if i and words[i - 1] == "--set"]
    assert words[:3] == ["tlm", "reference", str((work / "c.yaml").resolve())] and sets[1] == "seed=3", words
    key, _, text = sets[0].partition("=")
    assert key == "scene" and read_set_value(text) == os.path.join(folder, "s.yaml"), words  # (was: kept relative)
    monkeypatch.chdir(other)  # (the command run from another folder finds the same file)
    raw = apply_overrides({}, sets, cwd=other, warn=False)
    assert raw["scene"] == os.path.join(folder, "s.yaml") and os.path.isfile(raw["scene"])


def test_config_file_is_the_file_the_run_read_after_a_chdir(tmp_path, monkeypatch, cache):
    """``tlm.api.load_config('a.yaml')`` in one folder, ``os.chdir`` to another holding another ``a.yaml``, then
    ``tlm.api.run``: results.json's ``config_file`` named the other folder's file (of other settings), found from the
    working folder of the write; it names the file the run read (its folder: the config's ``base``)."""
    import json

    from tlm import api
    from tlm.config_read import config_file

    a, b = tmp_path / "A", tmp_path / "B"
    for folder, size in ((a, 8), (b, 4)):
        folder.mkdir()
        (folder / "a.yaml").write_text(f"scene: cornell\nmode: rcast\nresolution: [{size}, {size}]\n")
    monkeypatch.chdir(a)
    cfg = api.load_config("a.yaml")
    monkeypatch.chdir(b)
    assert config_file("a.yaml", cfg.base) == str((a / "a.yaml").resolve())
    assert config_file("a.yaml", tmp_path / "none") is None  # (not found where it was read: none, not b's)
    api.run(cfg, out=tmp_path / "o", progress=False)
    results = json.loads((tmp_path / "o" / "results.json").read_text())
    assert results["scene"]["resolution"] == [8, 8]
    assert results["config_file"] == str((a / "a.yaml").resolve()), results["config_file"]  # (was B/a.yaml)
