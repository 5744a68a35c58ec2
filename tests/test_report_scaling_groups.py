"""Scaling with N in the report and in ``tlm scaling`` (a large-scene probe's findings).

1. The summary's "Does it scale" reads what §3 fits: a sweep over ``arch.pipelines`` among the
   inputs (was: "No eq. 5.2 study among the inputs" beside §3's fit of that sweep).
2. A sweep crossing ``arch.pipelines`` with other factors is fitted once per combination of the
   other factors' values (a curve each, labelled by them), in §3, in the summary and by
   ``tlm scaling`` (was: refused, and §3 said there was no sweep over arch.pipelines); a zip of N
   with another factor (one N per combination) is still refused, and §3's line then names it.
3. A photon-map run with ``--no-reference``: the report's note says it was skipped as asked and
   gives the ``tlm reference`` command ``tlm run`` printed (recorded in ``results.json``; for a
   folder that does not record it, made from its config and overrides).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.scaling import fit, record
from tlm.report.collect import read
from tlm.report.images import images_section
from tlm.report.scaling import scaling_section
from tlm.report.summary import summary_section

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False}}


def _sweep(root: Path, name: str, spec: dict) -> Path:
    (root / f"{name}.yaml").write_text(yaml.safe_dump({"base": BASE, **spec}, sort_keys=False))
    assert main(["sweep", str(root / f"{name}.yaml"), "--out", str(root / name), "--jobs", "1", "--no-progress",
                 "--no-report"]) == 0
    return root / name


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory):
    """Tiny real sweeps of cornell at 16x16: N alone; N crossed with bsp.levels; N zipped with it."""
    root = tmp_path_factory.mktemp("scaling_groups")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        _sweep(root, "n", {"grid": {"arch.pipelines": [1, 2, 4]}})
        _sweep(root, "cross", {"grid": {"arch.pipelines": [1, 2], "bsp.levels": [5, 6]}})
        _sweep(root, "zipped", {"zip": {"arch.pipelines": [1, 2], "bsp.levels": [5, 6]}})
    return root


def _words(html: str) -> str:
    return " ".join(re.sub(r"<[^>]+>", " ", html).split())


# ------------------------------------------------------------------ 1: the summary reads §3's fits


def test_the_summary_says_how_a_sweep_over_pipelines_scales(sweeps, tmp_path, monkeypatch):
    inputs = read([sweeps / "n"])
    sec = scaling_section(inputs, tmp_path)
    assert sec.figures and not sec.absent
    import tlm.report.summary as summary

    drawn = {}
    save = summary.save
    monkeypatch.setattr(summary, "save", lambda fig, out, name, *a, **k: (
        drawn.setdefault(name, [ax.get_ylabel() for ax in fig.axes]), save(fig, out, name, *a, **k))[1])
    lead = _words(summary_section(inputs, tmp_path).lead)
    # (its curves are the static scheduler's unless one names another: the caption says so, h484; on the axis it
    # was cut off, h546)
    assert drawn["summary_scaling.png"] == ["speed-up of TThru"]
    assert "No eq. 5.2" not in lead
    said = re.search(r"Does it scale: cornell (\d+\.\d)x at N = 4 ", lead)
    assert said, lead
    rows = [json.loads(line) for line in (sweeps / "n" / "sweep.jsonl").read_text().splitlines()]
    tthru = {r["arch.pipelines"]: r["cycles.throughput"] for r in rows}
    assert said.group(1) == f"{tthru[1] / tthru[4]:.1f}"  # (the speed-up §3's idle table gives)
    assert (tmp_path / "summary_scaling.png").is_file()


# ------------------------------------------------------------------ 2: a fit per combination of the other factors


def test_a_sweep_crossing_pipelines_with_bsp_levels_is_fitted_per_level_in_the_report(sweeps, tmp_path):
    inputs = read([sweeps / "cross"])
    sec = scaling_section(inputs, tmp_path)
    assert not sec.absent, sec.absent
    assert not [n for n in sec.notes if "not fitted" in n or "no idle figure" in n], sec.notes
    scaling = [f for f in sec.figures if f.file.startswith("scaling_")]
    assert len(scaling) == 1  # (one figure per scene, a curve per level)
    assert "static (bsp.levels = 5) throughput" in scaling[0].caption
    assert "static (bsp.levels = 6) throughput" in scaling[0].caption
    idle = [f.title for f in sec.figures if f.file.startswith("idle_")]
    assert idle == ["cornell [bsp.levels = 5]: idle fraction per PM against N, from cross",
                    "cornell [bsp.levels = 6]: idle fraction per PM against N, from cross"]
    lead = _words(summary_section(inputs, tmp_path).lead)
    assert "cornell [bsp.levels = 5] " in lead and "cornell [bsp.levels = 6] " in lead, lead


def test_tlm_scaling_fits_each_combination_of_the_other_factors(sweeps, tmp_path, capsys):
    assert main(["scaling", str(sweeps / "cross"), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    out = capsys.readouterr().out
    meta = json.loads((tmp_path / "eq" / "eq52.json").read_text())
    got = sorted((f["group"], f["target"], tuple(f["pipelines"])) for f in meta["fits"])
    assert got == [(f"bsp.levels = {v}", t, (1, 2)) for v in (5, 6) for t in ("latency", "throughput")]
    assert re.search(r"^  cornell +rcast +static +bsp\.levels = 5 throughput ", out, re.M), out
    # the report of the fit draws a curve per level too
    (tmp_path / "rep").mkdir()
    sec = scaling_section(read([tmp_path / "eq"]), tmp_path / "rep")
    assert sec.figures and "static (bsp.levels = 6) latency" in sec.figures[0].caption


def test_a_zip_of_pipelines_with_another_factor_is_refused_and_section_3_names_it(sweeps, tmp_path, capsys):
    """One N per combination: no fit, as before; §3 no longer says there is no sweep over N."""
    assert main(["scaling", str(sweeps / "zipped"), "--out", str(tmp_path / "eq"), "--no-report"]) == 2
    err = capsys.readouterr().err
    assert "differ in more than N" in err and "bsp.levels" in err, err
    sec = scaling_section(read([sweeps / "zipped"]), tmp_path)
    assert not [f for f in sec.figures if f.file.startswith("scaling_")]
    # (its idle figure over N stays one, as no combination of the other factors has two values of N)
    assert [f.title for f in sec.figures] == ["cornell: idle fraction per PM against N, from zipped"]
    assert "no sweep over arch.pipelines" not in (sec.absent or "")
    assert any("bsp.levels" in n and "not fitted" in n for n in sec.notes), sec.notes
    lead = _words(summary_section(read([sweeps / "zipped"]), tmp_path).lead)
    assert "No eq. 5.2 fit of zipped" in lead, lead


def _config(n: int, levels: int) -> dict:
    return {"scene": "cornell", "mode": "rcast", "bsp": {"levels": levels},
            "arch": {"pipelines": n, "scheduler": "static"}}


def _results(n: int, work: int) -> dict:
    per = {"traversal": work // n, "intersection": 2 * work // n, "fragment": work // (2 * n)}
    return {"scene": {"name": "cornell"}, "timing": {"pipelines": [per] * n},
            "cycles": {"vertex": 1000, **per, "latency": 2000 + 2 * work // n, "throughput": 1000 + 2 * work // n}}


def test_a_combination_with_one_n_is_left_out_with_a_note_where_another_has_two():
    recs = [{**record(_results(n, w), _config(n, lv)), "sweep": "runs/sw", "factors": {"arch.pipelines": n,
                                                                                      "bsp.levels": lv}}
            for n, lv, w in ((1, 5, 12000), (2, 5, 12000), (4, 6, 9000))]
    assert set(fit(recs)) == {("cornell", "rcast", "static", t, "bsp.levels = 5") for t in ("latency", "throughput")}
    notes: list[str] = []
    fit(recs, notes)
    assert notes == ["runs/sw (cornell/rcast/static): bsp.levels = 6: not fitted: one value of N only (N = 4); "
                     "eq. 5.2 needs two"]
    with pytest.raises(InputError, match="differ in more than N"):  # (a zip: no combination has two)
        fit([recs[0], recs[2]])


# ------------------------------------------------------------------ 3: a reference skipped as asked


@pytest.mark.parametrize("recorded", [True, False])
def test_a_run_without_its_reference_is_said_skipped_with_the_command_tlm_run_printed(tmp_path, cache, capsys,
                                                                                       recorded):
    out = tmp_path / "pm"
    assert main(["run", "cornell", "--mode", "pmap", "--set", "resolution=[16,16]", "--set", "photons.count=2000",
                 "--no-reference", "--out", str(out), "--no-progress", "--no-report"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "pmap error" in x)
    command = line.split("compute it with: ", 1)[1]
    assert command == "tlm reference cornell --set 'resolution=[16,16]' --set photons.count=2000 --set mode=pmap"
    results = json.loads((out / "results.json").read_text())
    assert (results["error"]["skipped"], results["error"]["command"]) == ("--no-reference", command)
    if not recorded:  # (a folder of an older tlm: the command from its config and overrides)
        del results["error"]["skipped"], results["error"]["command"]
        (out / "results.json").write_text(json.dumps(results))
    (tmp_path / "rep").mkdir()
    sec = images_section(read([out]), tmp_path / "rep")
    said = [n for n in sec.notes if "error was not measured" in n]
    assert len(said) == 1 and f"skipped (--no-reference): no reference {results['error']['reference']} cached; " \
        f"compute it with: {command}, then run it again" in said[0], said
