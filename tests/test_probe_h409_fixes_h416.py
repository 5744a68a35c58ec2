"""h416 (probe h409, D3, D5 and two wordings).

D3: ``tlm scene export`` wrote the scene's name and its meshes' licence notices into the scene file's
header comments as they were; a BEL, an ESC or a NUL there (YAML refuses them even in a comment) made the
exported file unreadable: the export exited 0, ``tlm scene show`` of it 2. The comments now show each such
character escaped (``\\x07``); the name itself, in ``name:``, round-trips.

D5: ``tlm granularity`` merged a packet size listed twice into one row, unsaid; ``tlm sweep`` and ``tlm
error-vs-cost`` refuse a value listed twice. It is refused as ``tlm sweep`` words it, nothing written.

Wordings: ``packet_sizes: [2e12]`` (a float) says the integer to write; ``--set packet_sizes=[8]`` says
that ``packet_sizes`` is the study file's own key, not "unknown key".
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.scenes.loader import load_scene

NAME = "a\x07b\x1b[31mred\x00z\x7f\x9f"  # BEL, ESC, NUL, DEL and a C1 control
SCENE = {"geometry": {"mesh": "tri.obj"}, "materials": {"white": {"type": "lambertian", "albedo": [0.7, 0.7, 0.7]}},
         "default_material": "white", "lights": [{"type": "point", "position": [0, 0, 5], "power": [10, 10, 10]}],
         "camera": {"eye": [0, 0, 5], "target": [0, 0, 0], "vfov": 40}, "resolution": [8, 8]}


def _scene(folder: Path, licence: str) -> Path:
    (folder / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (folder / "LICENSE").write_text(licence)
    path = folder / "s.yaml"
    path.write_text(yaml.safe_dump({"name": NAME, **SCENE}))  # (YAML's escapes: "a\ab\e[31m...")
    return path


def test_an_export_of_a_name_and_notice_with_control_characters_reads_back(tmp_path, capsys):
    src = _scene(tmp_path, "Copyright (c) 2020 Someone\x0c\nBEL\x07here ESC\x1b[31m NUL\x00 end\n")
    assert load_scene(src).name == NAME
    (tmp_path / "ex").mkdir()
    out = tmp_path / "ex" / "out.yaml"
    assert main(["scene", "export", str(src), str(out)]) == 0
    assert load_scene(out).name == NAME  # (the old export: "YAML syntax error: unacceptable character #x0007")
    assert main(["scene", "show", str(out)]) == 0
    head = [line for line in out.read_text().splitlines() if line.startswith("#")]
    assert head[0].startswith("# tlm scene a\\x07b\\x1b[31mred\\x00z\\x7f\\x9f: written by tlm scene export")
    assert "#   BEL\\x07here ESC\\x1b[31m NUL\\x00 end" in head
    # exported again (its notice now from the OBJ's header): the same file, readable
    (tmp_path / "ex2").mkdir()
    again = tmp_path / "ex2" / "out.yaml"
    assert main(["scene", "export", str(out), str(again)]) == 0
    assert load_scene(again).name == NAME
    assert again.read_text() == out.read_text()


def test_an_export_named_by_a_file_with_a_control_character_reads_back(tmp_path):
    src = _scene(tmp_path, "Copyright (c) 2020 Someone\n")
    out = tmp_path / "o\x07ut.yaml"  # (the mesh's name, o\x07ut.obj, is in the first comment line too)
    assert main(["scene", "export", str(src), str(out)]) == 0
    assert load_scene(out).name == NAME
    assert out.read_text().startswith("# tlm scene a\\x07b")


BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "arch": {"frames": 1}}


def _study(tmp_path: Path, sizes) -> Path:
    study = tmp_path / "g.yaml"
    study.write_text(json.dumps({"base": BASE, "packet_sizes": sizes}))
    return study


def _refused(args: list[str], capsys) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_a_packet_size_listed_twice_is_refused_as_tlm_sweep_refuses_one(tmp_path, capsys):
    out = tmp_path / "o"
    said = _refused(["granularity", str(_study(tmp_path, [4, 16, 4])), "--out", str(out)], capsys)
    assert said == f"tlm: error: {tmp_path / 'g.yaml'}: packet_sizes: 4 given twice"
    assert not out.exists()


@pytest.mark.parametrize("text, value, write", [("[2e12]", "2e12", "2000000000000"), ("[4.0]", "4.0", "4"),
                                               ("[1, 16.0]", "16.0", "16")])
def test_a_whole_packet_size_written_as_a_float_says_the_integer_to_write(tmp_path, capsys, text, value, write):
    study = tmp_path / "g.yaml"
    study.write_text(f"base: {json.dumps(BASE)}\npacket_sizes: {text}\n")
    said = _refused(["granularity", str(study), "--out", str(tmp_path / "o")], capsys)
    assert said.startswith(f"tlm: error: {study}: packet_sizes: ") and "whole numbers >= 1" in said
    assert said.endswith(f"{value} reads as a float (a number written with an exponent or a decimal point); "
                         f"write {write}")


def test_an_integer_is_offered_only_where_it_would_do(tmp_path, capsys):
    study = tmp_path / "g.yaml"
    for text, tail in [("[4.0, 8]", "; write 4"), ("[0.0]", ""), ("[4.0, 0]", ""), ("[1.5]", ""), ("4.0", ""),
                       ("[.inf]", ""), ("[true]", "")]:
        study.write_text(f"base: {json.dumps(BASE)}\npacket_sizes: {text}\n")
        said = _refused(["granularity", str(study), "--out", str(tmp_path / "o")], capsys)
        assert said.endswith(tail if tail else "must be a non-empty list of whole numbers >= 1"), (text, said)


@pytest.mark.parametrize("item", ["packet_sizes=[8]", "packet_sizes.x=1"])
def test_set_of_packet_sizes_says_it_is_the_study_file_s_key(tmp_path, capsys, item):
    study = _study(tmp_path, [4, 16])
    said = _refused(["granularity", str(study), "--out", str(tmp_path / "o"), "--set", item], capsys)
    assert said.startswith(f"tlm: error: {study}: --set {item}: packet_sizes")
    assert said.endswith("the study file's own key, and --set sets its base (the run config): change packet_sizes "
                         "in the study file")
    assert "unknown key" not in said
    assert not (tmp_path / "o").exists()
