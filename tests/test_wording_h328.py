"""Wording leftovers of a last read (h328): a scene given as a pipe by a descriptor's name (``tlm scene show
/dev/stdin``, ``<(...)``) is said to be a pipe, not a link to nothing; a mesh file read as YAML through a descriptor's
name (``tlm run /dev/stdin < pawn.ply``) gets the pipe's words (save it as mesh.ply), not "rename it stdin.ply"; an
OBJ's ``mtllib`` that names a folder says so; a scene-file base of a sweep or a granularity study with a typo is its
one error line, without the base's note before it."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.granularity import load_granularity
from tlm.scenes.meshes import load_mesh

SCENES = Path(__file__).resolve().parents[1] / "scenes"
PLY = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n" \
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"


def _descriptor(data: bytes, tmp_path: Path, pipe: bool) -> int:
    """A descriptor reading ``data``: a pipe's, or a regular file's (as ``/dev/stdin < file`` gives)."""
    if pipe:
        r, w = os.pipe()
        os.write(w, data)
        os.close(w)
        return r
    (tmp_path / "given").write_bytes(data)
    return os.open(tmp_path / "given", os.O_RDONLY)


def test_a_scene_given_as_a_pipe_by_a_descriptors_name_is_said_to_be_a_pipe(tmp_path, capsys):
    fd = _descriptor((SCENES / "cornell.yaml").read_bytes(), tmp_path, pipe=True)
    try:
        assert main(["scene", "show", f"/dev/fd/{fd}"]) == 2
    finally:
        os.close(fd)
    out, err = capsys.readouterr()
    assert out == ""
    assert err == (f"tlm: error: /dev/fd/{fd}: is a pipe (a file descriptor's name), not a scene file: a scene is "
                   "read by its file's name (again by a render, its extends: and meshes from its folder): save it to "
                   "a file and name that\n"), err


def test_a_mesh_file_read_through_a_descriptors_name_gets_the_pipes_words(tmp_path, capsys):
    for pipe in (False, True):
        fd = _descriptor(PLY.encode(), tmp_path, pipe)
        try:
            assert main(["run", f"/dev/fd/{fd}", "--out", str(tmp_path / "o")]) == 2
        finally:
            os.close(fd)
        err = capsys.readouterr().err
        given = "given as a pipe" if pipe else "given by a file descriptor's name"
        said = (f"tlm: error: /dev/fd/{fd}: is a PLY mesh file {given}, not a YAML file: save it as a file, mesh.ply "
                "(a mesh file is read by its suffix), write `geometry: {mesh: mesh.ply}`")
        assert err.startswith(said), err
        assert err.count("\n") == 1 and "rename it" not in err and not (tmp_path / "o").exists()


def test_an_mtllib_that_names_a_folder_says_so(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "a.obj").write_text("mtllib sub\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(InputError) as e:
        load_mesh(tmp_path / "a.obj")
    assert str(e.value) == (f"{tmp_path / 'a.obj'}: line 1: the material library 'sub' (mtllib) is a folder, not a "
                            f"file: {tmp_path / 'sub'}")
    (tmp_path / "b.mtl").write_text("newmtl x\nKd 1 0 0\n")
    (tmp_path / "a.obj").write_text("mtllib sub b.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(InputError) as e:
        load_mesh(tmp_path / "a.obj")
    assert str(e.value).endswith(f"; b.mtl found) ({tmp_path / 'sub'}: a folder)"), str(e.value)


def test_a_scene_file_base_with_a_typo_is_one_line_without_the_note(tmp_path, capsys):
    (tmp_path / "bad.yaml").write_text("geometry: {builder: cornell_box}\ncamerra: {}\n")
    error = f"{tmp_path / 'bad.yaml'}: camerra: unknown key (did you mean 'camera'?)"
    spec = tmp_path / "sw.yaml"
    spec.write_text("base: bad.yaml\ngrid: {render.spp: [1, 2]}\n")
    assert main(["sweep", str(spec), "--dry-run", "--json", "--out", str(tmp_path / "o")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err == f"tlm: error: {error}\n", err
    study = tmp_path / "gr.yaml"
    study.write_text("base: bad.yaml\npacket_sizes: [16, 64]\n")
    with pytest.raises(InputError) as e:
        load_granularity(study)
    assert str(e.value) == error
    assert capsys.readouterr().err == ""
