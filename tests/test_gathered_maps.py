"""One rule says which photon maps a frame gathers (:func:`tlm.render.pmap.gathered_maps`):
the photon-map pass gathers exactly those, and ``tlm error-vs-cost`` times the leaf order of
exactly those with a row's trace. The answers below are those of the rule ``error_cost`` kept
a copy of before (its ``gathered_maps``), run on each case."""

from __future__ import annotations

import json

import numpy as np
import pytest

import tlm.experiments.error_cost as ec
from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments.run import render
from tlm.kernels.photons import PhotonMap
from tlm.kernels.traverse import build_accel
from tlm.render import pmap
from tlm.render.frame import Frame, cast
from tlm.render.pmap import gathered_maps, pmap_pass, trace_photon_map
from tlm.scenes.loader import load_scene

from .scenes import sphere_scene

FG = {"estimate.final_gather": 4}
NO_CAUSTIC_GROUP = {"photons.caustic_fraction": 0.0}
# case -> (the frame's settings, the trace's settings, the maps gathered, in order); the trace's
# settings are the frame's where the two are the same (a scene of "furnace": the diffuse sphere)
CASES = {
    "caustics, no final gathering": ({}, None, ["caustic", "indirect"]),
    "caustics, final gathering": (FG, None, ["caustic", "global"]),
    # (the global group's photons still reach the mirror and the glass: the caustic map is not empty)
    "no caustic group, no final gathering": (NO_CAUSTIC_GROUP, None, ["caustic", "indirect"]),
    "no caustic group, final gathering": ({**NO_CAUSTIC_GROUP, **FG}, None, ["caustic", "global"]),
    "caustic count 0, final gathering": ({"photons.caustic_count": 0, **FG}, None, ["caustic", "global"]),
    "density rule, no final gathering": ({"estimate.radius_fraction": None, "estimate.caustic_radius_fraction": None},
                                         {}, ["caustic", "indirect"]),
    "density rule, final gathering": ({"estimate.radius_fraction": None, **FG}, FG, ["caustic", "global"]),
    "fixed radius, final gathering": ({"estimate.radius": 30.0, **FG}, FG, ["caustic", "global"]),
    "aim box, no final gathering": ({"photons.aim": "box"}, None, ["caustic", "indirect"]),
    "aim box, final gathering": ({"photons.aim": "box", **FG}, None, ["caustic", "global"]),
    "mode rcast, no final gathering": ({"mode": "rcast"}, {}, ["caustic", "indirect"]),
    "mode rcast, final gathering": ({"mode": "rcast", **FG}, FG, ["caustic", "global"]),
    # a trace with a global map, a frame without final gathering, and the other way round
    "global map traced, no final gathering": ({}, FG, ["caustic", "indirect"]),
    "no global map traced, final gathering": (FG, {}, ["caustic", "indirect"]),
    # no mirror or glass: an empty caustic map is never gathered
    "diffuse scene, no final gathering": ({"scene": "furnace"}, None, ["indirect"]),
    "diffuse scene, final gathering": ({"scene": "furnace", **FG}, None, ["global"]),
    # the caustic group alone: the indirect and global maps are empty
    "caustic group alone, no final gathering": ({}, {"photons.count": 0, "photons.caustic_count": 300}, ["caustic"]),
    "caustic group alone, final gathering": (FG, {"photons.count": 0, "photons.caustic_count": 300, **FG},
                                             ["caustic"]),
    "no photons, no final gathering": ({}, {"photons.count": 0}, []),
    "no photons, final gathering": (FG, {"photons.count": 0, **FG}, []),
}


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    furnace = str(sphere_scene(tmp_path_factory.mktemp("gathered"), n_seg=8, n_rings=4))
    out = {}
    for name, path in (("cornell", "cornell"), ("furnace", furnace)):
        cfg = config_from_dict({"scene": path})
        scene = load_scene(cfg.scene, resolution=[16, 16])
        out[name] = (path, scene, build_accel(scene.triangles))
    return out


@pytest.fixture(scope="module")
def traces():
    return {}


def _frame(scenes, settings: dict) -> Frame:
    settings = dict(settings)
    path, scene, accel = scenes[settings.pop("scene", "cornell")]
    d = {"scene": path, "mode": settings.pop("mode", "pmap"), "resolution": [16, 16], "render": {"spp": 1},
         "photons": {"count": 600}, "estimate": {"final_gather": 0}}
    for key, value in settings.items():
        section, name = key.split(".")
        d.setdefault(section, {})[name] = value
    return Frame.create(scene, accel, config_from_dict(d))


