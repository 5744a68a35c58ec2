"""`tlm report` of a run whose results.json lacks a key, and a log axis over 600 decades (h306).

* A results.json whose ``cycles`` lacks a PM's cycles or TThru (the thesis tables read them) ended the
  report in ``internal error: KeyError: 'traversal'`` (exit 1): it is now a damaged input, named with its
  key among the page's damaged inputs, the rest reported; alone, one line and exit 2, nothing written.
  Every other key of ``cycles``, ``work``, ``timing`` and ``timing.units`` deleted in turn: no internal error.
* :class:`tlm.report.common.LogTicks` placed its ticks at ``log(t / lo) / log(hi / lo)``: over 1e-301 to
  1e300 the ratio overflows and each position was inf / inf (numpy's "invalid value in scalar divide", and
  one tick, 5e299, for the whole axis).
"""

from __future__ import annotations

import itertools
import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.thesis import OURS_CYCLES
from tlm.report import common
from tlm.report.checks import read_results

REPO = Path(__file__).resolve().parents[1]
NEEDED = {f"cycles.{k}" for k in OURS_CYCLES}  # (the keys the report needs: the thesis tables read them)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("h306")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--out", str(root / "good"), "--set",
                     "resolution=[8,8]", "--set", "arch.frames=2", "--set", "render.light_samples=1", "--set",
                     "mode=rcast", "--set", "arch.trace=false", "--no-report", "--no-progress",
                     "--no-reference"]) == 0
    return root / "good"


def _copy(run: Path, folder: Path, results: dict | None = None) -> Path:
    """The run's results.json (or ``results``) and config in ``folder``."""
    folder.mkdir(parents=True)
    shutil.copy(run / "config.resolved.yaml", folder)
    (folder / "results.json").write_text(json.dumps(results) if results is not None
                                         else (run / "results.json").read_text())
    return folder


def _without(results: dict, key: str) -> dict:
    out = json.loads(json.dumps(results))
    *parents, last = key.split("/")
    at = out
    for k in parents:
        at = at[k]
    del at[last]
    return out


def _keys(results: dict) -> list[str]:
    """Every key of ``cycles``, ``work`` (and each pass's), ``timing``, ``timing.units`` and of one PM's
    unit, '/'-separated (a unit is named ``pipe0.traversal``)."""
    units = results["timing"]["units"]
    return [*(f"cycles/{k}" for k in results["cycles"]), "work", *(f"work/{p}" for p in results["work"]),
            *(f"timing/{k}" for k in results["timing"]), *(f"timing/units/{u}" for u in units),
            *(f"timing/units/pipe0.traversal/{k}" for k in units["pipe0.traversal"])]


def test_a_results_json_without_a_pms_cycles_names_the_key(tmp_path):
    """The check itself (no render): every key the thesis tables read of ``cycles``."""
    results = {"tlm": "results/1", "scene": {"name": "cornell"}, "mode": "rcast", "timing": {}, "fps": 1.0,
               "cycles": dict.fromkeys(("vertex", "traversal", "intersection", "fragment", "throughput",
                                        "latency"), 10)}
    path = tmp_path / "results.json"
    path.write_text(json.dumps(results))
    assert read_results(path)["cycles"]["traversal"] == 10
    for key in OURS_CYCLES:
        path.write_text(json.dumps(_without(results, f"cycles/{key}")))
        with pytest.raises(InputError) as e:
            read_results(path)
        assert str(e.value) == f"{path}: cycles: has no {key!r}: not a tlm results file", key
    path.write_text(json.dumps(_without(results, "cycles/latency")))  # (no section reads it of a run)
    assert "latency" not in read_results(path)["cycles"]


