"""A run's warnings say each key once, named as it was given, and the same lines reach a render's
``warnings``, ``tlm.run``'s result, ``results.json`` and ``tlm run``'s stderr
(tlm.experiments.run_warnings.run_warnings): an override of a photon-map key in a run whose photon-map
pass is left out is warned of for that (not also for what it would do were the pass run),
``--set`` on the command line and ``(in the overrides)`` through the API; a photon-map
reference that is not converged is warned of as ``tlm run``'s error line says it; and a
render's repr says whether it holds a timing, not whether it was simulated."""

from __future__ import annotations

import json

import tlm
from tlm.cli import main
from tlm.experiments import run as runs
from tlm.experiments import run_warnings
from tlm.experiments.reference_cache import rounds_advice

SMALL = {"mode": "rcast", "resolution": [16, 16], "render.spp": 1, "render.light_samples": 1,
         "arch.packet_size": 16, "arch.frames": 2}
GIVEN = {"photons.count": 1000, "estimate.k": 9}
LEFT_OUT = "has no effect in this run: the photon-map pass is left out (mode 'rcast' does not include the pmap"
# (a reference far from its tolerance after the fewest rounds: computed in well under a second)
UNCONVERGED = {"mode": "pmap", "resolution": [8, 8], "render.spp": 1, "render.light_samples": 1,
               "photons.count": 2000, "reference.photons": 2000, "reference.k_nearest": 20, "reference.spp": 1,
               "reference.max_rounds": 4, "reference.tolerance": 1e-6, "arch.packet_size": 16, "arch.frames": 2}


def _about(lines: list[str], key: str) -> list[str]:
    return [w for w in lines if w.startswith((key, f"--set {key}"))]


def test_an_unread_override_is_warned_of_once_as_it_was_given(tmp_path, cache):
    cfg = tlm.load_config("cornell", {**SMALL, **GIVEN})
    results = tlm.run(cfg, tmp_path / "r", outputs="images")
    warnings = results["warnings"]
    assert json.loads((tmp_path / "r" / "results.json").read_text())["warnings"] == warnings
    for key, value in GIVEN.items():  # (was: estimate.k twice, under two reasons, and '--set' for a mapping)
        assert _about(warnings, key) == [f"{key}={value} (in the overrides) {LEFT_OUT} (photon-map) pass)"], warnings
    assert not [w for w in warnings if "--set" in w]
    # a render of the same config says the same lines (but the simulated stream's, which need the timing)
    res = runs.render(cfg.settings, cfg.base, cfg.label, overrides=cfg.overrides, via=cfg.via)
    timing = runs.simulate_run(res, runs.programs_for(cfg.settings, cfg.base))
    stream = run_warnings.stream_warnings(timing, cfg.settings)
    assert res.warnings == [w for w in warnings if w not in stream]


def test_render_image_says_what_the_run_says(tmp_path, cache):
    cfg = tlm.load_config("cornell", {**SMALL, **GIVEN})
    results = tlm.run(cfg, tmp_path / "r", outputs="images")
    res = tlm.render_image(cfg)
    assert _about(res.warnings, "photons.count") == _about(results["warnings"], "photons.count")
    assert _about(res.warnings, "estimate.k") == _about(results["warnings"], "estimate.k")


def test_a_key_set_twice_or_by_its_section_is_named_once():
    cfg = tlm.load_config("cornell", {**SMALL, "estimate.k": 9, "estimate": {"k": 5, "cone_k": 2.0},
                                      "reference.photons": 300})
    res = runs.render(cfg.settings, cfg.base, cfg.label, overrides=cfg.overrides, via="--set")
    lines = [w for w in res.warnings if w.startswith(("--set", "estimate", "reference"))]
    assert lines == [f'--set estimate={{"k": 5, "cone_k": 2.0}} {LEFT_OUT} (photon-map) pass)',
                     f"--set reference.photons=300 {LEFT_OUT} (photon-map) pass)"]


def test_the_command_line_names_each_key_once_by_set(tmp_path, capsys, cache):
    out = tmp_path / "o"
    assert main(["run", "cornell", "--mode", "rcast", "--set", "photons.count=1000", "--set", "estimate.k=9",
                 "--set", "resolution=[16,16]", "--set", "arch.packet_size=16", "--set", "arch.frames=2",
                 "--out", str(out), "--no-report", "--no-progress", "--outputs", "images"]) == 0
    err = [line.removeprefix("tlm: warning: ") for line in capsys.readouterr().err.splitlines()
           if line.startswith("tlm: warning: ")]
    assert err == json.loads((out / "results.json").read_text())["warnings"]
    for key, value in GIVEN.items():
        assert _about(err, key) == [f"--set {key}={value} {LEFT_OUT} (photon-map) pass)"], err


def test_a_reference_not_converged_is_a_warning(tmp_path, capsys, cache):
    cfg = tlm.load_config("cornell", UNCONVERGED)
    results = tlm.run(cfg, tmp_path / "r", outputs="images")  # (reference.auto: computed, 4 rounds, cached)
    error = results["error"]
    assert error["available"] and error["reference_converged"] is False and error["reference_rounds"] == 4
    line = (f"the photon-map reference {error['reference']} is NOT converged (4 rounds, relative standard error "
            f"{error['reference_standard_error']:.4f}, reference.tolerance 1e-06): the pmap error against it "
            "(error.rmse, error.rel_mse) includes its noise; raise reference.max_rounds"
            f"{rounds_advice(error['reference_standard_error'], 4, cfg.settings.reference)} and compute it again with "
            "'tlm reference'")  # (h473: the rounds that would reach the tolerance)
    assert [w for w in results["warnings"] if "NOT converged" in w] == [line]
    assert json.loads((tmp_path / "r" / "results.json").read_text())["warnings"] == results["warnings"]
    res = runs.render(cfg.settings, cfg.base, cfg.label)  # (the cached reference now)
    assert [w for w in res.warnings if "NOT converged" in w] == [line]
    assert main(["run", "cornell", *[f"--set={k}={json.dumps(v)}" for k, v in UNCONVERGED.items()],
                 "--out", str(tmp_path / "c"), "--no-report", "--no-progress", "--outputs", "images"]) == 0
    captured = capsys.readouterr()
    assert "NOT converged" in captured.out  # (the error line, as before)
    assert f"tlm: warning: {line}" in captured.err.splitlines()
    # a converged one says nothing
    assert run_warnings.reference_warnings({**error, "reference_converged": True}, cfg.settings) == []


def test_a_render_repr_says_what_it_holds_not_whether_it_was_simulated(cache):
    res = tlm.render_image(tlm.load_config("cornell", SMALL))
    timing = tlm.simulate(res)  # (returns the timing; the render is left as it is)
    assert res.timing is None and timing.cycles["throughput"] > 0
    last = repr(res).splitlines()[-1].strip()
    assert "not simulated" not in last
    assert last == "timing: not in this result: tlm.simulate(result) returns it (cycles, frames per second)"
