"""``tlm extreme``: the committed cases behave as they expect, and the runner judges right.

The committed ``configs/extreme.yaml`` runs whole (about 15 s): every case must come out
as expected. The runner is checked on small files whose expectations are wrong on
purpose, and the scene files' ``extends:`` (which the cases' scenes use) is checked
for its merge and its errors.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.extreme import load_cases, run_extreme
from tlm.scenes.loader import load_scene

ROOT = Path(__file__).resolve().parents[2]
BASE = {"seed": 0, "resolution": [16, 16], "render": {"light_samples": 1}, "arch": {"frames": 1, "trace": False}}


@pytest.fixture(scope="module")
def committed(tmp_path_factory):
    out = tmp_path_factory.mktemp("extreme") / "out"
    rows = run_extreme(ROOT / "configs" / "extreme.yaml", out)
    return out, rows


@pytest.mark.slow
def test_committed_cases_all_behave_as_expected(committed):
    out, rows = committed
    wrong = {r["case"]: r["measured"] for r in rows if not r["passed"]}
    assert not wrong, wrong
    cats = {r["category"] for r in rows}
    assert {"geometry", "scale", "shading", "photons", "timing", "bad input"} <= cats
    for cat in cats:
        assert sum(r["category"] == cat for r in rows) >= 3, cat
    lines = (out / "extreme.jsonl").read_text().splitlines()
    assert [json.loads(x)["case"] for x in lines] == [r["case"] for r in rows]
    assert (out / "extreme.csv").is_file() and (out / "provenance.json").is_file()


@pytest.mark.slow
def test_committed_bad_input_cases_write_nothing(committed):
    out, rows = committed
    for r in rows:
        ran = (out / "cases" / r["case"] / "results.json").is_file()
        assert ran == (r["category"] != "bad input"), r["case"]
        if r["category"] == "bad input":
            assert r["measured"].startswith("input error: ") and "\n" not in r["measured"]


def _write(tmp_path: Path, cases: list[dict]) -> Path:
    p = tmp_path / "cases.yaml"
    p.write_text(yaml.safe_dump({"base": BASE, "cases": cases}, sort_keys=False))
    return p


def _case(name, checks, **config):
    return {"name": name, "category": "test", "expect": "x", "config": {"scene": "ring", "mode": "rcast", **config},
            "checks": checks}


@pytest.mark.slow
def test_the_runner_reports_a_wrong_expectation(tmp_path, capsys):
    """Expectations that are false must come out as 'not as expected', and the CLI exits 1."""
    path = _write(tmp_path, [
        _case("ref", ["finite", "invariants"]),
        _case("same", [{"same_image": "ref", "rel_rms": 0}, {"compare": "cycles.throughput", "case": "ref"}]),
        _case("deeper", [{"same_image": "ref", "rel_rms": 0}], bsp={"levels": 12}),
        _case("slower-is-faster", [{"compare": "cycles.throughput", "case": "ref", "op": "<"}],
              arch={"page_miss_cycles": 1000}),
        _case("too-small", [{"value": "cycles.throughput", "max": 10}]),
        _case("no-such-key", [{"value": "cycles.nothing", "min": 0}]),
        _case("not-an-error", [{"error": "anything"}]),
        _case("right-error", [{"error": "must be positive"}], resolution=[0, 4]),
        _case("wrong-error", [{"error": "some other words"}], resolution=[0, 4]),
        _case("other-image", [{"same_image": "ref", "rel_rms": 1e-9}], scene="cornell"),
    ])
    assert main(["extreme", str(path), "--out", str(tmp_path / "out"), "--no-report"]) == 1
    rows = {json.loads(x)["case"]: json.loads(x) for x in (tmp_path / "out" / "extreme.jsonl").read_text().splitlines()}
    passed = {k for k, r in rows.items() if r["passed"]}
    assert passed == {"ref", "same", "deeper", "right-error"}, {k: r["measured"] for k, r in rows.items()}
    assert "results.json has no 'cycles.nothing'" in rows["no-such-key"]["measured"]
    assert "ran without the expected error" in rows["not-an-error"]["measured"]
    assert "relative RMS" in rows["other-image"]["measured"]
    out = capsys.readouterr().out
    assert "6 not" in out and "FAIL" in out


def test_a_case_that_is_all_as_expected_exits_0(tmp_path):
    path = _write(tmp_path, [_case("ref", ["finite"])])
    assert main(["extreme", str(path), "--out", str(tmp_path / "out")]) == 0
    page = (tmp_path / "out" / "report" / "report.html").read_text(encoding="utf-8")
    extreme = page[page.index('id="extreme"'):page.index('id="provenance"')]
    assert "1 case, 1 as expected" in extreme and "NOT as expected" not in extreme


@pytest.mark.parametrize("cases, words", [
    ([_case("a", ["finite"]), _case("a", ["finite"])], "'a' is used twice"),
    ([_case("a", ["finite"], arch={"fifo_deph": 2})], "did you mean 'fifo_depth'"),
    ([_case("a", [{"same_image": "b"}])], "'b' is not an earlier case"),
    ([_case("a", ["finite"]), _case("b", [{"compare": "fps", "case": "a", "op": "=~"}])], "op '=~'"),
    ([_case("a", ["finite", {"error": "x"}])], "expects an error has that one check"),
    ([_case("a", ["shiny"])], "'shiny' is not a check"),
    ([_case("a/b", ["finite"])], "must be a folder name"),
    ([{"name": "a", "category": "c", "expect": "x", "config": {}}], "cases[0].checks: missing"),
    ([{**_case("a", ["finite"]), "colour": 1}], "cases[0].colour: unknown key"),
    ([], "cases: must be a non-empty list"),
])
def test_bad_cases_files(tmp_path, capsys, cases, words):
    path = _write(tmp_path, cases)
    with pytest.raises(InputError, match=None) as err:
        load_cases(path)
    assert words in str(err.value) and str(path) in str(err.value)
    assert main(["extreme", str(path), "--out", str(tmp_path / "out")]) == 2
    assert not (tmp_path / "out").exists()


# -- scene files: extends ----------------------------------------------------------------------

def test_extends_changes_one_field_and_keeps_the_rest(tmp_path):
    base = load_scene("cornell")
    (tmp_path / "x.yaml").write_text("extends: cornell\nname: x\nmaterials: {glass: {ior: 1.25}}\n")
    x = load_scene(str(tmp_path / "x.yaml"))
    assert x.name == "x"
    mats = {m.name: m for m in x.materials}
    assert mats["glass"].ior == 1.25 and mats["glass"].transmittance == {m.name: m for m in base.materials}[
        "glass"].transmittance
    assert [m.name for m in x.materials] == [m.name for m in base.materials]
    np.testing.assert_array_equal(x.triangles, base.triangles)
    assert x.lights == base.lights and x.camera == base.camera


def test_extends_chain_and_a_mesh_path_relative_to_its_own_file(tmp_path):
    (tmp_path / "mesh").mkdir()
    (tmp_path / "mesh" / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "mesh" / "base.yaml").write_text(yaml.safe_dump({
        "name": "base", "geometry": {"mesh": "tri.obj"}, "materials": {"w": {"type": "lambertian",
                                                                             "albedo": [0.5, 0.5, 0.5]}},
        "default_material": "w", "lights": [{"type": "point", "position": [0, 0, 2], "power": [1, 1, 1]}],
        "camera": {"eye": [0.3, 0.3, 2], "target": [0.3, 0.3, 0], "vfov": 40}, "resolution": [8, 8]}))
    (tmp_path / "mid.yaml").write_text("extends: mesh/base.yaml\nname: mid\n")
    (tmp_path / "top.yaml").write_text("extends: mid.yaml\nname: top\ntransform: {scale: 2.0}\n")
    top = load_scene(str(tmp_path / "top.yaml"))
    assert top.name == "top" and top.n_triangles == 1
    np.testing.assert_allclose(top.triangles[0].max(axis=0), [2.0, 2.0, 0.0])


@pytest.mark.parametrize("text, words", [
    ("extends: me.yaml\n", "extends itself"),
    ("extends: 3\n", "must be a scene name or a scene file path"),
    ("extends: nowhere.yaml\n", "not found"),
    ("extends: cornel\n", "did you mean 'cornell'"),
    ("extends: cornell\nmaterials: {glass: {ior: -1}}\n", "ior"),
])
def test_bad_extends(tmp_path, text, words):
    (tmp_path / "me.yaml").write_text(text)
    with pytest.raises(InputError) as err:
        load_scene(str(tmp_path / "me.yaml"))
    assert words in str(err.value) and len(str(err.value).splitlines()) == 1
