"""Review of 66cab95: a mesh path holding a NUL character is bad input, not an internal error; a chain of
symbolic links ending in nothing is named as one; an editable install of this source tree whose
``pyproject.toml`` gives no version records the installed version, not "another copy"."""

from __future__ import annotations

import importlib.metadata as md
import json
from pathlib import Path

import pytest
import yaml

from tlm.errors import InputError
from tlm.scenes.loader import load_scene

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def _scene(folder: Path, mesh: str) -> Path:
    """A scene file in ``folder`` whose geometry is the mesh file ``mesh`` (any characters: YAML's own quoting)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "s.yaml"
    path.write_text(yaml.safe_dump({
        "geometry": [{"mesh": mesh}], "materials": {"grey": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
        "default_material": "grey", "lights": [{"type": "point", "position": [0.3, 0.3, 2], "power": [1, 1, 1]}],
        "camera": {"eye": [0.3, 0.3, 3], "target": [0.3, 0.3, 0], "up": [0, 1, 0], "vfov": 40},
        "resolution": [8, 8]}))
    return path


@pytest.mark.parametrize("mesh", ["x\0.obj", "../m/x\0.obj", "m/../x\0y.obj"])
def test_a_mesh_path_with_a_nul_character_is_bad_input_naming_it(tmp_path, mesh):
    (tmp_path / "m").mkdir()
    with pytest.raises(InputError) as e:  # (was a ValueError: "embedded null byte", tlm's internal error)
        load_scene(_scene(tmp_path / "a", mesh))
    said = str(e.value)
    assert "geometry[0].mesh" in said and "\\x00" in said and "not found" in said, said


def test_a_chain_of_links_ending_in_nothing_is_named_as_one(tmp_path):
    (tmp_path / "first.obj").symlink_to("second.obj")
    (tmp_path / "second.obj").symlink_to("nowhere.obj")
    with pytest.raises(InputError) as e:
        load_scene(_scene(tmp_path / "a", "../first.obj"))
    said = str(e.value)
    assert "is a symbolic link to 'second.obj', itself a link that leads to no file" in said, said
    assert "which is not there" not in said  # (second.obj is there: a link)


def _dist(folder: Path, version: str, direct_url: object | None) -> md.Distribution:
    """An installed tlm's metadata in ``folder`` (as pip writes it), with ``direct_url.json`` (None: none)."""
    info = folder / f"tlm-{version}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: tlm\nVersion: {version}\n")
    if direct_url is not None:
        (info / "direct_url.json").write_text(direct_url if isinstance(direct_url, str) else json.dumps(direct_url))
    return md.PathDistribution(info)


def test_an_editable_install_of_this_tree_without_a_version_in_its_pyproject_records_the_installed_one(
        tmp_path, monkeypatch):
    from tlm.experiments import provenance

    source = Path(provenance.__file__).resolve().parents[2]  # (the tree whose tlm/ runs)
    monkeypatch.setattr(provenance, "_source_version", lambda pyproject: None)  # (a pyproject with no version)
    another = "unknown (installed tlm 4.0 is another copy)"
    for i, (direct_url, recorded) in enumerate([
            ({"url": source.as_uri(), "dir_info": {"editable": True}}, "4.0"),  # (this tree's: its installed version)
            ({"url": source.as_uri(), "dir_info": {}}, another),  # (not editable: a copy of it installed)
            ({"url": "file:///elsewhere/tlm", "dir_info": {"editable": True}}, another),
            ("{not json", another), (["a list"], another), (None, another)]):
        dist = _dist(tmp_path / str(i), "4.0", direct_url)
        monkeypatch.setattr(md, "distribution", lambda name, dist=dist: dist)
        assert provenance.tlm_version.__wrapped__() == recorded, direct_url
