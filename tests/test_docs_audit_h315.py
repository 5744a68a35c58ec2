"""What a docs audit (h313) found, mended (h315): an error on a key of a scene file's ``extends:`` chain
names the file that gave the key (tlm/scenes/loader.py:load_scene, tlm/scenes/chain.py), and the pages
name what the code has (docs/api.md: every name of ``tlm.__all__``; docs/usage.md: every ``tlm params``
key, results.json's ``error.skipped``/``command``, ``tlm plots --only``'s steps, what ``tlm scene show``
prints; docs/functional.md: the default ``photons.aim`` first)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

import tlm
from tlm.cli import main

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
CORNELL = (ROOT / "scenes" / "cornell.yaml").read_text()


def _error(path: Path) -> tlm.InputError:
    with pytest.raises(tlm.InputError) as info:
        tlm.load_scene(path)
    return info.value


@pytest.mark.parametrize("geometry, key", [
    ("{transform: {scale: 0}}", "geometry.transform.scale"),
    ("{builder: cornell, params: {glass_seg: 2}}", "geometry.params.glass_seg"),
])
def test_a_one_item_geometry_merged_into_the_base_s_is_named_against_its_own_file(tmp_path, capsys, geometry, key):
    """(item 1) The one-item mapping merges into cornell's geometry, whose builder is cornell's; the bad
    key is this file's: its error named cornell.yaml (the file the geometry's mesh paths are relative to)."""
    scene = tmp_path / "s6.yaml"
    scene.write_text(f"extends: cornell\ngeometry: {geometry}\n")
    e = _error(scene)
    assert (e.source, e.key) == (str(scene), key), str(e)
    assert main(["scene", "show", str(scene)]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith(f"tlm: error: {scene}: {key}: "), line


@pytest.mark.parametrize("change, key", [
    (("ior: 1.5", "ior: -1"), "materials.glass.ior"),
    (("up: [0.0, 1.0, 0.0]", "up: [0.0, 0.0, 1.0]"), "camera.up"),
    (("power: [1100000.0, 950000.0, 750000.0]", "power: [1, 2]"), "lights[0].power"),
    (("photons: 120000", "photons: -3"), "photons"),
    (("glass_object: glass", "glass_object: glas"), "parts.glass_object"),
])
def test_a_bad_value_the_base_gives_is_named_against_the_base(tmp_path, change, key):
    """(item 1, the other merged keys) A scene file that extends one with a bad value, and gives
    none of that key itself: the error is the base's (it named the file that extends it)."""
    old, new = change
    assert CORNELL.count(old) == 1
    base = tmp_path / "base.yaml"
    base.write_text(CORNELL.replace(old, new))
    kid = tmp_path / "kid.yaml"
    kid.write_text("extends: base.yaml\nname: kid\n")
    e = _error(kid)
    assert (e.source, e.key) == (str(base), key), str(e)
    assert _error(base).source == str(base)  # (the base alone: the same line)


def test_a_key_the_middle_file_of_a_chain_gives_is_named_against_that_file(tmp_path):
    middle = tmp_path / "middle.yaml"
    middle.write_text("extends: cornell\ngeometry: {params: {glass_seg: 2}}\n")
    top = tmp_path / "top.yaml"
    top.write_text("extends: middle.yaml\nname: top\n")
    e = _error(top)
    assert (e.source, e.key) == (str(middle), "geometry.params.glass_seg"), str(e)


def test_a_mapping_merged_from_two_files_is_named_against_the_file_that_extends(tmp_path):
    """The camera's eye from this file, its target from cornell's: 'eye and target coincide' is
    the merged camera's, which no one file gave (this file's, as before; the key's own file is
    named where one file gave all of it)."""
    scene = tmp_path / "kid.yaml"
    scene.write_text("extends: cornell\ncamera: {eye: [278.0, 273.0, 0.0]}\n")
    e = _error(scene)
    assert (e.source, e.key) == (str(scene), "camera"), str(e)
    base = tmp_path / "base.yaml"
    base.write_text(CORNELL.replace("eye: [278.0, 273.0, -800.0]", "eye: [278.0, 273.0, 0.0]"))
    (tmp_path / "kid2.yaml").write_text("extends: base.yaml\n")
    e = _error(tmp_path / "kid2.yaml")
    assert (e.source, e.key) == (str(base), "camera"), str(e)


def _text(name: str) -> str:
    return (DOCS / name).read_text(encoding="utf-8")


def test_api_md_names_every_name_of_the_api():
    """(item 2) docs/api.md says everything the command does is a function of the package: each name
    of ``tlm.__all__`` is on the page, and the config command's functions of ``tlm.api`` too."""
    page = _text("api.md")
    missing = [n for n in tlm.__all__ if not re.search(rf"`(tlm\.)?{n}\b", page)]
    assert not missing, missing
    for name in ("list_experiments", "export_experiment"):
        assert f"api.{name}(" in page, name


