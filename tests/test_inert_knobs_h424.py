"""Keys that change nothing in some setups, now said (probe h421): the radius keys under the
k-nearest filter (``knn`` declares it uses no radius: :attr:`tlm.render.estimators.Estimator.uses_radius`),
``estimate.final_gather_photons`` with final gathering and a radius or fraction given (the global map's
radius is the given one), ``photons.caustic_fraction`` with ``photons.caustic_count`` set (a caustic budget
of its own), ``photons.leaf_photons`` with ``photons.levels`` set (the levels come first), and
``photons.aim_triangles`` with ``photons.aim: box`` (only ``parts`` aims at groups of triangles):
:func:`tlm.render.planner.inert_settings` names each, so a run warns of it and the frame key leaves it
out; and ``--set arch.trace=true`` with ``tlm run --outputs images``, which writes no ``trace.json``,
is warned of (:func:`tlm.experiments.run_warnings.trace_dropped`).

Each run is tiny (cornell, 16x16, 2000 photons) and is compared with the same base without the key:
the images, the work, the photons' work and the cycles are the same."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments.frames import functional_key
from tlm.render import estimators
from tlm.render.planner import RADIUS_SETTINGS, inert_changes, inert_settings

BASE = {"scene": "cornell", "mode": "pmap", "seed": 0, "resolution": [16, 16],
        "render": {"spp": 1, "light_samples": 1}, "photons": {"count": 2000},
        "estimate": {"final_gather": 0}, "reference": {"auto": False}, "arch": {"packet_size": 16}}


@pytest.fixture(scope="module")
def runner(tmp_path_factory):
    """``run(*sets, outputs="images")``: a ``tlm run`` of :data:`BASE` with the ``--set``s, its
    ``results.json`` and folder (each once for the module); the module's own ``$TLM_CACHE``."""
    root = tmp_path_factory.mktemp("h424")
    base = root / "base.yaml"
    base.write_text(yaml.safe_dump(BASE), encoding="utf-8")
    done: dict = {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))

        def run(*sets: str, outputs: str = "images") -> tuple[dict, Path]:
            if (sets, outputs) not in done:
                out = root / f"run{len(done)}"
                argv = ["run", str(base), "--out", str(out), "--outputs", outputs, "--no-progress", "--no-report"]
                for s in sets:
                    argv += ["--set", s]
                assert main(argv) == 0
                done[sets, outputs] = (json.loads((out / "results.json").read_text()), out)
            return done[sets, outputs]

        yield run


def same_results(a: tuple[dict, Path], b: tuple[dict, Path]) -> None:
    """The two runs rendered and timed alike: images, work, the photons' work and gathers, cycles."""
    (ra, fa), (rb, fb) = a, b

    def images(folder: Path) -> dict:
        return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted((folder / "images").glob("*.png"))}

    assert images(fa) == images(fb)
    assert ra["work"] == rb["work"]
    assert ra["cycles"] == rb["cycles"]
    for key in ("emitted", "stored", "caustic", "indirect", "work", "gather", "tree", "caustic_tree"):
        assert ra["photons"][key] == rb["photons"][key], key


def warned(results: dict, key: str) -> list[str]:
    return [w for w in results["warnings"] if w.startswith(f"{key} = ") and "has no effect in this run" in w]


CASES = [  # (the base's own sets, the key set, its value, words of the reason)
    (("estimate.filter=knn",), "estimate.radius", "50", "'knn'"),
    (("estimate.filter=knn",), "estimate.radius_fraction", "0.05", "'knn'"),
    (("estimate.filter=knn",), "estimate.radius_photons", "20", "'knn'"),
    (("estimate.filter=knn",), "estimate.caustic_radius", "20", "'knn'"),
    (("estimate.filter=knn",), "estimate.caustic_radius_photons", "30", "'knn'"),
    (("estimate.final_gather=4", "estimate.radius_fraction=0.05"), "estimate.final_gather_photons", "8",
     "estimate.radius_fraction is set"),
    (("estimate.final_gather=4", "estimate.radius=40"), "estimate.final_gather_photons", "8",
     "estimate.radius is set"),
    (("photons.caustic_count=500",), "photons.caustic_fraction", "0.2", "photons.caustic_count is set"),
    (("photons.levels=4",), "photons.leaf_photons", "32", "photons.levels is set"),
    (("photons.aim=box",), "photons.aim_triangles", "16", "photons.aim is 'box'"),
]


