"""Three small messages of the command line (a probe of an installed copy): a bare ``tlm
config`` or ``tlm scene`` names its subcommands, not argparse's ``config_cmd``; ``tlm
scaling`` of a folder that does not exist says so; a scene not found lists the built-in
scenes ``tlm scene list`` lists (not the two of bad input on purpose, still built-in by name)."""

from __future__ import annotations

import pytest

from tlm.cli import main
from tlm.errors import InputError
from tlm.scenes.loader import list_scenes, listed_scenes, resolve_scene_path


@pytest.mark.parametrize("command, subcommands", [("config", "{list,export}"), ("scene", "{list,show,export}")])
def test_a_bare_command_of_subcommands_names_them(capsys, command, subcommands):
    assert main([command]) == 2
    err = capsys.readouterr().err
    assert err.strip() == f"tlm: error: tlm {command}: the following arguments are required: {subcommands}", err


def test_scaling_of_a_folder_that_does_not_exist_says_so(tmp_path, capsys):
    assert main(["scaling", str(tmp_path / "nowhere"), "--no-report"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == (f"tlm: error: {tmp_path / 'nowhere'}: no such folder: name a 'tlm sweep' output folder "
                           "(runs/scaling_ring)"), err
    assert not (tmp_path / "nowhere").exists()


def test_a_scene_not_found_lists_the_scenes_scene_list_lists(capsys):
    bad = [n for n in list_scenes() if n not in listed_scenes()]
    assert bad == ["extreme/bad_extends_itself", "extreme/bad_scale_zero"]
    with pytest.raises(InputError) as e:
        resolve_scene_path("nosuch")
    assert "cornell" in str(e.value) and not any(b in str(e.value) for b in bad)
    assert main(["scene", "list"]) == 0
    shown = capsys.readouterr().out
    assert all(n in shown for n in listed_scenes()) and not any(b in shown for b in bad)
    assert resolve_scene_path("extreme/bad_scale_zero").name == "bad_scale_zero.yaml"  # (built-in by name)
