"""Five leftovers (h310).

1. Two internal errors of one process in one second got one traceback file name: the second's went to the
   temporary folder, a third's nowhere (``the traceback could not be saved``). Now the next free name
   (``...-2.txt``) in the cache, the first kept, and the line names the file written.
2. ``tlm run <(cat cornell.yaml) --no-reference`` recorded ``tlm reference /dev/fd/63 ...`` in results.json (and so
   the report), which no later command can read; now the run folder's ``config.resolved.yaml``, said so.
3. A mesh (OBJ, PLY, STL, glTF bytes) given through a pipe where a config goes was parsed as YAML (``must be a
   mapping``, ``not a UTF-8 text file``); now the line a mesh file given by its name gets.
4. A file too large to be read whole named where a mesh goes for an ``arch.programs`` table too; now only where
   a config or a scene file goes (``read_yaml``).
5. ``sweep.csv`` (every text file ``tlm.storage`` writes) was in the locale's encoding: under an ASCII locale a
   non-ASCII host name made the write fail. Now UTF-8.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from tlm import cli_failed, cli_signals, config
from tlm.cli import main
from tlm.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
needs_dev_fd = pytest.mark.skipif(not os.path.isdir("/dev/fd"), reason="no /dev/fd here")


# ------------------------------------------------------------------ 1: tracebacks of one second


def test_errors_in_one_second_get_a_traceback_file_each_in_the_cache(cache, monkeypatch, capsys):
    monkeypatch.setattr(time, "strftime", lambda fmt, *a: "20260202-000000")  # (every error in one second)
    monkeypatch.setattr(cli_signals, "_NAMED", ["", 0])  # (none of this process's named yet)
    folder = cache / "tracebacks"
    from tlm import storage

    stem = f"tlm-traceback-20260202-000000-{storage.process_tag()}"
    saved = []
    for i in range(3):
        try:
            raise RuntimeError(f"error number {i}")
        except RuntimeError as e:
            saved.append(cli_signals.save_traceback(e))
    assert [p.parent for p in saved] == [folder] * 3  # (was: the second in /tmp, the third nowhere)
    assert [p.name for p in saved] == [f"{stem}.txt", f"{stem}-2.txt", f"{stem}-3.txt"]
    assert [f"RuntimeError: error number {i}" in p.read_text() for i, p in enumerate(saved)] == [True] * 3
    # the command's line names the file written
    assert cli_failed._failed(ValueError("one more"), ["run"]) == 1
    line = capsys.readouterr().err
    named = Path(line.split("full traceback in ", 1)[1].rstrip(")\n"))
    assert named == folder / f"{stem}-4.txt" and "ValueError: one more" in named.read_text()
    # a file already at the process's next name (another's: a link) is not written through, as before
    (folder / f"{stem}-5.txt").symlink_to(cache / "victim.txt")
    (cache / "victim.txt").write_text("keep")
    monkeypatch.setattr(tempfile, "gettempdir", lambda: str(cache / "no-such-folder-file"))
    (cache / "no-such-folder-file").write_text("")  # (the temporary folder cannot take it either)
    assert cli_signals.save_traceback(RuntimeError("boom")) is None
    assert (cache / "victim.txt").read_text() == "keep"


# ------------------------------------------------------------------ 2: the reference command of a piped config


def test_a_piped_configs_reference_command_names_the_runs_copy(tmp_path, piped):
    from tlm.experiments.run import read_once, skipped_reference

    cfg = config.config_from_dict({"scene": "cornell", "mode": "pmap"})
    pipe = piped(b"scene: cornell\n")
    out = tmp_path / "o"
    got = skipped_reference(cfg, pipe, ["resolution=[16,16]"], out)
    assert got["command"] == f"tlm reference {out.absolute() / 'config.resolved.yaml'}"  # (was /dev/fd/N --set ...)
    assert got["config_read_once"].startswith(f"{pipe} is a pipe, read once: the command names the run's copy")
    file = tmp_path / "c.yaml"
    file.write_text("scene: cornell\n")
    assert skipped_reference(cfg, str(file), ["resolution=[16,16]"], out) == {  # (a file: as before)
        "skipped": "--no-reference", "command": f"tlm reference {file} --set 'resolution=[16,16]'"}
    assert (read_once(pipe), read_once(str(file)), read_once(None)) == ("a pipe", None, None)


@needs_dev_fd
def test_tlm_run_of_a_piped_config_records_a_command_that_runs_again(tmp_path, cache, piped, capsys):
    out = tmp_path / "pm"
    pipe = piped((ROOT / "configs" / "cornell.yaml").read_bytes())
    assert main(["run", pipe, "--mode", "pmap", "--set", "resolution=[16,16]", "--set", "photons.count=2000",
                 "--no-reference", "--out", str(out), "--no-progress", "--no-report"]) == 0
    resolved = out.absolute() / "config.resolved.yaml"
    line = next(x for x in capsys.readouterr().out.splitlines() if "pmap error" in x)
    assert line.split("compute it with: ", 1)[1].startswith(f"tlm reference {resolved} ({pipe} is a pipe, read once")
    error = json.loads((out / "results.json").read_text())["error"]
    assert error["command"] == f"tlm reference {resolved}" and resolved.is_file()  # (was `tlm reference /dev/fd/N`)
    cfg = config.load_config(resolved)[0]  # (what it names: every setting of the run, the --set values included)
    assert (cfg.mode, cfg.resolution, cfg.photons.count) == ("pmap", (16, 16), 2000)


def test_a_sweeps_piped_base_is_named_by_a_points_config(tmp_path, piped, monkeypatch):
    from types import SimpleNamespace

    from tlm.experiments.sweep_reference import _base_config

    monkeypatch.chdir(tmp_path)
    (tmp_path / "base.yaml").write_text("scene: cornell\n")
    sweep = SimpleNamespace(path=tmp_path / "sweep.yaml", base_file="base.yaml")
    assert _base_config(sweep) == "base.yaml"
    assert _base_config(SimpleNamespace(path=tmp_path / "sweep.yaml", base_file=piped(b"scene: cornell\n"))) \
        is None  # (was /dev/fd/N, relative to here: no command reads it again)


# ------------------------------------------------------------------ 3: a mesh through a pipe

OBJ = (ROOT / "scenes" / "examples" / "pawn.obj").read_bytes()[:3000]
PLY = (b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
       b"property float z\nend_header\n" + struct.pack("<9f", *[0.1 * i + 1e-3 for i in range(9)]) + b"\xff\xfe")
STL = b"\x00" * 80 + struct.pack("<I", 1) + struct.pack("<12f", *[1.5] * 12) + b"\x00\x00"
GLB = b"glTF" + struct.pack("<II", 2, 100) + b"\xff" * 88
GLTF = b'{"asset": {"version": "2.0"}, "meshes": [], "scenes": []}'


@needs_dev_fd
@pytest.mark.parametrize(("data", "suffix", "format_"), [
    (OBJ, ".obj", "an OBJ"), (PLY, ".ply", "a PLY"), (STL, ".stl", "an STL"),
    (GLB, ".glb", "a binary glTF (.glb)"), (GLTF, ".gltf", "a glTF")], ids=["obj", "ply", "stl", "glb", "gltf"])
def test_a_piped_mesh_is_said_as_a_mesh_file_is(tmp_path, piped, data, suffix, format_):
    named = tmp_path / f"mesh{suffix}"
    named.write_bytes(data)
    with pytest.raises(InputError) as by_name:
        config.read_yaml(named)
    pipe = piped(data)
    with pytest.raises(InputError) as piped:  # (was: must be a mapping, a YAML error, not a UTF-8 text file)
        config.read_yaml(Path(pipe))
    assert str(piped.value) == str(by_name.value).replace(
        f"{named}: is {format_} mesh file, not a YAML file: ",
        f"{pipe}: is {format_} mesh file given as a pipe, not a YAML file: save it as a file, mesh{suffix} (a mesh "
        "file is read by its suffix), ")
    assert f"given as a pipe, not a YAML file: save it as a file, mesh{suffix}" in str(piped.value)


@needs_dev_fd
def test_tlm_run_of_a_piped_mesh_is_one_line(tmp_path, piped, capsys):
    assert main(["run", piped(OBJ), "--out", str(tmp_path / "r")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "is an OBJ mesh file given as a pipe, not a YAML file" in err
    assert not (tmp_path / "r").exists()
    assert config.read_yaml(Path(piped(b"scene: cornell\n"))) == {"scene": "cornell"}  # (YAML: as before)


# ------------------------------------------------------------------ 4: too large, by the file's role


def test_a_programs_table_too_large_is_not_told_of_meshes(tmp_path, monkeypatch):
    from tlm.arch.costs import load_programs
    from tlm.config_read import MESH_NAMED, TooLarge

    monkeypatch.setattr(config, "MAX_TEXT_BYTES", 1000)
    big = tmp_path / "big.yaml"
    big.write_text("a: 1\n" * 500)
    with pytest.raises(InputError) as table:
        load_programs(big)
    assert str(table.value) == (f"{big}: arch.programs: is too large to be a YAML file tlm reads (2,500 bytes, at "
                                "most 0 MiB)")  # (was: ...: a mesh is named in a scene file's geometry)
    with pytest.raises(InputError) as run_config:  # (where a config or scene file goes: where a mesh goes)
        config.read_yaml(big)
    assert str(run_config.value).endswith(f"(2,500 bytes, at most 0 MiB): {MESH_NAMED}")
    assert MESH_NAMED == "a mesh is named in a scene file's geometry (docs/scenes.md)"
    assert isinstance(table.value, TooLarge) and isinstance(run_config.value, TooLarge)  # (InputErrors: exit 2)


# ------------------------------------------------------------------ 5: UTF-8 whatever the locale

PROBE = """
import sys
from pathlib import Path
from tlm import storage
from tlm.experiments.sweep_rows import write_rows
out = Path(sys.argv[1])
write_rows(out, [{"point": 0, "hash": "ab", "status": "ok", "host": "w\\u00f6rker-\\u03a9", "scene": "cornell"}])
storage.write_rows(out, "rows", [{"host": "w\\u00f6rker-\\u03a9"}])
with storage.appending(out / "log.txt") as f:
    f.write("w\\u00f6rker\\n")
"""


def test_text_files_are_utf8_under_an_ascii_locale(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "LC_ALL": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
    done = subprocess.run([sys.executable, "-c", PROBE, str(tmp_path)], capture_output=True, text=True, env=env,
                          timeout=120)
    assert done.returncode == 0, done.stderr  # (was: UnicodeEncodeError: 'ascii' codec can't encode '\xf6')
    assert "wörker-Ω" in (tmp_path / "sweep.csv").read_bytes().decode("utf-8")
    assert "wörker-Ω" in (tmp_path / "rows.csv").read_bytes().decode("utf-8")
    assert (tmp_path / "log.txt").read_bytes() == "wörker\n".encode()