@pytest.mark.slow  # (a render, and a report for each key)
def test_each_key_deleted_in_turn_is_no_internal_error(tiny_run, tmp_path, capsys, cache):
    """A run without one key: a key the report needs is one line naming the file and the key, exit 2, no
    report written (the run is the only input); any other is read around, the report written."""
    results = json.loads((tiny_run / "results.json").read_text())
    keys = _keys(results)
    assert {k.replace("/", ".") for k in keys} >= NEEDED and len(keys) > 40, keys
    wrong = []
    for i, key in enumerate(keys):
        bad = _copy(tiny_run, tmp_path / str(i), _without(results, key))
        capsys.readouterr()
        rc = main(["report", str(bad), "--no-progress"])
        err = capsys.readouterr().err
        name = key.replace("/", ".")
        if "internal error" in err:
            wrong.append(f"{name}: {err.strip()[:300]}")
        elif name in NEEDED:
            said = (f"tlm: error: {bad / 'results.json'}: cycles: has no {name.split('.')[1]!r}: not a tlm results "
                    "file; copy it again or run it again\n")
            if rc != 2 or err != said or (bad / "report").exists():
                wrong.append(f"{name}: exit {rc}, not one line naming it: {err.strip()[:300]}")
        elif rc != 0 or "Damaged inputs" in (bad / "report" / "report.html").read_text(encoding="utf-8"):
            wrong.append(f"{name}: a key the report reads around, refused or said to be damaged: {err.strip()[:300]}")
        shutil.rmtree(bad)
    assert not wrong, "\n".join(wrong)


@pytest.mark.slow  # (a render)
def test_a_run_without_a_pms_cycles_is_named_and_the_rest_reported(tiny_run, tmp_path, capsys, cache):
    results = json.loads((tiny_run / "results.json").read_text())
    _copy(tiny_run, tmp_path / "runs" / "good")
    bad = _copy(tiny_run, tmp_path / "runs" / "bad", _without(results, "cycles/traversal"))
    capsys.readouterr()
    assert main(["report", str(tmp_path / "runs"), "--out", str(tmp_path / "rep"), "--no-progress"]) == 0
    err = capsys.readouterr().err
    line = (f"{bad / 'results.json'}: cycles: has no 'traversal': not a tlm results file; copy it again or run it "
            f"again: the run {bad} is left out of this report")
    assert f"tlm: note: {line}\n" in err and "internal error" not in err, err
    page = (tmp_path / "rep" / "report.html").read_text(encoding="utf-8")
    assert "Damaged inputs" in page and "1 damaged file left out" in page and "good: cornell/rcast" in page


def test_a_log_axis_over_600_decades_places_its_ticks_without_nan():
    """1e-301 to 1e300: hi / lo is inf; the ticks were placed at inf / inf (a RuntimeWarning each), no set
    fitted and the axis had one tick. Now several, apart, and no warning."""
    for axis in ("x", "y"):
        fig = Figure(figsize=(5.4, 3.1), layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        data, other = np.array([1e-301, 1e300]), np.array([0.0, 1.0])
        with np.errstate(over="ignore"):  # (matplotlib's own autoscale of such data overflows: not ours)
            ax.plot(*((data, other) if axis == "x" else (other, data)), "o")
            (ax.set_xscale if axis == "x" else ax.set_yscale)("log")
            (ax.set_xlim if axis == "x" else ax.set_ylim)(1e-301, 1e300)
        common.log_ticks(ax, axis)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            fig.canvas.draw()
        a = ax.xaxis if axis == "x" else ax.yaxis
        ticks = [t for t in a.get_majorticklocs() if 1e-301 <= t <= 1e300]
        assert len(ticks) >= 3, ticks
        renderer = fig.canvas.get_renderer()
        at = 0 if axis == "x" else 1
        boxes = sorted((t.get_window_extent(renderer) for t in a.get_majorticklabels()
                        if t.get_visible() and t.get_text() and 1e-301 <= t.get_position()[at] <= 1e300),
                       key=lambda b: b.x0 if axis == "x" else b.y0)
        assert len(boxes) == len(ticks) and all((p.x1 <= q.x0) if axis == "x" else (p.y1 <= q.y0)
                                                for p, q in itertools.pairwise(boxes)), boxes


def test_a_log_ratio_is_right_at_either_end_of_the_floats():
    """The ratio of the logs' ends where it overflows; the log of the ratio where the logs are equal."""
    assert common._ln_ratio(1e300, 1e-301) == pytest.approx(601 * np.log(10), rel=1e-12)
    assert common._ln_ratio(1e300, 1e300) == 0.0
    nxt = float(np.nextafter(1e300, np.inf))
    assert np.log(nxt) == np.log(1e300) and common._ln_ratio(nxt, 1e300) > 0