@pytest.mark.parametrize(("base", "key", "value", "why"), CASES, ids=[f"{c[1]}-{c[0][-1]}" for c in CASES])
def test_the_key_is_warned_of_and_changes_nothing(runner, base, key, value, why):
    plain = runner(*base)
    got = runner(*base, f"{key}={value}")
    lines = warned(got[0], key)
    assert len(lines) == 1 and why in lines[0], got[0]["warnings"]
    assert not warned(plain[0], key)
    same_results(plain, got)


def cfg(**sections) -> object:
    return config_from_dict({"scene": "cornell", "mode": "pmap", **sections})


def test_the_knn_rule_is_the_filters_declaration(monkeypatch):
    """Derived from ``uses_radius``: the k-nearest filter's radius keys (and final_gather_photons under
    final gathering) are named; a filter that declares no radius gets the rule too."""
    assert not estimators.KNearest.uses_radius
    knn = inert_settings(cfg(estimate={"filter": "knn", "final_gather": 4}))
    assert {*RADIUS_SETTINGS, "estimate.final_gather_photons"} <= set(knn)
    assert all("'knn'" in knn[k] for k in RADIUS_SETTINGS)
    disk = {"filter": "disk", "final_gather": 0}
    assert not set(RADIUS_SETTINGS) & set(inert_settings(cfg(estimate=disk)))
    monkeypatch.setattr(estimators.Disk, "uses_radius", False)
    assert "'disk'" in inert_settings(cfg(estimate=disk))["estimate.radius"]


def test_the_rules_stand_only_in_their_condition():
    for sections, key in (({"estimate": {"final_gather": 4}}, "estimate.final_gather_photons"),
                          ({}, "photons.caustic_fraction"), ({}, "photons.leaf_photons"),
                          ({"photons": {"aim": "parts"}}, "photons.aim_triangles")):
        assert key not in inert_settings(cfg(**sections)), key
    lines = inert_changes(cfg(photons={"levels": 4, "leaf_photons": 32}))
    assert [ln for ln in lines if ln.startswith("photons.leaf_photons = 32 has no effect in this run: ")], lines


def test_a_sweep_of_leaf_photons_with_levels_set_renders_one_frame():
    """The frame key leaves out what the run never reads: leaf_photons under photons.levels, caustic_fraction
    under caustic_count, aim_triangles under aim box, final_gather_photons under a given radius; not the knn
    radius keys either (results.json records no radius under knn: tlm.render.pmap.radii)."""
    def key(**sections) -> str:
        return functional_key(cfg(**sections), "scene", "code")

    assert key(photons={"levels": 4, "leaf_photons": 8}) == key(photons={"levels": 4, "leaf_photons": 32})
    assert key(photons={"leaf_photons": 8}) != key(photons={"leaf_photons": 32})
    assert key(photons={"caustic_count": 500, "caustic_fraction": 0.2}) == key(photons={"caustic_count": 500})
    assert key(photons={"aim": "box", "aim_triangles": 16}) == key(photons={"aim": "box"})
    fg = {"final_gather": 4, "radius_fraction": 0.05}
    assert key(estimate={**fg, "final_gather_photons": 8}) == key(estimate=fg)
    assert key(estimate={"filter": "knn", "radius": 50.0}) == key(estimate={"filter": "knn"})


def test_a_knn_run_records_no_radius(runner):
    results = runner("estimate.filter=knn", "estimate.radius=50")[0]
    ph = results["photons"]
    assert ph["radius"] is None and ph["radius_rule"] is None and ph["caustic_radius"] is None, ph


def test_trace_asked_but_not_written_is_warned_of(runner):
    results, out = runner("arch.trace=true")
    assert not (out / "trace.json").exists()
    lines = [w for w in results["warnings"] if w.startswith("--set arch.trace=true is not kept")]
    assert len(lines) == 1 and "--outputs" in lines[0], results["warnings"]
    # not without the --set (the default arch.trace: --outputs images keeps no trace, as documented) ...
    assert not [w for w in runner()[0]["warnings"] if "arch.trace" in w]
    # ... nor where the outputs name trace (it is written), nor where the last --set turns it off
    results, out = runner("arch.trace=true", outputs="images,trace")
    assert (out / "trace.json").exists() and not [w for w in results["warnings"] if "arch.trace" in w]
    assert not [w for w in runner("arch.trace=true", "arch.trace=false")[0]["warnings"] if "arch.trace" in w]
