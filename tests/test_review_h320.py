"""Review of 9b0e3bd (h320).

1. A mesh given through a pipe was told as one only where ``os.memfd_create`` and ``/proc/self/fd`` exist (Linux): its
   bytes were written to an anonymous file to be told by :func:`~tlm.mesh_files.mesh_file_format`; on macOS (no
   memfd, no /proc) ``tlm run <(cat pawn.obj)`` was parsed as YAML still (``must be a mapping``). Now the bytes are
   told by themselves (:func:`~tlm.mesh_files.mesh_bytes_format`, which ``mesh_file_format`` reads a file by), on any
   system.
2. The report's readers of tlm's own JSON and YAML (``tlm.report.checks.read_json``/``read_yaml``) and
   ``read_jsonl`` read in the locale's encoding what tlm now writes in UTF-8: under an ASCII locale a non-ASCII
   character was "cannot read". Now UTF-8.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from tlm import config
from tlm.errors import InputError
from tlm.mesh_files import MTL_FORMAT, mesh_bytes_format, mesh_file_format

ROOT = Path(__file__).resolve().parents[1]

OBJ = (ROOT / "scenes" / "examples" / "pawn.obj").read_bytes()[:3000]
PLY = (b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
       b"property float z\nend_header\n" + struct.pack("<9f", *[0.1 * i + 1e-3 for i in range(9)]) + b"\xff\xfe")
STL = b"\x00" * 80 + struct.pack("<I", 1) + struct.pack("<12f", *[1.5] * 12) + b"\x00\x00"
GLB = b"glTF" + struct.pack("<II", 2, 100) + b"\xff" * 88
GLTF = b'\n  {"asset": {"version": "2.0"}, "meshes": [], "scenes": []}'


@pytest.mark.skipif(not os.path.isdir("/dev/fd"), reason="no /dev/fd here")
@pytest.mark.parametrize(("data", "format_"), [
    (OBJ, "an OBJ"), (PLY, "a PLY"), (STL, "an STL"), (GLB, "a binary glTF (.glb)"), (GLTF, "a glTF")],
    ids=["obj", "ply", "stl", "glb", "gltf"])
def test_a_piped_mesh_is_told_where_there_is_no_memfd(piped, monkeypatch, data, format_):
    monkeypatch.delattr(os, "memfd_create", raising=False)  # (macOS, the BSDs: no memfd_create, no /proc)
    pipe = piped(data)
    with pytest.raises(InputError) as e:  # (was: must be a mapping, a YAML error, not a UTF-8 text file)
        config.read_yaml(Path(pipe))
    assert f"{pipe}: is {format_} mesh file given as a pipe, not a YAML file: save it as a file" in str(e.value)
    assert config.read_yaml(Path(piped(b"scene: cornell\n"))) == {"scene": "cornell"}  # (YAML: as before)


BIG_GLTF = json.dumps({"asset": {"version": "2.0"}, "meshes": [], "extras": "x" * (1 << 20)}).encode()
CASES = {
    "obj": OBJ, "ply": PLY, "stl": STL, "glb": GLB, "gltf": GLTF, "big_gltf": BIG_GLTF, "cut_gltf": GLTF[:-1],
    "ascii_stl": b"solid x\n facet normal 0 0 1\n  outer loop\n", "mtl": b"newmtl a\nKd 1 1 1\n",
    "json_config": b'{"scene": "cornell", "asset": {"version": 1}, "meshes": []}', "yaml": b"scene: cornell\n",
    "empty": b"", "stl_sized_yaml": b"\x00" * 84,
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_bytes_are_told_as_a_file_of_them_is(tmp_path, name):
    path = tmp_path / "noname"  # (no suffix: told by the content alone)
    path.write_bytes(CASES[name])
    assert mesh_bytes_format(CASES[name]) == mesh_file_format(path)
    assert mesh_bytes_format(CASES[name][:1 << 20], len(CASES[name])) == mesh_file_format(path)  # (a pipe's head)
    assert mesh_bytes_format(b"\x00" * 84, name="c.yaml") is None and mesh_file_format(tmp_path / "c.mtl") == MTL_FORMAT


PROBE = """
import json, sys
from pathlib import Path
from tlm.report.checks import read_json, read_yaml
from tlm.storage import read_jsonl
out = Path(sys.argv[1])
(out / "results.json").write_bytes(json.dumps({"host": "w\\u00f6rker"}, ensure_ascii=False).encode())
(out / "config.resolved.yaml").write_bytes("host: w\\u00f6rker\\n".encode())
(out / "sweep.jsonl").write_bytes((json.dumps({"host": "w\\u00f6rker"}, ensure_ascii=False) + "\\n").encode())
assert read_json(out / "results.json") == {"host": "w\\u00f6rker"}
assert read_yaml(out / "config.resolved.yaml") == {"host": "w\\u00f6rker"}
assert read_jsonl(out / "sweep.jsonl") == [(1, {"host": "w\\u00f6rker"})]
"""


def test_tlms_text_files_are_read_as_utf8_under_an_ascii_locale(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "LC_ALL": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
    done = subprocess.run([sys.executable, "-c", PROBE, str(tmp_path)], capture_output=True, text=True, env=env,
                          timeout=120)
    assert done.returncode == 0, done.stderr  # (was: cannot read: 'ascii' codec can't decode byte 0xc3)
