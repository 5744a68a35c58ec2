"""The one study runner (:mod:`tlm.experiments.study`): the study file's frame and its
one-line errors, and the output folder every study writes the same way, whole or not at all."""

from __future__ import annotations

import csv
import json

import pytest
import yaml

from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.experiments.study import read_study, run_study


def test_read_study_returns_the_file_its_base_and_its_name(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text("description: d\nbase: {scene: ring}\npipelines: [1, 2]\n")
    raw, base, src = read_study(path, ("pipelines",))
    assert raw == {"description": "d", "base": {"scene": "ring"}, "pipelines": [1, 2]}
    assert base == {"scene": "ring"} and src == str(path)
    path.write_text("pipelines: [1]\n")
    assert read_study(path, ("pipelines",))[1] == {}  # no base: the defaults


@pytest.mark.parametrize("text, says", [
    ("[1, 2]\n", "must be a mapping with base, pipelines"),
    ("base: {}\npipeline: [1]\n", "pipeline: unknown key (expected base, pipelines, description)"),
    ("base: [1]\n", "base: must be a run config mapping"),
])
def test_read_study_rejects_a_bad_frame_in_one_line(tmp_path, text, says):
    path = tmp_path / "s.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as e:
        read_study(path, ("pipelines",))
    assert str(e.value) == f"{path}: {says}"
    with pytest.raises(InputError, match="file not found"):
        read_study(tmp_path / "none.yaml", ())


def test_run_study_writes_rows_config_files_and_provenance(tmp_path):
    out = tmp_path / "out"
    seen, folders = [], []

    def run_point(p, folder):
        folders.append(folder)
        (folder / f"point{p}.txt").write_text(str(p))  # a point's own file lands in the output
        return None if p == 0 else {"p": p} if p == 1 else [{"p": p, "half": 0}, {"p": p, "half": 1}]

    def finish(rows, folder):
        return [{**r, "share": r["p"] / sum(x["p"] for x in rows)} for r in rows]

    rows = run_study("studies/s.yaml", out, "points", [0, 1, 2], run_point, columns=("share",),
                     config=config_from_dict({"scene": "ring"}), finish=finish, progress=seen.append,
                     files=lambda rows: {"n.json": {"n": len(rows)}, "n.yaml": {"n": len(rows)}, "n.txt": "three"})
    assert [r["p"] for r in rows] == [1, 2, 2] and seen == [{"p": 1}, {"p": 2, "half": 0}, {"p": 2, "half": 1}]
    assert rows[0]["share"] == 0.2 and folders[0] != out  # the points ran in a temporary folder
    assert [json.loads(ln) for ln in (out / "points.jsonl").read_text().splitlines()] == rows
    with open(out / "points.csv", newline="") as f:
        table = list(csv.reader(f))
    assert table[0] == ["share", "p", "half"] and len(table) == 4
    assert yaml.safe_load((out / "config.resolved.yaml").read_text())["scene"] == "ring"
    assert json.loads((out / "n.json").read_text()) == {"n": 3}
    assert yaml.safe_load((out / "n.yaml").read_text()) == {"n": 3}
    assert (out / "n.txt").read_text() == "three" and (out / "point2.txt").read_text() == "2"
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["study"] == "studies/s.yaml" and prov["host_seconds"] >= 0 and "versions" in prov
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no temporary folder left


def test_run_study_is_all_or_nothing(tmp_path):
    """A point that fails leaves no output folder; a destination that is not an earlier
    output of the study is refused before any point runs; an earlier one is replaced."""
    out = tmp_path / "out"

    def boom(p, folder):
        if p == 1:
            raise RuntimeError("point 1 failed")
        return {"p": p}

    with pytest.raises(RuntimeError, match="point 1 failed"):
        run_study(None, out, "points", [0, 1], boom)
    assert list(tmp_path.iterdir()) == []
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    ran = []
    with pytest.raises(InputError, match="not an earlier tlm output"):
        run_study(None, out, "points", [0], lambda p, f: ran.append(p))
    assert ran == [] and (out / "mine.txt").read_text() == "keep"
    (out / "mine.txt").unlink()
    run_study(None, out, "points", [5], lambda p, f: {"p": p})
    run_study(None, out, "points", [6], lambda p, f: {"p": p})  # its own earlier output: replaced
    assert (out / "points.jsonl").read_text() == '{"p": 6}\n' and "config.resolved.yaml" not in {
        p.name for p in out.iterdir()}
