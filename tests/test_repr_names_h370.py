"""A byte of a name not UTF-8 (a folder ``dir_\\xff`` from another system) in the scene loader's, the mesh files', the
export's and the report's messages is shown as ``\\xff``, by :func:`tlm.errors.quoted`, as h368 made the others
(``mesh file '.../dir_\\xff/missing.obj' not found``, not ``dir_\\udcff``); and a ``--set`` value holding one
(``--set scene=dir_\\xff/c.yaml``, which YAML refuses: ``unacceptable character #xdcff``) is kept as the path it
is, YAML's syntax around it read as without it (:func:`tlm.config.read_set_value`)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tlm.cli import main
from tlm.config import apply_overrides, read_set_value, read_yaml
from tlm.errors import InputError

REPO = Path(__file__).resolve().parents[1]
DIR = os.fsdecode(b"dir_\xff")  # (dir_\udcff, as the command line and os.listdir read it)
SHOWN = "dir_\\xff"  # (what a tlm: line shows of it)


def _err(capsys, argv: list[str]) -> str:
    """The ``tlm:`` error ``tlm ARGV`` ends with (exit 2), no surrogate's escape in it."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "\\udc" not in err and "Traceback" not in err, err
    return err


def test_scene_and_mesh_paths_not_utf8_shown_as_a_byte(tmp_path, cache, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / DIR).mkdir()
    (tmp_path / DIR / "m.yaml").write_text("extends: cornell\ngeometry: [{mesh: missing.obj}]\n", encoding="utf-8")
    err = _err(capsys, ["scene", "show", f"{DIR}/m.yaml"])
    assert f"geometry[0].mesh: mesh file '{tmp_path}/{SHOWN}/missing.obj' not found" in err
    os.symlink(f"{DIR}/gone.obj", tmp_path / DIR / "link.obj")
    (tmp_path / DIR / "l.yaml").write_text("extends: cornell\ngeometry: [{mesh: link.obj}]\n", encoding="utf-8")
    err = _err(capsys, ["scene", "show", f"{DIR}/l.yaml"])
    assert f"mesh file '{tmp_path}/{SHOWN}/link.obj' is a symbolic link to '{SHOWN}/gone.obj', which" in err
    (tmp_path / DIR / "e.yaml").write_text("extends: none.yaml\n", encoding="utf-8")
    err = _err(capsys, ["scene", "show", f"{DIR}/e.yaml"])
    assert f"extends: scene file 'none.yaml' not found (looked in {tmp_path}/{SHOWN}" in err
    err = _err(capsys, ["scene", "show", f"{DIR}/none.yaml"])
    assert f"scene: scene file '{SHOWN}/none.yaml' not found" in err
    (tmp_path / DIR / "afile").write_text("x")
    err = _err(capsys, ["scene", "export", "cornell", f"{DIR}/afile/no/x.obj"])
    assert f"{SHOWN}/afile/no/x.obj: folder '{SHOWN}/afile/no' cannot be made: '{SHOWN}/afile' is a file" in err
    assert not (tmp_path / DIR / "afile").is_dir()


def test_a_set_value_with_a_byte_not_utf8_is_kept():
    path = f"{DIR}/c.yaml"
    assert read_set_value(path) == path and read_set_value(f'"{path}"') == path and read_set_value(f"'{path}'") == path
    assert read_set_value(f"[{path}, 2]") == [path, 2] and read_set_value(f"{{a{DIR}: {path}}}") == {f"a{DIR}": path}
    # (YAML's syntax without one, as it was)
    assert read_set_value("[8, 8]") == [8, 8] and read_set_value("'3'") == "3" and read_set_value("1e3") == 1000.0
    assert read_set_value("{spp: 2}") == {"spp": 2} and read_set_value("null") is None
    assert apply_overrides({}, [f"scene={path}", "render.spp=2"]) == {"scene": path, "render": {"spp": 2}}
    # (an error of YAML's keeps its line, the byte shown as a tlm: line shows it)
    for text, problem in ((f"[{path}", "expected ',' or ']', but got '<stream end>'"),
                          ("[1", "expected ',' or ']', but got '<stream end>'"),
                          (f"{{a: {DIR}, a: 2}}", "duplicate key 'a': give each key once")):
        with pytest.raises(InputError) as e:
            apply_overrides({}, [f"x={text}"])
        said = str(e.value)
        assert "cannot parse value" in said and problem in said and "\\udc" not in said and "\n" not in said, said
    with pytest.raises(InputError) as e:
        apply_overrides({}, [f"x=[{path}"])
    assert f"cannot parse value '[{SHOWN}/c.yaml'" in str(e.value)


def test_a_run_of_a_scene_in_a_folder_not_utf8_by_set(tmp_path, cache, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / DIR).mkdir()
    assert main(["scene", "export", "cornell", f"{DIR}/c.yaml"]) == 0  # (c.yaml, its c.obj and c.mtl)
    capsys.readouterr()
    argv = ["run", str(REPO / "configs" / "cornell.yaml"), "--set", f"scene={DIR}/c.yaml", "--set", "resolution=[8,8]",
            "--out", "o", "--no-progress", "--no-report"]
    assert main(argv) == 0, capsys.readouterr().err
    assert read_yaml(tmp_path / "o" / "config.resolved.yaml")["scene"] == str(tmp_path / DIR / "c.yaml")
    # (the report's folder refused where it is the run it reads, the run named as a byte is shown; a report.html in
    # the run's folder, as if a report had been written there, lets it past the check of an earlier output)
    (tmp_path / DIR / "o").symlink_to(tmp_path / "o")
    (tmp_path / "o" / "report.html").write_text("", encoding="utf-8")
    err = _err(capsys, ["report", f"{DIR}/o", "--out", "o"])
    assert f"--out: 'o' is '{SHOWN}/o', an input of the report" in err
    err = _err(capsys, ["run", str(REPO / "configs" / "cornell.yaml"), "--set", f"scene={DIR}/none.yaml",
                        "--out", "o2", "--no-progress"])
    assert f"with --set: scene: scene file '{SHOWN}/none.yaml' not found" in err and not (tmp_path / "o2").exists()
