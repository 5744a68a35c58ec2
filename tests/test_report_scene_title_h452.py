"""h452 (found by probe h443): the image sets' title names a run's scene as the thesis's by the rule
Tables I-III table it by (:func:`tlm.report.tables.thesis_table`, by its file), not by its label.

``scene_title`` compared the report's label with the thesis scene's name, so one report put a byte copy
of ``scenes/cornell.yaml`` under another name in Table III while its image set said "..., not the
thesis's Cornell Box scene", and titled a user's edited ``scenes/cornell.yaml``, read on another machine
(labelled ``cornell`` by its place), "cornell: Cornell Box scene (Fig. 17)" though the tables leave it out.
And the Tables section of a report with nothing to table says in one sentence why: no run of a thesis
scene *file* (a user's ``room.yaml`` is not one).
"""

from __future__ import annotations

import pytest

from tlm.config import config_from_dict
from tlm.experiments.run import run as run_experiment
from tlm.report.collect import Inputs, Run, read
from tlm.report.images import images_section, scene_title
from tlm.report.tables import tables_section, thesis_table
from tlm.scenes.loader import scenes_dir

TINY = {"seed": 0, "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1}, "arch": {"trace": False},
        "mode": "rcast"}
POWER = "power: [1100000.0, 950000.0, 750000.0]"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Runs of a byte copy of the thesis's cornell.yaml (box.yaml), of a user's room.yaml (the Cornell
    box renamed room) and of a user's edited scenes/cornell.yaml."""
    root = tmp_path_factory.mktemp("h452")
    thesis = (scenes_dir() / "cornell.yaml").read_text(encoding="utf-8")
    assert "\nname: cornell\n" in thesis and POWER in thesis
    files = {"copy": root / "elsewhere" / "box.yaml", "user": root / "proj" / "room.yaml",
             "edited": root / "proj" / "scenes" / "cornell.yaml"}
    texts = {"copy": thesis, "user": thesis.replace("\nname: cornell\n", "\nname: room\n"),
             "edited": thesis.replace(POWER, "power: [2e6, 2e6, 2e6]")}
    out = {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        for key, path in files.items():
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(texts[key], encoding="utf-8")
            run_experiment(config_from_dict({**TINY, "scene": str(path)}, "test"), root / key)
            (out[key],) = read([root / key]).runs
    return out


def _image_title(run: Run, out) -> str:
    out.mkdir()
    (figure,) = images_section(Inputs([], runs=[run]), out).figures
    return figure.title


def test_a_byte_copy_of_a_thesis_scene_is_titled_as_the_table_it_is_in(runs, tmp_path):
    run = runs["copy"]
    assert thesis_table(run) == "cornell"
    tables = tables_section(Inputs([], runs=[run]), tmp_path)
    assert not tables.absent and "Table III. Cornell Box scene" in tables.html
    title = scene_title(run)
    assert title.endswith(": Cornell Box scene (Fig. 17)") and "not the thesis's" not in title, title
    assert _image_title(run, tmp_path / "i").startswith(f"{title}: image set by mode")


def test_a_scene_read_elsewhere_by_the_place_of_a_thesis_scene_is_not_titled_as_one(runs, tmp_path):
    run = runs["edited"]
    moved = Run(run.path, run.label, run.kind,
                {**run.results, "scene": {**run.results["scene"], "source": "/gone/proj/scenes/cornell.yaml"}}, {})
    assert moved.scene_label == "cornell"  # (labelled by its place under a scenes folder)
    assert thesis_table(moved) is None  # (its recorded digest is not the thesis's: h391)
    assert tables_section(Inputs([], runs=[moved]), tmp_path / "t").absent
    assert scene_title(moved) == "cornell, not the thesis's Cornell Box scene (Fig. 17)"


def test_a_users_scene_named_room_is_in_no_table_and_not_titled_as_one_and_the_tables_say_why(runs, tmp_path):
    run = runs["user"]
    assert run.scene == "room" and thesis_table(run) is None
    assert scene_title(run).endswith(", not the thesis's Room scene (Fig. 16)")
    assert "not the thesis's Room scene (Fig. 16)" in _image_title(run, tmp_path / "i")
    tables = tables_section(Inputs([], runs=[run]), tmp_path / "t")
    assert tables.absent == ("no run or thesis study among the inputs has simulated cycles of a thesis scene file "
                             "(thesis/ring, thesis/room or cornell, or a byte copy of one; a scene of any other "
                             "file is not one, even one "
                             "named ring, room or cornell)")
    assert any("scene 'room' has no table in the thesis (" in n for n in tables.notes), tables.notes
