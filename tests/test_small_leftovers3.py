"""Small leftovers: error-vs-cost says it computes a reference none cached and refuses a base mode it
would not run; 'tlm config export' does not point a copy at the user's own file; a scene not found is
named as given; the oracle's install hint works in an installed copy; a sweep finding says a tie."""

from __future__ import annotations

import itertools
import json
import sys
import tomllib
from pathlib import Path

import pytest

import tlm.api
import tlm.builtin
from tests.helpers_packaged import installed_configs, one_error
from tlm.cli import main
from tlm.errors import InputError
from tlm.report.collect import Inputs, Study, Sweep
from tlm.report.summary import sweep_findings

from .scenes import sphere_scene

REPO = Path(__file__).resolve().parents[1]
# a reference of two rounds over 800 photons: quick, and not converged
SHORT = {"photons": 800, "k_nearest": 20, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 2, "spp": 1}


_one_error = one_error


def _study(tmp_path: Path, **base) -> Path:
    sphere_scene(tmp_path, n_seg=8, n_rings=4)
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({
        "base": {"scene": "furnace.yaml", "resolution": [8, 8], "reference": SHORT, "photons": {"count": 800},
                 "estimate": {"final_gather": 0}, **base},
        "points": [{"estimate.filter": ["disk"]}],
    }))
    return exp


# ---------------------------------------------------------------- error-vs-cost


def test_error_vs_cost_says_it_computes_a_reference_none_cached_before_it_does(tmp_path, cache, capsys,
                                                                               monkeypatch):
    """It computed a reference (minutes at the default settings) saying nothing; 'tlm run' says so."""
    import tlm.experiments.error_cost as ec

    said = []
    compute = ec.compute_reference

    def computed(*args, **kwargs):
        said.append(capsys.readouterr().out)  # (what was printed before the rounds started)
        return compute(*args, **kwargs)

    monkeypatch.setattr(ec, "compute_reference", computed)
    out = tmp_path / "out"
    assert main(["error-vs-cost", str(_study(tmp_path)), "--out", str(out), "--truth-spp", "0", "--no-report"]) == 0
    (before,) = said
    key = json.loads((out / "reference.json").read_text())["key"]
    assert (f"error-vs-cost: computing the photon-map reference {key} (no finished one cached): 800 photons and "
            "k = 20 per round, until the relative standard error is below 1e-06 (at most 2 rounds)") in before
    assert main(["error-vs-cost", str(_study(tmp_path)), "--out", str(out), "--truth-spp", "0", "--no-report"]) == 0
    assert "computing" not in capsys.readouterr().out  # (cached now: nothing computed, nothing said)
    assert len(said) == 1


@pytest.mark.parametrize("mode", ["rcast", "refract"])
def test_error_vs_cost_refuses_a_base_mode_it_would_not_run(tmp_path, cache, capsys, mode):
    """A base's mode: rcast became mode: pmap unsaid; mode: pmap, or none, is the study's."""
    out = tmp_path / "out"
    assert main(["error-vs-cost", str(_study(tmp_path, mode=mode)), "--out", str(out), "--truth-spp", "0",
                 "--no-report"]) == 2
    line = _one_error(capsys)
    assert f"evc.yaml: base.mode: '{mode}': error-vs-cost measures the photon map" in line
    assert "give mode: pmap, or leave it out" in line
    assert not out.exists() and not cache.exists()  # (refused before any work)
    from tlm.experiments.error_cost import load_experiment

    base, _, _ = load_experiment(_study(tmp_path, mode="pmap"))
    assert base["mode"] == "pmap"
    with pytest.raises(InputError, match=r"a point cannot vary mode: every point is a photon-map frame \(mode: pmap; "
                                         "leave it out\\)$"):
        tlm.api.error_vs_cost(_edit_points(_study(tmp_path), [{"mode": ["pmap"]}]), out, truth_spp=0)


def _edit_points(exp: Path, points: list) -> Path:
    raw = json.loads(exp.read_text())
    exp.write_text(json.dumps({**raw, "points": points}))
    return exp


# ---------------------------------------------------------------- tlm config export


@pytest.fixture
def packaged(tmp_path, monkeypatch):
    return installed_configs(tmp_path, monkeypatch)


