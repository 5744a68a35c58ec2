"""What the docs probe (h482) found in the code: a scene file given to ``tlm scene show`` by a link to it (as
``/dev/stdin < my.yaml`` is) has its meshes looked for beside the file, as ``tlm run`` looks for them, not beside
the link (``/dev/pawn.obj not found``)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from tlm import api

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "scenes" / "examples"


def _example(tmp_path: Path) -> Path:
    shutil.copytree(EXAMPLES, tmp_path / "ex")
    return tmp_path / "ex" / "mesh_on_floor.yaml"


def test_a_scene_file_on_stdin_from_a_file_finds_its_meshes_beside_the_file(tmp_path):
    scene = _example(tmp_path)
    with open(scene) as fh:
        done = subprocess.run([sys.executable, "-m", "tlm", "scene", "show", "/dev/stdin"], stdin=fh,
                              capture_output=True, text=True, cwd=tmp_path, timeout=300,
                              env={**os.environ, "PYTHONPATH": str(REPO)})  # (this tree's tlm)
    assert done.returncode == 0, done.stderr
    assert '"name": "mesh_on_floor"' in done.stdout and "not found" not in done.stderr


def test_a_scene_file_named_by_a_link_in_another_folder_loads_its_meshes(tmp_path):
    scene = _example(tmp_path)
    (tmp_path / "elsewhere").mkdir()
    link = tmp_path / "elsewhere" / "linked.yaml"
    link.symlink_to(scene)
    loaded = api.load_scene(link)
    assert loaded.n_triangles > 2 and loaded.source == str(scene)
