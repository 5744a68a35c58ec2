"""A ``--set`` of a photon-map key in a run whose photon-map pass is left out says so (the
config file's own photon sections stay silent: a config may hold them for ``--mode pmap``)."""

from __future__ import annotations

import json
from types import SimpleNamespace

from tlm.cli import main
from tlm.experiments.run_warnings import unread_overrides

SMALL = ["--set", "resolution=[16,16]", "--set", "arch.packet_size=16", "--set", "arch.frames=2",
         "--no-report", "--no-progress", "--outputs", "images"]


def test_a_photon_key_set_for_a_run_without_the_photon_map_pass_warns(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["run", "configs/cornell.yaml", "--out", str(out), *SMALL, "--mode", "refract",
                 "--set", "photons.count=5000", "--set", "estimate.filter=disk",
                 "--set", "reference.photons=3000"]) == 0
    warnings = json.loads((out / "results.json").read_text())["warnings"]
    err = capsys.readouterr().err
    for item in ("photons.count=5000", "estimate.filter=disk", "reference.photons=3000"):
        line = (f"--set {item} has no effect in this run: the photon-map pass is left out (mode 'refract' does "
                "not include the pmap (photon-map) pass)")
        assert line in warnings
        assert line in err
    assert not [w for w in warnings if w.startswith(("--set arch.", "--set resolution"))]


def test_the_same_keys_in_a_photon_map_run_do_not():
    res = SimpleNamespace(plan=SimpleNamespace(run_names=["rcast", "pmap"], passes=[]))
    assert unread_overrides(res, ["photons.count=2000", "estimate.k=4"]) == []
    left_out = SimpleNamespace(name="pmap", run=False, reason="why", by=None)
    res = SimpleNamespace(plan=SimpleNamespace(run_names=["rcast"], passes=[left_out]))
    assert unread_overrides(res, [" estimate.k = 4", "bsp.levels=7"]) == [
        "--set estimate.k = 4 has no effect in this run: the photon-map pass is left out (why)"]
