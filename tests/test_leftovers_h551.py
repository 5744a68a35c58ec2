"""Two leftovers of h534's review (h551). 1: the Python API takes ``-`` as a file's name in every function that takes a
config or an experiment file (``"-"``, ``"./-"`` and ``Path("-")`` alike), and where no such file is here says so in
the API's words; before, ``tlm.load_config("-")`` read a file ``-`` while ``tlm.sweep("-")`` and the studies refused it,
quoting the command line (``tlm run /dev/stdin --out DIR``). The command line still refuses ``-`` (h526's tests).
2: ``tlm cache list`` shows a scene file by the fewest trailing parts of its path that tell a group's frames apart,
not its whole absolute path (which widened the "what" column to ~150 characters); ``--json``'s ``differs`` keeps it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import tlm
from tlm import api
from tlm import cache_admin as ca
from tlm.fingerprint import code_fingerprint

# ------------------------------------------------------------------ 1: `-` in the Python API

WHERE_NONE = "-: no file of that name here (the Python API reads no standard input: give a file's path, or "
CALLS = {"load_config": lambda c, out: tlm.load_config(c), "experiment_path": lambda c, out: api.experiment_path(c),
         "reference": lambda c, out: tlm.reference(c), "run": lambda c, out: tlm.run(c, out),
         "sweep": lambda c, out: tlm.sweep(c, out), "thesis": lambda c, out: tlm.thesis(c, out),
         "calibrate": lambda c, out: tlm.calibrate(c), "extreme": lambda c, out: tlm.extreme(c, out)}


@pytest.mark.parametrize("given", ["-", Path("-")], ids=["str", "Path"])
@pytest.mark.parametrize("call", list(CALLS))
def test_dash_where_no_file_is_refused_in_the_apis_words(tmp_path, monkeypatch, call, given):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(api.InputError) as got:
        CALLS[call](given, tmp_path / "out")
    said = str(got.value)
    how = "pass the config as a mapping)" if call in ("load_config", "experiment_path", "reference", "run") else \
        "a built-in experiment's name)"
    assert said == WHERE_NONE + how, said  # (before: "... give /dev/stdin (tlm run /dev/stdin --out DIR ...")
    assert "tlm " not in said and not (tmp_path / "out").exists()


def test_dash_is_the_file_of_that_name_in_every_api_function_not_on_the_command_line(tmp_path, monkeypatch, capsys):
    from tlm.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "-").write_text("scene: cornell\nresolution: [8, 8]\n")
    for given in ("-", "./-", Path("-")):
        assert api.experiment_path(given) == api.experiment_path(given, "sweep") == Path("-")
        assert tlm.load_config(given).settings.resolution == (8, 8)
        for study in ("sweep", "thesis", "extreme"):  # (read: a run config, which the study does not run; before:
            with pytest.raises(api.InputError, match=r"^-: a run config \(it has scene:\), not a"):  # "-" unread)
                CALLS[study](given, tmp_path / "out")
    assert main(["sweep", "-"]) == 2  # (the command line: refused, as h526 made it, a file "-" here or not)
    assert "-: not the standard input here: give /dev/stdin (tlm sweep /dev/stdin" in capsys.readouterr().err
    # (the command line's lookup, through tlm.api as cli_parser's)
    with api.argument_names.flags_kept(), pytest.raises(api.InputError, match="give /dev/stdin"):
        api.experiment_path("-", "run")


# ------------------------------------------------------------------ 2: tlm cache list's source=


def _frames(folder: Path, sources: list[str]) -> list[ca.Entry]:
    """A frame a source, alike but for it (sidecars as frames writes them), described and told apart."""
    folder.mkdir(parents=True, exist_ok=True)
    entries = []
    for i, source in enumerate(sources):
        side = folder / (f"{i + 1:x}" * 24 + ".json")
        side.write_text(json.dumps({"scene": {"name": "room", "resolution": [8, 8], "source": source, "triangles": 10},
                                    "code_fingerprint": code_fingerprint(), "primary": {"spp": 1}}) + "\n")
        e = ca.Entry("functional", side.stem, [side])
        ca.describe(e, whole=True)
        entries.append(e)
    ca.tell_apart(entries)
    return entries


def test_cache_list_shows_a_scene_file_by_the_tail_that_tells_it_apart(tmp_path):
    deep = "/home/someone/projects/a-long-folder-name/experiments/2026-12-03/scenes"
    sources = [f"{deep}/a/room.yaml", f"{deep}/b/room.yaml", f"{deep}/a/other.yaml", "/room.yaml"]
    entries = _frames(tmp_path / "functional", sources)
    assert [e.what() for e in entries] == [  # (before: each whole path, 80 characters)
        "frame room 8x8 [source=a/room.yaml]", "frame room 8x8 [source=b/room.yaml]",
        "frame room 8x8 [source=other.yaml]", "frame room 8x8 [source=/room.yaml]"]
    rows = [json.loads(json.dumps(e.row())) for e in entries]  # (as --json writes them: the whole path)
    assert [r["differs"] for r in rows] == [{"source": s} for s in sources]
    assert rows[0]["what"] == entries[0].what()


def test_one_scene_file_name_in_two_folders_shows_what_tells_them_apart(tmp_path):
    entries = _frames(tmp_path / "functional", ["/x/scenes/room.yaml", "/y/x/scenes/room.yaml"])
    assert [e.what() for e in entries] == ["frame room 8x8 [source=/x/scenes/room.yaml]",
                                           "frame room 8x8 [source=y/x/scenes/room.yaml]"]


def test_a_run_config_named_dash_given_to_a_study_is_pointed_to_as_dot_slash_dash(tmp_path, monkeypatch):
    """The refusal's command names a file '-' as ./-: 'tlm run -' is refused on the command line (no stdin there)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "-").write_text("scene: cornell\nresolution: [8, 8]\n")
    with pytest.raises(tlm.InputError, match=r"run it with tlm run \./-$"):
        tlm.sweep("-", tmp_path / "out")
    assert not (tmp_path / "out").exists()
