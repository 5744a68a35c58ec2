"""What a probe of the Python API (docs/api.md) found, mended.

``tlm.sweep`` returned its table without the sweep's warnings (``tlm sweep`` prints them): they are
its ``attrs["warnings"]`` now. ``tlm.export_scene`` wrote a Scene with a NaN vertex (a file no load
reads back) and ``tlm.scene_info`` reported NaN bounds: both refuse it as the loader refuses such a
file. ``tlm.reference`` said ``computed=True`` of a cached reference it only kept, called its
``progress`` after each cycle but the first (8 rounds: one call), and its lines said ``--force``.
Python errors named the command line's ``--set`` and ``--outputs``. ``tlm.plots`` printed by default
and raised a type the API did not export. A config's repr showed ``resolution=None`` for the scene's
own, and a typo of a setting named ``RunConfig``.
"""

from __future__ import annotations

import dataclasses
import inspect
import json
import math

import numpy as np
import pytest

import tlm
from tlm import api
from tlm.api_common import flags_kept

FAST = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1},
        "arch": {"frames": 1, "trace": False}}
# 2 cycles of 2 rounds, far short of the tolerance: not converged, and kept when asked again
SHORT = {"photons": 500, "k_nearest": 20, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 4, "spp": 2}
PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "render": {"spp": 1}, "photons": {"count": 500},
        "reference": SHORT}


def test_a_sweep_s_warnings_are_its_table_s_attrs_and_go_to_warn(tmp_path, cache):
    path = tmp_path / "inert.yaml"
    path.write_text(json.dumps({"base": FAST, "grid": {"estimate.k": [4, 16]}}))
    heard: list[str] = []
    rows = tlm.sweep(path, tmp_path / "out", jobs=1, warn=heard.append)
    assert list(rows["status"]) == ["ok", "ok"]
    said = rows.attrs["warnings"]
    assert len(said) == 1 and "the factor estimate.k changes nothing in any point" in said[0]
    assert heard == said
    assert rows[["estimate.k"]].attrs["warnings"] == said  # (a selection keeps them)
    again = tlm.sweep(path, tmp_path / "out", jobs=1)  # (warn=None: returned, not printed; every point done)
    assert again.attrs["warnings"] == said


def _nan_scene(value: float = math.nan):
    scene = tlm.load_scene("cornell", resolution=[8, 8])
    tri = scene.triangles.copy()
    tri[5, 1, 2] = value
    return dataclasses.replace(scene, triangles=tri)


@pytest.mark.parametrize("value", [math.nan, math.inf])
def test_a_scene_of_a_nan_vertex_is_refused_before_anything_is_written(tmp_path, value):
    bad = _nan_scene(value)
    said = r"^scene 'cornell': triangles: 1 triangle\(s\) have NaN or infinite vertices \(first: triangle 5, "
    with pytest.raises(tlm.InputError, match=said):
        tlm.scene_info(bad)
    for name in ("box.yaml", "box.obj", "box.ply"):
        with pytest.raises(tlm.InputError, match=said):
            tlm.export_scene(bad, tmp_path / name)
    assert list(tmp_path.iterdir()) == []
    ok = tlm.load_scene("cornell", resolution=[8, 8])
    assert all(math.isfinite(x) for x in tlm.scene_info(ok)["bounds"]["min"])
    tlm.export_scene(ok, tmp_path / "box.ply")  # (a loaded scene passes)
    assert (tmp_path / "box.ply").is_file()


def test_a_reference_kept_from_the_cache_is_not_computed_now_and_its_line_names_force(cache):
    first = tlm.reference(PMAP)
    assert first.computed and not first.meets and first.meta["rounds"] == 4
    said: list[str] = []
    kept = tlm.reference(PMAP, say=said.append)  # (the same settings: computing would repeat the same rounds)
    same = ("rounds", "relative_standard_error", "standard_error_per_cycle")
    assert kept.computed is False and kept.kept and {k: kept.meta[k] for k in same} == {k: first.meta[k] for k in same}
    assert "force=True" in kept.kept and "--force" not in kept.kept
    assert said == [kept.kept]
    fewer = tlm.reference(api.load_config(PMAP, {"reference.max_rounds": 2}), say=said.append)
    assert fewer.computed is False and "asks for fewer rounds" in fewer.kept and "force=True" in fewer.kept
    with flags_kept():  # (tlm reference's own lines name its flag)
        assert "use --force" in tlm.reference(PMAP).kept


