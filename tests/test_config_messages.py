"""A config's error messages speak YAML, not Python: ``two is not an integer or null`` (not
``'two' is not an int | None``), a float of a whole number where an integer goes says what to
write, a file given to the wrong command names the command that takes it, and the overrides
are named as they were given (``--set`` on the command line, ``the overrides`` through the API)."""

from __future__ import annotations

import re
import typing
from pathlib import Path

import pytest

import tlm
from tlm.api_common import refuse_other_kind
from tlm.cli import main
from tlm.config import RunConfig, _schema, config_from_dict, describe, read_yaml
from tlm.config_words import value_text
from tlm.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"
# what no message may show: Python's type names, its union bar, NoneType, a quoted repr of the value
PYTHON = re.compile(r"NoneType|\||\b(int|str|float|bool)\b|list\[|'two'|\"two\"")


def _nested(key: str, value):
    section, _, name = key.rpartition(".")
    return {section: {name: value}} if section else {key: value}


def _error(call) -> str:
    with pytest.raises(InputError) as info:
        call()
    return str(info.value)


def _wrong(tp) -> object:
    """A value of none of the kinds ``tp`` takes."""
    args = set(typing.get_args(tp)) | {tp}
    return [1] if str in args else "two"


@pytest.mark.parametrize("key", [k for k, _, _ in describe()])
def test_every_field_s_type_error_is_in_yaml_words(key):
    section, _, name = key.rpartition(".")
    hints, _ = _schema(type(getattr(RunConfig(), section)) if section else RunConfig)
    bad = _wrong(hints[name])
    message = _error(lambda: config_from_dict(_nested(key, bad)))
    assert message.startswith(f"(dict): {key}: {value_text(bad)} is not "), message
    assert not PYTHON.search(message.partition(f"{key}: ")[2]), message


def test_the_probe_s_messages():
    assert _error(lambda: tlm.load_config("cornell", ["render.threads=two"], via="--set")) == (
        f"{CONFIGS / 'cornell.yaml'}, with --set: render.threads: two is not an integer or null")
    assert _error(lambda: config_from_dict({"resolution": "two"})) == (
        "(dict): resolution: two is not a list of 2 integers (e.g. [64, 64]) or null")
    assert _error(lambda: config_from_dict({"render": {"fresnel": "two"}})) == (
        "(dict): render.fresnel: two is not true or false")
    assert _error(lambda: config_from_dict({"photons": {"aim": 3}})) == (
        "(dict): photons.aim: 3 is not one of parts, box")
    assert _error(lambda: config_from_dict({"mode": "nope"})) == (
        "(dict): mode: nope is not one of rcast, reflect, refract, pmap")
    assert "scene: 3 is not a string (quote it, '3'" in _error(lambda: config_from_dict({"scene": 3}))
    assert _error(lambda: config_from_dict({"render": "two"})) == "(dict): render: must be a mapping of keys, got two"
    # a section given the one value its main key takes: the hint says where it goes (a bare "photons: 5000" was
    # refused with no word of photons.count)
    assert _error(lambda: config_from_dict({"photons": 5000})) == (
        "(dict): photons: must be a mapping of keys, got 5000 (did you mean photons: {count: 5000}?)")
    assert _error(lambda: config_from_dict({"estimate": "knn"})) == (
        "(dict): estimate: must be a mapping of keys, got knn (did you mean estimate: {filter: knn}?)")
    assert _error(lambda: config_from_dict({"photons": True})) == "(dict): photons: must be a mapping of keys, got true"


def test_a_file_that_is_not_a_mapping_says_what_it_is(tmp_path):
    path = tmp_path / "list.yaml"
    path.write_text("- scene: cornell\n")
    assert _error(lambda: tlm.load_config(path)) == f"{path}: must be a mapping of keys (key: value lines), got a list"


@pytest.mark.parametrize("value, text", [
    ("two", "two"), ("3", "'3'"), ("", "''"), ("null", "'null'"), ("it's", "it's"), ("a: b", "'a: b'"),
    (None, "null"), (True, "true"), (1e9, "1e9"), (1.5e12, "1.5e12"), (1e-5, "1e-5"), (0.5, "0.5"),
    (float("nan"), "nan"), ([64, "a"], "[64, a]"), ({"spp": 2}, "{spp: 2}"),
])
def test_values_are_shown_as_yaml_writes_them(value, text):
    assert value_text(value) == text


