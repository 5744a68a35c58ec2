"""Review of cb5949e (h538): a reference or ground truth cached before the meta.json seals is sealed in place as it
is first read (before: used with a warning said again by every later process, which entered every report); ``tlm
sweep --dry-run`` checks a cached reference's seal (before: a reference whose meta.json was edited counted as
cached, then the sweep removed it and computed it); a sweep point's ``results.json`` records ``plugins`` as a run's
does (before: only a run's)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from tlm import fingerprint
from tlm.experiments import reference_cache as rc
from tlm.fingerprint import META_SEAL, seal_problem
from tlm.oracle import mitsuba as om


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("tlm: warning: ")]


def _older(folder):
    """``folder``'s meta.json as a tlm before the seals wrote it (no format, no digest)."""
    meta = json.loads((folder / "meta.json").read_text())
    older = {k: v for k, v in meta.items() if k not in ("format", META_SEAL)}
    (folder / "meta.json").write_text(json.dumps(older, indent=2) + "\n")
    return older


def _entries():
    ref = "ab" * 8
    rc.save_reference(ref, np.ones((4, 6, 3)), {"rounds": 8, "relative_standard_error": 0.01, "converged": True})
    truth = om.save_ground_truth("cd" * 10, np.ones((4, 6, 3)), {"scene": "cornell", "spp": 64, "width": 6,
                                                                  "height": 4, "mitsuba_version": "3.5.0"})
    return ((rc.cache_dir() / ref, lambda: rc.load_reference(ref), "reference", "rounds", 8),
            (truth, lambda: om.load_ground_truth(truth.name), "Mitsuba ground-truth", "spp", 64))


def test_an_entry_of_before_the_seals_is_sealed_as_read_and_later_processes_are_quiet(cache, capsys, monkeypatch):
    for folder, load, what, field, value in _entries():
        older = _older(folder)
        monkeypatch.setattr(fingerprint, "_OLDER", set())
        capsys.readouterr()
        got = load()
        assert got is not None and got[1][field] == value
        (line,) = _warnings(capsys.readouterr().err)
        assert line.startswith(f"tlm: warning: {what} cache entry {folder} was written by an older tlm") and \
            "sealed as read" in line, line
        meta = json.loads((folder / "meta.json").read_text())
        assert seal_problem(meta, META_SEAL) is None and list(meta)[-1] == META_SEAL
        assert meta["format"].endswith("-meta/2") and {k: meta[k] for k in older} == older
        assert [f.name for f in folder.iterdir()] and not [f for f in folder.iterdir() if f.name.startswith(".")]
        monkeypatch.setattr(fingerprint, "_OLDER", set())  # (a later process)
        again = load()
        assert again is not None and again[1][field] == value
        assert not _warnings(capsys.readouterr().err)

    # one of another user's (or in a cache that cannot be written) is left as it is, said once a process
    (folder, load, what, field, value), _ = _entries()
    older = _older(folder)
    monkeypatch.setattr(fingerprint, "_OLDER", set())
    monkeypatch.setattr(os, "geteuid", lambda: os.stat(folder).st_uid + 1)  # (the file is another user's)
    capsys.readouterr()
    for _ in range(2):
        assert load()[1][field] == value
    (line,) = _warnings(capsys.readouterr().err)
    assert "it is used as it is" in line and "sealed as read" not in line, line
    assert json.loads((folder / "meta.json").read_text()) == older


@pytest.mark.parametrize("edit", ["seal", "format"])
def test_dry_run_checks_a_cached_references_seal(cache, edit):
    from tlm.experiments.sweep_plan import _cached_meta

    for key in ("ef" * 8, "01" * 8):
        rc.save_reference(key, np.ones((4, 6, 3)), {"rounds": 8, "relative_standard_error": 0.01, "converged": True})
    _older(rc.cache_dir() / ("01" * 8))  # (an older tlm's, no seal: counted as cached, as the sweep uses it)
    assert _cached_meta("01" * 8)["rounds"] == 8
    key = "ef" * 8
    path = rc.cache_dir() / key / "meta.json"
    text = path.read_text()
    path.write_text(text.replace('"rounds": 8', '"rounds": 9') if edit == "seal"
                    else text.replace('"reference-meta/2"', '"reference-meta/3"'))
    assert _cached_meta(key) is None  # (before: 9 rounds, counted 'cached'; the sweep's read removes it, computes)
    assert (rc.load_reference(key) is None) and path.parent.exists() == (edit == "format")


@pytest.mark.slow
def test_a_sweep_points_results_json_records_its_plugins(tmp_path, monkeypatch):
    import importlib
    import sys

    import yaml

    from tlm import api
    from tlm.registry import ESTIMATORS

    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    monkeypatch.syspath_prepend(str(tmp_path))
    (tmp_path / "h538_plug.py").write_text(
        "from tlm.registry import ESTIMATORS\nfrom tlm.render.estimators import Disk\n\n\n"
        "@ESTIMATORS.register('h538disk')\nclass Mine(Disk):\n    pass\n")
    importlib.invalidate_caches()
    importlib.import_module("h538_plug")
    try:
        base = {"scene": "cornell", "resolution": [16, 12], "mode": "pmap", "photons": {"count": 2000},
                "render": {"spp": 1}, "estimate": {"final_gather": 0, "filter": "h538disk"},
                "reference": {"auto": False}}
        sweep = tmp_path / "sw.yaml"
        sweep.write_text(yaml.safe_dump({"base": base, "grid": {"arch.pipelines": [1]}}))
        done = api.run_sweep(sweep, tmp_path / "sw", jobs=1)
        (row,) = done.rows
        got = json.loads((tmp_path / "sw" / "points" / row["hash"] / "results.json").read_text())
        assert [(p["setting"], p["name"], p["module"], p["class"]) for p in got["plugins"]] == [
            ("estimate.filter", "h538disk", "h538_plug", "Mine")]
    finally:
        sys.modules.pop("h538_plug", None)
        ESTIMATORS._classes.pop("h538disk", None)


def test_installed_distributions_are_listed_once_a_process(monkeypatch):
    """A plug-in's record names the distribution that holds it (registry._distribution): the list of every installed
    distribution's files (0.3-1 s) was read again for each plug-in class; now once a process."""
    import importlib.metadata as md

    from tlm import registry

    calls = []
    real = md.packages_distributions
    monkeypatch.setattr(md, "packages_distributions", lambda: calls.append(1) or real())
    if hasattr(registry, "_packages"):  # (since h538)
        registry._packages.cache_clear()
    reg = registry.Registry("h538 kind", (), "tlm.h538-none")
    reg._loaded = True
    for name in ("one", "two"):
        cls = type(f"H538{name}", (), {"__module__": f"h538fake{name}"})  # (no file: keyed by its bytecode)
        reg.register(name)(cls)
        assert reg.plugin(name)["distribution"] is None
    assert len(calls) == 1