def test_progress_is_called_after_each_round_with_its_numbers_and_the_bits_are_the_same(cache):
    calls: list[tuple] = []
    made = tlm.reference(PMAP, progress=lambda *a: calls.append(a))
    meta = made.meta
    assert [c[0] for c in calls] == list(range(1, meta["rounds"] + 1))  # (4 rounds: 4 calls)
    measured = [c for c in calls if not math.isnan(c[2])]
    assert [c[0] for c in measured] == [4]  # (the second cycle's end: the first measure)
    assert measured[-1][1:] == (meta["final_change"], meta["relative_standard_error"])
    assert all(math.isnan(c[1]) and math.isnan(c[2]) for c in calls if c[0] != 4)
    again = tlm.reference(PMAP, force=True)  # (no progress: the same rounds, to the bit)
    assert again.meta["standard_error_per_cycle"] == meta["standard_error_per_cycle"]
    hint = inspect.signature(tlm.reference).parameters["progress"].annotation
    assert "bool" in str(hint) and "Callable" in str(hint)  # (True and False are taken)


def test_python_errors_name_the_arguments_not_the_flags():
    with pytest.raises(tlm.InputError, match=r"^overrides: 'render\.spp' is not of the form dotted\.key=value$"):
        tlm.load_config("cornell", ["render.spp"])
    with pytest.raises(tlm.InputError, match=r"^text: 'aov,xx': expected a comma-separated list"):
        tlm.parse_outputs("aov,xx")
    # a config's label stays as its overrides were given (strings: the command line's --set)
    with pytest.raises(tlm.InputError, match=r"cornell\.yaml, with --set: render\.spp: 0 must be >= 1"):
        tlm.load_config("cornell", ["render.spp=0"])
    with flags_kept():  # (the command line's command: its flags, as typed)
        with pytest.raises(tlm.InputError, match=r"^--set: 'render\.spp' is not of the form"):
            tlm.load_config("cornell", ["render.spp"])
        with pytest.raises(tlm.InputError, match=r"^--outputs: 'aov,xx'"):
            tlm.parse_outputs("aov,xx")


def test_plots_prints_nothing_unless_asked_and_its_error_type_is_the_api_s(tmp_path, capsys):
    from tlm.api import StepsFailed
    from tlm.errors import StepsFailed as raised

    assert StepsFailed is raised and "StepsFailed" in (api.plots.__doc__ or "")
    assert inspect.signature(tlm.plots).parameters["say"].default is None
    ran: list[list[str]] = []

    def step(argv: list[str]) -> int:
        ran.append(argv)
        return 0  # (writes nothing: the report then finds no step's folder)

    (tmp_path / "configs").mkdir()  # (a configs folder that is not there is refused before any step)
    with pytest.raises(tlm.InputError, match="no step's folder exists"):
        tlm.plots(tmp_path / "configs", tmp_path / "runs", tmp_path / "plots", ["thesis"], run_command=step)
    assert [a[0] for a in ran] == ["thesis"]
    assert capsys.readouterr().out == ""
    heard: list[str] = []
    with pytest.raises(tlm.InputError):
        tlm.plots(tmp_path / "configs", tmp_path / "runs", tmp_path / "plots", ["thesis"], run_command=step,
                  say=heard.append)
    assert heard and heard[0].startswith("== thesis: tlm thesis ")


def test_a_config_shows_the_resolution_it_renders_at_and_a_typo_names_config():
    assert "resolution=[320, 240] (the scene's), seed=0)" in repr(api.load_config({"scene": "ring"}))
    assert "resolution=[16, 16], seed=0)" in repr(api.load_config({"scene": "ring", "resolution": [16, 16]}))
    cfg = api.load_config({"scene": "ring"})
    assert cfg.resolution is None  # (the setting itself)
    with pytest.raises(AttributeError, match=r"^'Config' object has no attribute 'resolutoin' \(did you mean "
                                             r"'resolution'\?\)$"):
        cfg.resolutoin  # noqa: B018
    assert not hasattr(cfg, "nosuch") and cfg.render.spp >= 1
    np.testing.assert_equal(cfg.settings.resolution, None)
