"""h423: hand-written lists moved onto ``listing``, and ``--set`` of a study file's own key.

Lists: a Dask worker with three versions other than the sweep's read "Python ... and numpy ... and numba ...";
a reference judged against three of its points' tolerances "meets 0.01 (...) and 0.02 (...) and 0.04 (...)";
``tlm report`` of a folder with no tlm output and four folders passed over said "...; and 1 more passed over".

--set: h416 made ``tlm granularity --set packet_sizes=...`` say that packet_sizes is the study file's own
key; ``--set base=...``, ``--set description=...`` and every other study's own keys (``points``, ``scenes``,
``modes``, ``cases``; a sweep file's ``set``, ``grid``, ``zip``) were still a plain "unknown key" (or "did
you mean 'scene'?"). Every study command, and ``tlm sweep``, now says it the same way
(:func:`tlm.experiments.study.refuse_own_keys`), nothing written; ``--set base.render.spp=2`` is told
``--set render.spp=2``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tlm.cli import main
from tlm.experiments.dask_workers import OtherVersionsOnWorker, check_worker_versions
from tlm.experiments.reference_cache import ReferenceSettings
from tlm.experiments.sweep_reference import _judged
from tlm.report.collect import read

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "arch": {"frames": 1}}
PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [16, 16]}
CASE = {"name": "a", "category": "geometry", "expect": "x", "config": {"mode": "rcast"}, "checks": ["finite"]}
# each command, its file's own keys and the file (JSON is YAML)
STUDIES = {
    "granularity": (("packet_sizes",), {"base": BASE, "packet_sizes": [4, 16]}),
    "error-vs-cost": (("points",), {"base": PMAP, "points": [{"estimate.k": [4, 8]}]}),
    "thesis": (("scenes", "modes"), {"base": {"resolution": [16, 16]}, "scenes": ["cornell"], "modes": ["rcast"]}),
    "extreme": (("cases",), {"base": {"scene": "cornell", "resolution": [16, 16]}, "cases": [CASE]}),
}
SWEEP = {"base": BASE, "set": {"render.spp": 1}, "grid": {"arch.fifo_depth": [4, 8]}, "zip": {}}


def _refused(args: list[str], capsys) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def _cases():
    for cmd, (keys, text) in STUDIES.items():
        for key in ("base", "description", *keys):
            yield cmd, text, key, "study file"
    for key in ("base", "description", "set", "grid", "zip"):
        yield "sweep", SWEEP, key, "sweep file"


@pytest.mark.parametrize("cmd, text, key, file", list(_cases()))
def test_a_set_of_the_file_s_own_key_says_so_on_every_study(tmp_path, capsys, cache, cmd, text, key, file):
    study = tmp_path / "s.yaml"
    study.write_text(json.dumps({"description": "d", **text}))
    out = tmp_path / "o"
    said = _refused([cmd, str(study), "--out", str(out), "--set", f"{key}=[1]"], capsys)
    assert said == (f"tlm: error: {study}: --set {key}=[1]: {key} is the {file}'s own key, and --set sets its base "
                    f"(the run config): change {key} in the {file}")
    assert not out.exists()


@pytest.mark.parametrize("cmd", [*STUDIES, "sweep"])
def test_a_set_of_a_key_under_base_is_told_the_set_that_sets_it(tmp_path, capsys, cache, cmd):
    study = tmp_path / "s.yaml"
    study.write_text(json.dumps(STUDIES[cmd][1] if cmd in STUDIES else SWEEP))
    out = tmp_path / "o"
    said = _refused([cmd, str(study), "--out", str(out), "--set", "base.render.spp=2"], capsys)
    file = "sweep file" if cmd == "sweep" else "study file"
    assert said == (f"tlm: error: {study}: --set base.render.spp=2: base.render.spp is in base, the {file}'s own "
                    "key, and --set sets what base holds (the run config): --set render.spp=2")
    assert not out.exists()


def test_a_set_of_the_base_s_own_keys_is_still_taken(tmp_path, capsys, cache):
    # (a run config key named like none of the file's: refused for its value, as tlm run refuses it)
    study = tmp_path / "s.yaml"
    study.write_text(json.dumps(STUDIES["thesis"][1]))
    said = _refused(["thesis", str(study), "--out", str(tmp_path / "o"), "--set", "render.spp=two"], capsys)
    assert said.startswith(f"tlm: error: {study}, with --set: render.spp: ") and "own key" not in said


SWEEPS = {"python": "3.11.7", "numpy": "2.4.6", "numba": "0.68.1", "kernels": "numba"}


def test_three_versions_on_a_worker_are_one_list():
    with pytest.raises(OtherVersionsOnWorker) as e:
        check_worker_versions(SWEEPS, {"python": "3.12.1", "numpy": "1.26.4", "numba": "0.60.0", "kernels": "numba"},
                              "worker w")
    assert str(e.value).startswith("worker w runs Python 3.12 (the sweep's 3.11), numpy 1.26.4 (the sweep's 2.4.6) "
                                   "and numba 0.60.0 (the sweep's 0.68.1): ")


def test_a_reference_judged_against_three_tolerances_lists_them_once():
    meta = {"relative_standard_error": 0.03, "rounds": 8, "cycles": 4}
    asked = [ReferenceSettings(photons=10, tolerance=t) for t in (0.04, 0.05, 0.06, 0.06, 0.01)]
    assert _judged(meta, asked) == ("; against its points' own tolerances it meets 0.04 (1 point), 0.05 (1 point) "
                                    "and 0.06 (2 points), and does NOT meet 0.01 (1 point)")


@pytest.mark.parametrize("n, shown", [(4, 4), (5, 3)])
def test_no_tlm_output_never_says_and_1_more_passed_over(tmp_path, n, shown):
    from tlm.errors import InputError

    root = tmp_path / "root"
    for i in range(n):
        (root / f".hidden{i}").mkdir(parents=True)
    with pytest.raises(InputError) as e:
        read([root])
    said = str(e.value)
    assert said.count("a hidden folder, not searched") == shown, said
    assert "and 1 more" not in said
    if n == 5:
        assert said.endswith("; and 2 more passed over"), said
    else:
        assert said.endswith(f"{Path(root, '.hidden3')}: a hidden folder, not searched"), said