def _case(scenes, traces, case: str):
    """The case's frame, its photon maps (traced once per trace setting) and the names gathered."""
    settings, traced_by, expected = CASES[case]
    traced_by = settings if traced_by is None else {**traced_by, **({"scene": settings["scene"]}
                                                                    if "scene" in settings else {})}
    key = json.dumps(traced_by, sort_keys=True)
    if key not in traces:
        traces[key] = trace_photon_map(_frame(scenes, traced_by)).photons
    return _frame(scenes, settings), traces[key], expected


def _attribute(photons, name: str) -> PhotonMap:
    return {"caustic": photons.caustic_map, "indirect": photons.indirect_map, "global": photons.global_map}[name]


@pytest.mark.parametrize("case", list(CASES))
def test_the_rule_gives_the_old_copy_s_answers(scenes, traces, case):
    frame, photons, expected = _case(scenes, traces, case)
    found = gathered_maps(frame, photons)
    assert list(found) == expected
    for name, m in found.items():
        assert m is _attribute(photons, name)


def test_a_single_map_is_gathered_alone_unless_empty(scenes, traces):
    frame, photons, _ = _case(scenes, traces, "caustics, no final gathering")
    fg_frame, _, _ = _case(scenes, traces, "caustics, final gathering")
    empty = _case(scenes, traces, "no photons, no final gathering")[1].indirect_map
    assert gathered_maps(frame, photons.indirect_map) == {"photons": photons.indirect_map}
    assert gathered_maps(fg_frame, photons.indirect_map) == {"photons": photons.indirect_map}
    assert gathered_maps(frame, empty) == {}
    assert gathered_maps(frame, None) == {}


@pytest.mark.parametrize("case", list(CASES))
def test_the_photon_map_pass_gathers_the_rule_s_maps(scenes, traces, case):
    """pmap_pass's per-map tallies (what ``tlm run`` reports per map) name the rule's maps."""
    frame, photons, expected = _case(scenes, traces, case)
    g = cast(frame, np.arange(16 * 16))
    per_map: dict = {}
    pmap_pass(frame, g, photons, per_map=per_map)
    assert sorted(per_map) == sorted(expected)


def test_error_cost_asks_the_photon_map_s_rule():
    assert ec.gathered_maps is pmap.gathered_maps


def test_an_error_cost_row_and_a_render_agree_on_the_maps(tmp_path, cache, monkeypatch):
    """The maps a row's trace put in leaf order (timed with the trace) are those a render of
    the row's config gathers (its per-map tallies), with and without final gathering."""
    base = {"scene": "cornell", "seed": 0, "resolution": [16, 16], "render": {"spp": 1},
            "photons": {"count": 600},
            "reference": {"photons": 600, "k_nearest": 10, "tolerance": 0.9, "min_rounds": 2, "max_rounds": 2,
                          "spp": 1}}
    points = {"estimate.final_gather": [0, 4], "photons.caustic_fraction": [0.0, 0.5]}
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({"base": base, "points": [points]}))
    made: list[PhotonMap] = []  # the maps whose leaf order was made (held: no id is reused)
    prepared = PhotonMap.prepared

    def recording(self):
        made.append(self)
        return prepared(self)

    monkeypatch.setattr(PhotonMap, "prepared", recording)
    rows: dict[tuple, set] = {}
    real_pass = ec.pmap_pass

    def row_pass(frame, g, photons, *args, **kwargs):  # (the row's trace is done: what did it put in leaf order?)
        names = {n for n in ("caustic", "indirect", "global")
                 if any(m is _attribute(photons, n) for m in made if m is not None)}
        rows[(frame.cfg.estimate.final_gather, frame.cfg.photons.caustic_fraction)] = names
        return real_pass(frame, g, photons, *args, **kwargs)

    monkeypatch.setattr(ec, "pmap_pass", row_pass)
    assert main(["error-vs-cost", str(exp), "--out", str(tmp_path / "out"), "--truth-spp", "0", "--no-report"]) == 0
    assert set(rows) == {(fg, cf) for fg in (0, 4) for cf in (0.0, 0.5)}
    monkeypatch.setattr(PhotonMap, "prepared", prepared)
    for (fg, cf), names in rows.items():
        assert names == ({"caustic", "global"} if fg else {"caustic", "indirect"}), (fg, cf)
        cfg = config_from_dict({**base, "mode": "pmap", "estimate": {"final_gather": fg},
                                "photons": {"count": 600, "caustic_fraction": cf}})
        assert set(render(cfg).gather_maps) == names, (fg, cf)