@pytest.mark.parametrize("raw, key, whole", [
    ({"resolution": [1e9, 1]}, "resolution", "1000000000"),
    ({"photons": {"count": 1e12}}, "photons.count", "1000000000000"),
    ({"render": {"spp": 4.0}}, "render.spp", "4"),
])
def test_a_float_of_a_whole_number_where_an_integer_goes_says_what_to_write(raw, key, whole):
    message = _error(lambda: config_from_dict(raw))
    assert f"{key}: " in message and message.endswith(f"reads as a float (a number written with an exponent or a "
                                                       f"decimal point); write {whole}")
    assert "1000000000.0" not in message and "e+" not in message
    assert "write" not in _error(lambda: config_from_dict({"render": {"spp": 2.5}}))  # (no whole number to write)


def test_a_file_given_to_another_command_names_the_command(tmp_path, capsys):
    thesis, sweep, cornell = CONFIGS / "thesis.yaml", CONFIGS / "sweep_fifo.yaml", CONFIGS / "cornell.yaml"
    assert _error(lambda: tlm.load_config("thesis")) == (
        f"{thesis}: a thesis study file (it has scenes:, modes:), not a run config or a scene file: "
        "run it with tlm thesis thesis")
    assert _error(lambda: tlm.run_sweep("thesis", tmp_path / "o")).endswith(
        "not a sweep file: run it with tlm thesis thesis")
    assert _error(lambda: tlm.scene_file(sweep)).endswith("a sweep file (it has grid:), not a run config or a "
                                                           "scene file: run it with tlm sweep sweep_fifo")
    assert _error(lambda: tlm.thesis("cornell", tmp_path / "o")).endswith(
        "a run config (it has scene:), not a thesis study file: run it with tlm run cornell")
    refuse_other_kind(read_yaml(thesis), thesis, "calibrate")  # (calibrate fits to a thesis study)
    mine = tmp_path / "mine.yaml"
    mine.write_text("description: a copy\nbase: {scene: cornell}\ncases: []\n")
    assert _error(lambda: tlm.load_config(mine)).endswith(f"not a run config or a scene file: run it with tlm "
                                                          f"extreme {mine}")
    assert main(["sweep", "thesis", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("tlm: error:") == 1 and err.strip().endswith("tlm thesis thesis")
    assert not (tmp_path / "o").exists()
    unclear = tmp_path / "unclear.yaml"  # (a study's base, its key mistyped: no command to name, not a config)
    unclear.write_text("base: {scene: cornell}\nscnes: [cornell]\n")
    assert "not a run config (keys: base, scnes): `base:` is a study's or a sweep's" in _error(
        lambda: tlm.load_config(unclear))
    # a run config's typo of a study's key is still the run config's own message
    typo = tmp_path / "typo.yaml"
    typo.write_text("modes: pmap\n")
    assert "modes: unknown key (did you mean 'mode'?)" in _error(lambda: tlm.load_config(typo))
    assert cornell.is_file()


def test_overrides_are_named_as_they_were_given(tmp_path):
    scene = tmp_path / "Mirror.yaml"
    scene.write_text("geometry: {builder: cornell}\n")
    api = _error(lambda: tlm.load_config(scene, {"render.threads": "two"}))
    assert api == f"scene file {scene} at the default settings, with the overrides: render.threads: two is not an " \
                  "integer or null"
    cli = _error(lambda: tlm.load_config(scene, ["render.threads=two"]))
    assert cli.startswith(f"scene file {scene} at the default settings, with --set: ")
    assert "with --set" not in _error(lambda: tlm.load_config({"seed": 0}, {"seed": -1}))
    assert "(dict), with the overrides: seed: -1 must be >= 0" in _error(lambda: tlm.load_config({}, {"seed": -1}))
    # the command line's strings are --set's; a mapping, or what via says, is named so
    assert tlm.load_config("cornell", ["mode=rcast"]).label.endswith("cornell.yaml, with --set")
    cfg = tlm.load_config("cornell", {"mode": "rcast"})
    assert cfg.label.endswith("cornell.yaml, with the overrides")
    assert cfg.updated(["seed=2"]).label == cfg.label  # (named as its first overrides were)
    assert tlm.load_config(cfg.settings, {"seed": 1}).label == "(dict), with the overrides"
    assert tlm.load_config("cornell", ["mode=rcast"], via="the notebook's").label.endswith(
        "cornell.yaml, with the notebook's")
    assert "the overrides: 'seed' is not of the form" in _error(lambda: tlm.load_config("cornell", ["seed"],
                                                                                         via="the overrides"))
