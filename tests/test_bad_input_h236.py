"""Bad input on the config and command-line side (h236): each case is one clear line and the
exit status of its kind, or an InputError naming the argument, not a crash, a hang or a silent pick.

A key that is no string (YAML's ``1:``, ``true:``, ``null:``, a date) is an unknown key; a YAML
alias bomb is refused where it is parsed, and the values a message shows are cut short; a
``render.threads`` past 1,024 is refused; a folder that takes no new files (``/proc``) is a
write error of one line; ``NUMBA_NUM_THREADS=0`` names the variable; a flag of one value given
twice is refused; ``load_scene`` names a wrong object by its type and ``load_config`` refuses a
set of overrides; an inline sweep base's key is named under ``base``; a value with a key given
twice says so; an error line shows control characters escaped.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import yaml

import tlm
from tlm import config_words, storage
from tlm.cli import build_parser, main
from tlm.cli_signals import one_line
from tlm.config import apply_overrides, config_from_dict, read_yaml
from tlm.errors import EnvironmentFailure, InputError
from tlm.experiments.sweep_file import load_sweep
from tlm.scenes.validate import shown

REPO = Path(__file__).resolve().parents[1]
SMALL = "scene: cornell\nresolution: [8, 8]\nmode: rcast\nrender: {spp: 1, light_samples: 1}\n"


def _bomb(levels: int, wide: int = 9) -> str:
    """A YAML list whose aliases expand it to ``wide ** (levels + 1)`` leaves in a few hundred bytes."""
    text = "&a0 [x" + ", x" * (wide - 1) + "]"
    for i in range(1, levels + 1):
        text = f"&a{i} [{text}" + f", *a{i - 1}" * (wide - 1) + "]"
    return text


def _one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tlm: error: "), err
    return lines[0]


@pytest.mark.parametrize(("key", "named"), [("1", "1"), ("true", "true"), ("null", "null"),
                                            ("2026-01-01", "2026-01-01")])
def test_a_key_that_is_no_string_is_an_unknown_key(tmp_path, cache, capsys, key, named):
    config = tmp_path / "intkey.yaml"
    config.write_text(f"{SMALL}{key}: 2\n")
    assert main(["run", str(config), "--out", str(tmp_path / "out")]) == 2
    assert _one_error_line(capsys.readouterr().err).endswith(f"intkey.yaml: {named}: unknown key")
    assert not (tmp_path / "out").exists()


def test_a_key_that_is_no_string_through_the_api_and_in_a_section():
    with pytest.raises(InputError, match=r"^\(dict\): 1: unknown key$"):
        tlm.load_config({"scene": "cornell", 1: 2})
    with pytest.raises(InputError, match=r"render\.null: unknown key"):
        config_from_dict({"render": {None: 2}})


def test_a_study_base_with_a_key_that_is_no_string(tmp_path, cache, capsys):
    study = tmp_path / "gran.yaml"
    study.write_text("base:\n  scene: cornell\n  mode: rcast\n  1: 2\npacket_sizes: [1, 4]\n")
    assert main(["granularity", str(study), "--out", str(tmp_path / "out")]) == 2
    assert _one_error_line(capsys.readouterr().err).endswith("gran.yaml: 1: unknown key")


def test_an_alias_bomb_is_refused_where_it_is_parsed(tmp_path):
    with pytest.raises(yaml.YAMLError, match="aliases"):
        config_words.parse_yaml(f"render:\n  spp: {_bomb(7)}\n")  # (9 ** 8: 43 million leaves in 400 bytes)
    config = tmp_path / "bomb.yaml"
    config.write_text(f"scene: cornell\nrender:\n  spp: {_bomb(7)}\n")
    with pytest.raises(InputError, match=r"bomb\.yaml: YAML error at line \d+, column \d+: its aliases"):
        read_yaml(config)
    assert len(config_words.parse_yaml(_bomb(4))) == 9  # (9 ** 5 leaves: taken, as a list written out would be)


def test_a_message_says_a_huge_value_after_a_few_items(monkeypatch):
    value = config_words.parse_yaml(_bomb(4))  # 59,049 leaves, each a string YAML would parse to say it
    said = []
    real = config_words._string_text
    monkeypatch.setattr(config_words, "_string_text", lambda v: said.append(v) or real(v))
    text = config_words.value_text(value)
    assert len(text) <= 80 and text.startswith("[[[[[x, x") and len(said) < 1000, (text, len(said))  # (not 59,049)
    assert len(config_words.value_text(list(range(10 ** 6)))) <= 80


def test_a_scene_message_shows_at_most_200_characters_of_a_value():
    assert len(shown(config_words.parse_yaml(_bomb(4)))) <= 200
    assert len(shown([0.5] * 100_000)) <= 200 and shown([0.5] * 100_000).endswith("...")
    assert shown([1.0, 2.0, 3.0]) == "[1.0, 2.0, 3.0]" and shown("x") == "'x'"


def test_render_threads_has_a_maximum():
    assert config_from_dict({"render": {"threads": 1024}}).render.threads == 1024
    with pytest.raises(InputError, match=r"render\.threads: 1025 must be <= 1024"):
        config_from_dict({"render": {"threads": 1025}})


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
def test_a_folder_that_takes_no_new_files_is_a_write_error(tmp_path, cache, capsys):
    with pytest.raises(EnvironmentFailure, match=r"^/proc/x\.yaml: cannot write: /proc takes no new files"):
        storage.write_file(Path("/proc/x.yaml"), "a: 1\n")
    assert main(["config", "export", "cornell", "/proc/x.yaml"]) == 1
    assert _one_error_line(capsys.readouterr().err) == ("tlm: error: /proc/x.yaml: cannot write: /proc takes no new "
                                                        "files (making one there: no such file or directory)")


def test_numba_num_threads_below_one_names_the_variable(tmp_path, cache, capsys, monkeypatch):
    config = tmp_path / "small.yaml"
    config.write_text(SMALL)
    monkeypatch.setenv("NUMBA_NUM_THREADS", "0")
    assert main(["run", str(config), "--out", str(tmp_path / "out")]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert line.startswith("tlm: error: environment: NUMBA_NUM_THREADS: '0' is below 1"), line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("argv", "said"), [
    (["run", "c.yaml", "--mode", "rcast", "--mode", "pmap"], "tlm run: --mode given twice (rcast, then pmap)"),
    (["run", "c.yaml", "--seed", "1", "--seed=2"], "tlm run: --seed given twice (1, then 2)"),
    (["run", "c.yaml", "--out", "a", "--out", "b"], "tlm run: --out given twice (a, then b)"),
    (["sweep", "s.yaml", "--jobs", "1", "--jobs", "2"], "tlm sweep: --jobs given twice (1, then 2)"),
    (["report", "d", "--title", "x", "--title", "y"], "tlm report: --title given twice (x, then y)"),
])
def test_a_flag_of_one_value_given_twice_is_refused(argv, said):
    with pytest.raises(InputError, match=r"given twice") as got:
        build_parser().parse_args(argv)
    assert str(got.value) == f"{said}: give it once"
    # (a flag that gathers its values stays repeatable; a flag given once is taken)
    args = build_parser().parse_args(["run", "c.yaml", "--set", "seed=1", "--set", "seed=2", "--seed", "3"])
    assert args.set == ["seed=1", "seed=2"] and args.seed == 3 and not hasattr(args, "_tlm_flags_given")


@pytest.mark.parametrize("value", [5, None, {"scene": "cornell"}, b"cornell"])
def test_load_scene_names_a_wrong_object_by_its_type(value):
    with pytest.raises(InputError, match=r"^scene: .* is not a scene's name or path") as got:
        tlm.load_scene(value)
    assert "built-in scene (" not in str(got.value)


def test_load_scene_names_a_config_by_its_type():
    with pytest.raises(InputError, match=r"^scene: a Config is not a scene's name or path"):
        tlm.load_scene(tlm.load_config("cornell"))


def test_load_config_refuses_a_set_of_overrides():
    with pytest.raises(InputError, match=r"^overrides: a set has no order"):
        tlm.load_config("cornell", {"render.spp=1", "render.spp=2"})
    assert tlm.load_config("cornell", ("render.spp=1", "render.spp=2")).render.spp == 2


def test_an_inline_sweep_base_names_its_key_under_base(tmp_path):
    sweep = tmp_path / "s.yaml"
    sweep.write_text("base: {scene: cornell, resolution: [8, 8], bogus: 1}\ngrid: {seed: [0, 1]}\n")
    with pytest.raises(InputError, match=r"s\.yaml: base\.bogus: unknown key"):
        load_sweep(sweep)
    sweep.write_text("base: {scene: cornell, render: {spp: 0}}\ngrid: {seed: [0, 1]}\n")
    with pytest.raises(InputError, match=r"s\.yaml: base\.render\.spp: 0 must be >= 1"):
        load_sweep(sweep)


def test_a_set_value_with_a_key_given_twice_says_so():
    with pytest.raises(InputError, match=r"render: cannot parse value '\{spp: 1, spp: 2\}': duplicate key 'spp'"):
        apply_overrides({}, ["render={spp: 1, spp: 2}"])


def test_an_error_line_shows_control_characters_escaped(tmp_path, cache, capsys):
    assert one_line(ValueError("a\x00b\x1b[31mc\td\x7f")) == "a\\x00b\\x1b[31mc d\\x7f"
    config = tmp_path / "nul.yaml"
    config.write_text(SMALL + 'arch: {programs: "p\\0.yaml"}\n')
    assert main(["run", str(config), "--out", str(tmp_path / "out")]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert "p\\x00.yaml" in line and "\x00" not in line, line


def test_usage_md_says_what_the_code_does():
    usage = (REPO / "docs" / "usage.md").read_text(encoding="utf-8")
    assert "(`tlm params | head -1`)" not in usage  # (its 11 KB may fit in the pipe: no 141)
    assert "`--set estimate={k: 9} has no effect in this run: ...`" in usage  # (the warning names it as given)
