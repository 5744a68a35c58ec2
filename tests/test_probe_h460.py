"""Probe of the session's features as a user runs them (h460)."""
from __future__ import annotations

import os
from pathlib import Path

from tlm import config_paths


def test_the_shadowed_scene_line_gives_the_whole_path_where_a_relative_one_climbs_to_the_root(tmp_path, monkeypatch):
    """``tlm run cornell`` from a folder holding a scene file ``cornell.yaml`` (the built-in experiment's folder
    holding a run config of that name, so ``./cornell.yaml`` is not the file both ways) said
    ``scene=../../../tmp/h460/sub/cornell.yaml``, climbing from the config's folder to ``/``: the whole path,
    shorter, names it as well."""
    deep = tmp_path.joinpath(*["d"] * (len(str(tmp_path)) // 2 + 8), "configs")
    deep.mkdir(parents=True)
    (deep / "cornell.yaml").write_text("scene: cornell\n")
    work = tmp_path / "w"
    work.mkdir()
    target = work / "cornell.yaml"
    target.write_text("geometry: {}\n")
    monkeypatch.chdir(work)
    given = config_paths._given_as(os.fspath(target), "cornell.yaml", [deep])
    assert given == os.fspath(target)
    assert not given.startswith("..")
    assert Path(given).resolve() == target.resolve()


def test_a_dry_run_says_the_rounds_an_interrupted_reference_saved(tmp_path, cache, capsys):
    """``tlm sweep --reference --dry-run`` after a Ctrl-C during the sweep's reference said 'compute (2 points)'
    alone, as if from round 1: it names the rounds saved (references/<key>.partial.npz) that it resumes from."""
    import json

    import numpy as np
    import yaml

    from tlm.cli import main
    from tlm.experiments.reference_cache import partial_path

    base = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "photons": {"count": 1500},
            "render": {"light_samples": 1}, "estimate": {"final_gather": 0},
            "arch": {"frames": 1, "trace": False, "packet_size": 32},
            "reference": {"photons": 1500, "k_nearest": 20, "max_rounds": 8, "min_rounds": 4, "spp": 2}}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": base, "grid": {"arch.fifo_depth": [1, 16]}}))
    args = ["sweep", str(path), "--out", str(tmp_path / "o"), "--reference", "--dry-run"]
    assert main([*args, "--json"]) == 0
    (ref,) = json.loads(capsys.readouterr().out)["references"]
    assert (ref["action"], ref["saved_rounds"]) == ("compute", 0)
    saved = partial_path(ref["key"])
    saved.parent.mkdir(parents=True, exist_ok=True)
    np.savez(saved, info=np.array(json.dumps({"version": 1, "key": ref["key"], "k": 3, "strata": 2})))
    assert main([*args, "--json"]) == 0
    (ref,) = json.loads(capsys.readouterr().out)["references"]
    assert (ref["action"], ref["saved_rounds"]) == ("compute", 6)
    assert main(args) == 0
    said = capsys.readouterr().out.splitlines()
    assert (f"    {ref['key']}: compute (2 points; 6 rounds saved by an interrupted compute, resumed where these "
            "settings allow)") in said
    assert saved.exists()  # (a dry run removes nothing)
