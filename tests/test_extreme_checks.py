"""``tlm extreme``: every check's keys and values are checked before any case runs.

A misspelt key (``maxx``), a value of the wrong type (``min: "abc"``, ``rel_rms: "x"``,
``error: 123``) or a case named that has no results (one that expects an error) is an
input error of the cases file: one line naming the file and the key, exit status 2,
nothing written. A ``value`` that is not a number in ``results.json`` (known only after
the run) fails its check with a line that says so.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.experiments.extreme import judge, load_cases

ROOT = Path(__file__).resolve().parents[1]
BASE = {"scene": "ring", "mode": "rcast", "resolution": [16, 16], "render": {"spp": 1, "light_samples": 1},
        "arch": {"frames": 2, "trace": False}}


def _case(name: str, checks: list, **config) -> dict:
    return {"name": name, "category": "test", "expect": "x", "config": config, "checks": checks}


def _extreme(tmp_path: Path, cases: list[dict]) -> tuple[int, Path, Path]:
    path = tmp_path / "cases.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "cases": cases}, sort_keys=False))
    out = tmp_path / "out"
    return main(["extreme", str(path), "--out", str(out), "--no-report"]), path, out


def _refused(tmp_path, capsys, cases: list[dict], *words: str) -> None:
    """The file is refused before any case runs: exit 2, one line naming it and ``words``, no output folder."""
    rc, path, out = _extreme(tmp_path, cases)
    err = capsys.readouterr().err
    assert rc == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert str(path) in err and all(w in err for w in words), err
    assert not out.exists()


@pytest.mark.parametrize("checks, key, words", [
    ([{"value": "primary.misses", "maxx": -1}], "cases[1].checks[0]", "unknown key 'maxx' (did you mean 'max'?)"),
    ([{"value": "cycles.throughput", "mx": 1}], "cases[1].checks[0]", "unknown key 'mx' (did you mean 'max'?)"),
    ([{"compare": "cycles.throughput", "case": "a", "op": "~", "rell": 0.5}], "cases[1].checks[0]",
     "unknown key 'rell' (did you mean 'rel'?)"),
    ([{"same_image": "a", "rel_rsm": 1}], "cases[1].checks[0]", "unknown key 'rel_rsm' (did you mean 'rel_rms'?)"),
    ([{"value": "primary.misses", "colour": 1}], "cases[1].checks[0]",
     "unknown key 'colour' (a value check takes value, min, max, equals)"),
])
def test_a_misspelt_key_of_a_check_is_refused(tmp_path, capsys, cache, checks, key, words):
    """Before: the key was ignored, so the check always passed ("2 as expected", exit 0)."""
    _refused(tmp_path, capsys, [_case("a", ["finite"]), _case("b", checks)], f"{key}: {words}")


def test_a_bound_that_is_not_a_number_is_refused(tmp_path, capsys, cache):
    """Before: TypeError ('>=' between int and str) after the run, an internal error (exit 1)."""
    _refused(tmp_path, capsys, [_case("a", [{"value": "primary.misses", "min": "abc"}])],
             "cases[0].checks[0].min: 'abc' is not a number")


@pytest.mark.parametrize("bad, words", [(True, "True is not a number"), (float("nan"), "nan is not finite")])
def test_a_bound_that_is_a_bool_or_not_finite_is_refused(tmp_path, capsys, cache, bad, words):
    _refused(tmp_path, capsys, [_case("a", [{"value": "primary.misses", "max": bad}])],
             f"cases[0].checks[0].max: {words}")


def test_a_tolerance_that_is_not_a_number_is_refused(tmp_path, capsys, cache):
    """Before: ValueError (float('x')) after both runs, an internal error (exit 1)."""
    _refused(tmp_path, capsys, [_case("a", ["finite"]), _case("b", [{"same_image": "a", "rel_rms": "x"}])],
             "cases[1].checks[0].rel_rms: 'x' is not a number")


def test_an_expected_error_that_is_not_text_is_refused(tmp_path, capsys, cache):
    """Before: TypeError ('in' of an int) once the run failed, an internal error (exit 1)."""
    _refused(tmp_path, capsys, [_case("a", [{"error": 123}], resolution=[0, 4])],
             "cases[0].checks[0].error: 123 is not a non-empty text")


@pytest.mark.parametrize("check", [{"same_image": "a"}, {"compare": "cycles.throughput", "case": "a"}])
def test_a_case_that_expects_an_error_cannot_be_compared_with(tmp_path, capsys, cache, check):
    """Before: accepted, and the check failed after the run with "results.json has no 'a'"."""
    _refused(tmp_path, capsys, [_case("a", [{"error": "must be positive"}], resolution=[0, 4]), _case("b", [check])],
             "cases[1].checks[0]: 'a' expects an error, so it has no results to compare with")


def test_a_case_cannot_be_compared_with_itself(tmp_path, capsys, cache):
    """Before: accepted (the case counted as earlier than itself), then "results.json has no 'a'"."""
    _refused(tmp_path, capsys, [_case("a", [{"same_image": "a"}])], "cases[0].checks[0]: 'a' is not an earlier case")


def test_a_value_that_is_not_a_number_fails_its_check(tmp_path, capsys, cache):
    """Known only after the run: the check fails with one line (before: TypeError, an internal error)."""
    a = _case("a", [{"value": "scene", "min": 1}, {"value": "scene.name", "equals": "ring"}])
    rc, _, out = _extreme(tmp_path, [a, _case("b", [{"compare": "scene", "case": "a", "op": "<"}])])
    captured = capsys.readouterr()
    assert rc == 1 and captured.err == "", captured.err
    rows = [json.loads(x) for x in (out / "extreme.jsonl").read_text().splitlines()]
    assert [r["passed"] for r in rows] == [False, False]
    assert rows[0]["measured"] == "scene is a mapping, not a number; scene.name = ring"
    assert rows[1]["measured"] == "scene: a mapping against a mapping (a), not numbers"


def test_a_case_whose_run_failed_has_no_results_to_compare(tmp_path):
    passed, measured = judge({"same_image": "a"}, tmp_path, {}, {})
    assert not passed and measured == "case 'a' has no results (its run failed)"


def test_the_committed_cases_still_load():
    _, cases, _ = load_cases(ROOT / "configs" / "extreme.yaml")
    assert len(cases) >= 30
