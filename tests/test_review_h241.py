"""Review of the report's honesty and the sweep report on several pipelines (h241): a factor that takes a PM's
cycles from none to some does not "change nothing"; two scene files of one name outside the working folder are
named by their paths, not by digests; the sweep's ``tlm reference`` command names no base file other than the
one the sweep read (a report made from another folder, a base edited since); ``tlm plots`` takes a scaling
folder without a sweep in it (an interrupted or emptied one) as absent, and says so."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tlm.errors import InputError
from tlm.experiments.scaling import groups
from tlm.report.collect import Inputs, Run, Sweep
from tlm.report.regenerate import regenerate
from tlm.report.summary import sweep_findings
from tlm.report.summary_points import PMS, points_error

# ---------------------------------------------------------------- "changes nothing": a count from 0 moves


def test_a_factor_that_takes_a_pm_from_no_cycles_to_some_does_not_change_nothing():
    rows = [{"point": i, "hash": f"h{i}", "status": "ok", "render.shadows": s, "fps": 414.4,
             "cycles.vertex": 1447829, "cycles.traversal": 436535, "cycles.intersection": 0 if not s else 5072,
             "cycles.fragment": 75844, "cycles.throughput": 1447829, "cycles.latency": 2895658}
            for i, s in enumerate((False, True))]
    (text,) = sweep_findings(Inputs([], sweeps=[Sweep(Path("sw"), {"grid": {"render.shadows": [False, True]}},
                                                      rows, [])]))
    assert "changes nothing" not in text
    assert "render.shadows keeps the frame rate between points that differ only in it, but moves Tisct" in text
    assert "from none in some points" in text


# ---------------------------------------------------------------- two files of one name: their paths


def test_two_scene_files_of_one_name_outside_the_working_folder_are_named_by_their_paths(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    recs = [{"scene": "room", "scene_file": f, "scene_ref": f, "scene_id": i, "mode": "rcast", "scheduler": "static"}
            for f, i in (("/x/a/room.yaml", "sha256 aaaa"), ("/x/b/room.yaml", "sha256 bbbb"))]
    assert sorted(k[0] for k in groups(recs)) == ["/x/a/room.yaml", "/x/b/room.yaml"]
    # (one file given by two paths that are one string: the digests still tell two contents apart)
    same = [{**r, "scene_ref": "/x/a/room.yaml", "scene_file": "/x/a/room.yaml"} for r in recs]
    assert sorted(k[0] for k in groups(same)) == ["room.yaml [sha256 aaaa]", "room.yaml [sha256 bbbb]"]
    # (a name under the working folder and one outside it: each as given)
    mine = {**recs[0], "scene_file": str(tmp_path / "room.yaml"), "scene_ref": "room.yaml"}
    assert sorted(k[0] for k in groups([mine, recs[1]])) == ["/x/b/room.yaml", "room.yaml"]


# ---------------------------------------------------------------- the sweep's reference command


def _unmeasured(out: Path, project: Path, spec: dict) -> str:
    run = Run(out / "points" / "h0", "sw #0", "sweep-point",
              {"scene": {"name": "myroom"}, "mode": "pmap", "error": {"available": False, "reference": "ref0"}},
              {"scene": str(project / "myroom.yaml"), "mode": "pmap"}, factors={"arch.pipelines": 1})
    rows = [{"point": 0, "hash": "h0", "status": "ok", "arch.pipelines": 1}]
    said = points_error(Inputs([], runs=[run], sweeps=[Sweep(out, spec, rows, [run])]))
    return said[said.index("<code>") + 6:said.index("</code>")]


def test_the_reference_command_names_the_points_config_where_the_base_is_not_the_sweeps(tmp_path, monkeypatch):
    project = tmp_path / "proj"
    project.mkdir()
    (tmp_path / "else").mkdir()
    (project / "room.yaml").write_text("scene: myroom.yaml\nmode: pmap\n")
    out = project / "runs" / "sw"
    resolved = str(out / "points" / "h0" / "config.resolved.yaml")
    spec = {"sweep": "sw.yaml", "base_file": "room.yaml", "base": {"scene": "myroom.yaml", "mode": "pmap"},
            "set": {}, "grid": {"arch.pipelines": [1]}}
    monkeypatch.chdir(project)  # (as the sweep ran: its base from here)
    assert _unmeasured(out, project, spec) == "tlm reference room.yaml"
    monkeypatch.chdir(tmp_path / "else")  # (the report made from another folder: room.yaml names nothing here)
    assert _unmeasured(out, project, spec) == f"tlm reference {resolved}"
    (tmp_path / "else" / "room.yaml").write_text("scene: cornell\nmode: pmap\n")  # (another file of that name)
    assert _unmeasured(out, project, spec) == f"tlm reference {resolved}"
    monkeypatch.chdir(project)
    (project / "room.yaml").write_text("scene: myroom.yaml\nmode: pmap\nresolution: [8, 8]\n")  # (edited since)
    assert _unmeasured(out, project, spec) == f"tlm reference {resolved}"


# ---------------------------------------------------------------- tlm plots: a scaling folder without a sweep

SPEC = {"sweep": "x.yaml", "grid": {"arch.scheduler": ["static", "dynamic"], "arch.pipelines": [1, 2, 4]}}


def _stub(called: list):
    def run_command(argv: list[str]) -> int:
        called.append(argv)
        if argv[0] == "sweep":
            folder = Path(argv[argv.index("--out") + 1])
            folder.mkdir(parents=True, exist_ok=True)
            (folder / "sweep.yaml").write_text(yaml.safe_dump(SPEC))
            rows = [{"point": i, "hash": f"h{i}", "status": "ok", "arch.scheduler": s, "arch.pipelines": n,
                     "scene": "cornell", "mode": "rcast", "cycles.throughput": 1000 // n, "fps": 1e8 / (1000 // n),
                     **{f"idle.{pm}": 0.1 for pm in PMS}}
                    for i, (s, n) in enumerate((s, n) for s in ("static", "dynamic") for n in (1, 2, 4))]
            (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
        return 0
    return run_command


def test_a_scaling_folder_without_a_sweep_is_absent_and_said(tmp_path):
    (tmp_path / "configs").mkdir()
    runs = tmp_path / "runs"
    (runs / "scaling_cornell").mkdir(parents=True)  # (a sweep interrupted before its first row, or emptied)
    called, said = [], []
    page = regenerate(tmp_path / "configs", runs, tmp_path / "plots", ["scaling_ring"], run_command=_stub(called),
                      say=said.append)
    assert page.is_file()
    assert any(f"{runs / 'scaling_cornell'} left out: no sweep in it" in s for s in said)
    called.clear()
    regenerate(tmp_path / "configs", runs, tmp_path / "plots", ["scaling_ring", "eq52"], run_command=_stub(called),
               say=said.append)
    eq52 = next(a for a in called if a[0] == "scaling")
    assert eq52[1:eq52.index("--out")] == [str(runs / "scaling_ring")]
    assert any("eq52: fits scaling_ring alone: no folder scaling_room; no sweep in scaling_cornell" in s for s in said)


def test_eq52_with_only_empty_scaling_folders_is_refused_before_any_step(tmp_path):
    (tmp_path / "configs").mkdir()
    runs = tmp_path / "runs"
    for name in ("scaling_ring", "scaling_room", "scaling_cornell"):
        (runs / name).mkdir(parents=True)
    called: list = []
    with pytest.raises(InputError, match=r"no sweep in scaling_ring, scaling_room, scaling_cornell \(no sweep.jsonl\)"):
        regenerate(tmp_path / "configs", runs, tmp_path / "plots", ["thesis", "eq52"], run_command=_stub(called),
                   say=lambda _: None)
    assert called == []
