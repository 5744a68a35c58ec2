"""Control characters and special destinations in the lines of the run, claims, scene loader and
studies. A run's warnings said during the run
(tlm.storage.warn) escape their control characters; ``--out`` in a folder that takes no new files
(/proc) is named with why (tlm.claims), not "cannot write beside the output folder (No such file or
directory)"; a scene given by itself that is a special file or a folder is named once (tlm.scenes.loader);
an error of a file with a tab in its name keeps its source when a study renames it (sweep_sets.named)."""

from __future__ import annotations

import os

import pytest

from tlm.cli import main
from tlm.errors import InputError
from tlm.render import checks as render_checks

SMALL_SETS = ["--set", "mode=rcast", "--set", "resolution=[8,8]", "--set", "render.spp=1", "--set",
              "render.light_samples=1", "--set", "arch.packet_size=16", "--set", "arch.frames=2"]
RED = "scene \x1b[31mred\x1b[0m café 日本"


def test_a_runs_warning_line_shows_an_escape_sequence(tmp_path, cache, monkeypatch, capsys):
    monkeypatch.setattr(render_checks, "branching_warning", lambda cfg, scene: [f"{RED}: a warning naming it"])
    assert main(["run", "cornell", "--out", str(tmp_path / "r"), "--no-report", "--outputs", "images",
                 *SMALL_SETS]) == 0
    err = capsys.readouterr().err
    assert "\x1b" not in err, err
    assert "tlm: warning: scene \\x1b[31mred\\x1b[0m café 日本: a warning naming it" in err.splitlines(), err


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc (a folder that takes no new files)")
@pytest.mark.parametrize("out", ["/proc/h254_xy", "/proc/h254_a/b", "/proc/h254_a\tb"])
def test_an_out_in_proc_is_named_with_why(capsys, out):
    assert main(["run", "cornell", "--out", out, "--no-report", *SMALL_SETS]) == 1  # (the machine's: as config export)
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("tlm: error:")]
    shown = out.replace("\t", "\\t")
    assert lines == [f"tlm: error: {shown}: cannot write: /proc takes no new files (making one there: no such file "
                     "or directory)"], lines


@pytest.mark.skipif(not os.path.exists("/dev/null"), reason="needs /dev/null")
def test_a_scene_given_by_itself_that_is_no_file_is_named_once(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "d").mkdir()
    for given, what in (("/dev/null", "a special file (a device, a pipe or a socket)"), ("d/", "a folder")):
        assert main(["scene", "show", given]) == 2
        assert capsys.readouterr().err.splitlines() == [f"tlm: error: {given}: is {what}, not a scene file"]
    (tmp_path / "c.yaml").write_text("scene: /dev/null\n")  # (named by a config: the config, its key, the path)
    assert main(["run", "c.yaml", "--no-report"]) == 2
    assert capsys.readouterr().err.splitlines() == [
        "tlm: error: c.yaml: scene: scene file '/dev/null' is a special file (a device, a pipe or a socket), not a "
        "scene file"]


def test_a_renamed_error_of_a_tabbed_file_names_it_once():
    from tlm.experiments.sweep_sets import named

    e = named(InputError("bad", source="a\tb.yaml", key="k"), "sweep.yaml")
    assert str(e) == "sweep.yaml: k: bad", str(e)