def test_every_key_tlm_params_lists_is_named_in_the_docs():
    """(item 3) Each dotted key of ``tlm params`` is named, whole, on a page of docs/."""
    pages = "".join(p.read_text(encoding="utf-8") for p in DOCS.glob("*.md"))
    missing = [key for key, _, _ in tlm.params() if key not in pages]
    assert not missing, (f"tlm params lists {', '.join(missing)}, which no page of docs/ names: document each "
                         f"key in docs/usage.md, with its section's keys")
    usage = _text("usage.md")
    for key in ("photons.russian_roulette", "photons.caustic_count", "photons.aim_triangles", "estimate.cone_k",
                "estimate.k_nearest"):
        assert f"`{key}`" in usage, key


def test_the_results_json_error_row_names_what_a_skipped_reference_records():
    """(item 3) results.json's ``error`` of a reference not computed as asked (``--no-reference``)."""
    from tlm.config import RunConfig
    from tlm.experiments.run import skipped_reference

    (row,) = [line for line in _text("usage.md").splitlines() if line.startswith("| `error` |")]
    for key in skipped_reference(RunConfig(), "cornell.yaml", ()):
        assert f"`{key}`" in row, key


def _only_paragraph(usage: str) -> str:
    start = usage.index("`--only STEP [STEP ...]`")
    return usage[start:usage.index("\n\n", start)]


def test_plots_only_s_steps_are_listed_in_usage_md_and_in_the_help(capsys):
    """(item 3) Every step of ``tlm plots`` (tlm/report/regenerate.py:STEPS) by name, in usage.md's
    ``--only`` paragraph and in ``tlm plots --help``."""
    from tlm.report.regenerate import STEPS

    paragraph = _only_paragraph(_text("usage.md"))
    assert main(["plots", "--help"]) == 0
    help_text = " ".join(capsys.readouterr().out.split())
    for name, _ in STEPS:
        assert f"`{name}`" in paragraph, name
        assert re.search(rf"\b{name}\b", help_text), name


def test_usage_md_says_each_key_tlm_scene_show_prints(capsys):
    """(item 5) ``tlm scene show``'s JSON: each top-level key named in usage.md's sentence on it."""
    assert main(["scene", "show", "cornell"]) == 0
    shown = json.loads(capsys.readouterr().out)
    usage = _text("usage.md")
    start = usage.index("`tlm scene show NAME` (")
    said = usage[start:usage.index("`tlm scene export", start)]
    missing = [key for key in shown if f"`{key}`" not in said]
    assert not missing, missing


def test_functional_md_says_what_the_default_aim_does_first():
    """(item 4) The caustic group's aim: the default's (tlm/config.py) text first, then the other."""
    from tlm.config import RunConfig

    default = RunConfig().photons.aim
    page = _text("functional.md")
    said = re.search(r"By default \(`photons\.aim: (\w+)`\)", page)
    assert said and said.group(1) == default
    other = "box" if default == "parts" else "parts"
    assert said.start() < page.index(f"`photons.aim: {other}`")


def test_the_chain_s_origins_follow_each_key_to_the_file_that_gave_it_last():
    """tlm/scenes/chain.py: the bookkeeping behind the tests above, key by key."""
    from tlm.scenes.chain import origin, record

    a, b, c = Path("a.yaml"), Path("b.yaml"), Path("c.yaml")
    first = {"geometry": {"builder": "cornell", "params": {"x": 1}}, "lights": [{"type": "point"}],
             "camera": {"eye": [0, 0, 1], "target": [0, 0, 0]}}
    origins: dict[str, Path] = {}
    record(origins, first, {}, a)
    record(origins, {"geometry": {"params": {"x": 2}}, "camera": {"eye": [0, 0, 2]}}, first, b)
    assert origin(origins, "geometry.params.x") == b and origin(origins, "geometry.builder") == a
    assert origin(origins, "lights[0].power") == a  # (below a list: the list's file)
    assert origin(origins, "camera.eye") == b and origin(origins, "camera.target") == a
    assert origin(origins, "camera") is None and origin(origins, "geometry") is None  # (merged from two files)
    assert origin(origins, "camera.up") is None and origin(origins, "resolution") is None  # (no file gave them)
    record(origins, {"geometry": [{"mesh": "m.obj"}]}, {"geometry": {"builder": "cornell"}}, c)  # (replaced whole)
    assert origin(origins, "geometry.builder") == c and origin(origins, "geometry[0].mesh") == c


def test_a_material_given_another_type_is_the_file_s_that_retypes_it(tmp_path):
    """A material retyped is replaced whole (read_scene_tree): a key of it missing is the retyping file's,
    even where the base gave that key to the material it replaced."""
    base = tmp_path / "base.yaml"
    base.write_text(CORNELL)
    middle = tmp_path / "middle.yaml"
    middle.write_text("extends: base.yaml\nmaterials: {glass: {type: mirror}}\n")  # (no reflectance)
    top = tmp_path / "top.yaml"
    top.write_text("extends: middle.yaml\nname: top\n")
    e = _error(top)
    assert (e.source, e.key) == (str(middle), "materials.glass.reflectance"), str(e)