def test_config_export_does_not_point_a_sweep_at_the_users_own_base(packaged, capsys):
    """A ring.yaml of the user's own beside sr.yaml: the copy's base: ring.yaml would read it."""
    mine = "scene: cornell  # mine\n"
    Path("ring.yaml").write_text(mine)
    assert main(["config", "export", "scaling_ring", "sr.yaml"]) == 2
    line = _one_error(capsys)
    assert line.startswith("tlm: error: ring.yaml: exists with other contents: sr.yaml's base: ring.yaml would "
                           "read it in place of the built-in scaling_ring's base config: copy into another folder")
    assert not Path("sr.yaml").exists() and Path("ring.yaml").read_text() == mine
    # the sweep copied into the base's own name: the base would overwrite it (or it the base)
    Path("ring.yaml").unlink()
    with pytest.raises(InputError, match=r"^ring.yaml: is the name of the base config scaling_ring names"):
        tlm.builtin.export_experiment("scaling_ring", "ring.yaml")
    assert list(Path().iterdir()) == []
    # a base with the same contents is the one the copy needs: kept, and not said to be written
    assert tlm.builtin.export_experiment("scaling_ring", "sr.yaml") == [Path("sr.yaml"), Path("ring.yaml")]
    assert tlm.builtin.export_experiment("scaling_ring", "sr2.yaml") == [Path("sr2.yaml")]
    assert Path("ring.yaml").read_bytes() == (packaged / "ring.yaml").read_bytes()


# ---------------------------------------------------------------- tlm scene show|export NAME


def test_a_scene_not_found_is_named_as_given(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    for args in (["scene", "show", "nosuch"], ["scene", "export", "nosuch", "x.ply"]):
        assert main(args) == 2
        line = _one_error(capsys)
        assert line.startswith("tlm: error: nosuch: scene: 'nosuch' is not a built-in scene (") and "(load_scene)" \
            not in line
    assert main(["scene", "show", "no/such.yaml"]) == 2
    assert _one_error(capsys).startswith("tlm: error: no/such.yaml: scene: scene file 'no/such.yaml' not found")
    # a resolution given to load_scene is still this call's, not the scene file's
    with pytest.raises(InputError, match=r"^\(load_scene\): resolution: \[0, 5\]"):
        tlm.api.load_scene("cornell", resolution=[0, 5])
    assert tlm.api.load_scene("thesis/ring", resolution=[4, 3]).camera.width == 4


# ---------------------------------------------------------------- the oracle's install hint


def test_the_oracle_install_hint_works_in_an_installed_copy(monkeypatch):
    """'pip install -e ".[oracle]"' works in a checkout only: the packages are named too, as the extra has them."""
    import tlm.oracle.mitsuba as om
    from tlm.report.tradeoff import evc_truth_figure

    extra = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["optional-dependencies"]["oracle"]
    named = " ".join(f'"{p}"' for p in extra)
    monkeypatch.setitem(sys.modules, "mitsuba", None)  # `import mitsuba` now raises ImportError
    with pytest.raises(InputError) as e:
        om.require()
    assert f"(pip install {named}; in a checkout: pip install -e \".[oracle]\")" in str(e.value)
    notes: list[str] = []
    assert evc_truth_figure(Study("error-vs-cost", Path("evc"), [{"rmse": 0.1, "truth_rmse": None}]), Path("."),
                            "x.png", notes) is None
    (note,) = notes
    assert f"pip install {named}; in a checkout" in note


# ---------------------------------------------------------------- the report's sweep finding


def _sweep(grid: dict, fps) -> Sweep:
    keys = list(grid)
    rows = [{"status": "ok", **dict(zip(keys, combo, strict=True)), "fps": fps(*combo)}
            for combo in itertools.product(*grid.values())]
    return Sweep(Path("sw"), {"grid": grid}, rows, [])


def test_a_sweep_finding_says_a_tie_and_agrees_with_itself():
    """N = 2 and 4 tie: it named one of them the best value (which one: a set's order) and the other
    the best point."""
    fps = {1: 1400.5929176684797, 2: 1586.6341935535054, 4: 1586.6341935535054}
    (text,) = sweep_findings(Inputs([], sweeps=[_sweep({"arch.pipelines": [1, 2, 4]}, fps.get)]))
    assert text == ("<b>Sweep sw</b> (3 of 3 points ok): arch.pipelines moves the frame rate most, 1.13x between its "
                    "best values (2 and 4, tied) and its worst (1), averaged over the other factors; the best points, "
                    "tied at 1,590 FPS, are arch.pipelines = 2 and arch.pipelines = 4.")
    # two factors: 3 and 4 tie for the best value; six points tie at the best frame rate, four of them named
    (text,) = sweep_findings(Inputs([], sweeps=[_sweep({"a": [1, 2, 3, 4], "b": [8, 16, 32, 64]},
                                                       lambda a, b: 10.0 * min(a, 3) * (1 + (b > 8)))]))
    assert ("a moves the frame rate most, 3.00x between its best values (3 and 4, tied) and its worst (1), averaged "
            "over the other factors; ") in text
    assert text.endswith("the best points, tied at 60 FPS, are (a = 3, b = 16), (a = 3, b = 32), (a = 3, b = 64), "
                         "(a = 4, b = 16) and 2 more.")
