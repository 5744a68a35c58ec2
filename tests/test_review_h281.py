"""Review of 6820743 (h281): a sweep that a scaling study among a report's inputs lists is shown through that
study's fit alone, and ``tlm scaling``'s message for points of one N.

1. ``report.scaling.fitted_sweeps`` matched the study's ``eq52.json`` ``sweeps`` by path alone, so a sweep
   among the inputs that the study's fit does not show (run again with other points or a second factor since,
   or another sweep where the relative path leads now: the study copied without its sweeps) was not fitted by
   the report either: its fit was shown nowhere, the summary gave the stale study's speed-up alone, and a note
   said it was "shown through that fit". Now only a sweep whose points are those the study was fitted from
   (``fitted_from``; by the path alone for a study of an older tlm) is left to the study; of two studies that
   list it, the note names the one whose fit shows it.
2. ``tlm scaling`` of a sweep over ``arch.pipelines`` whose points of the other values of N had not finished
   (interrupted, or failed) said "the sweep has one value of N ... eq. 5.2 needs a sweep over arch.pipelines":
   it now says that no point of another N has finished.
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.scaling import fit_group
from tlm.report.collect import read
from tlm.report.scaling import fit_sources, fitted_sweeps, scaling_section
from tlm.report.summary import summary_section
from tlm.scenes.loader import scenes_dir

CORNELL = scenes_dir() / "cornell.yaml"


def _sweep(folder: Path, points: list[tuple[int, int]], work: int = 12000, salt: str = "",
           rows_of: set[int] | None = None) -> Path:
    """A sweep folder of finished points ``(N, page-miss cycles)`` without rendering (the factors those that
    vary among them); ``rows_of``: the N whose points have a row yet (the others not run: interrupted)."""
    keys = ["arch.pipelines", *(["arch.page_miss_cycles"] if len({m for _, m in points}) > 1 else [])]
    (folder / "points").mkdir(parents=True)
    spec = {"tlm": "sweep/1", "grid": {k: sorted({p[i] for p in points}) for i, k in enumerate(keys)}, "points": []}
    rows = []
    for i, (n, miss) in enumerate(points):
        h = salt + f"{i:016x}"[len(salt):]
        factors = dict(zip(keys, (n, miss), strict=False))
        per = {"traversal": 9000 // n, "intersection": (work + miss) // n, "fragment": 3000 // n}
        thru = 1000 + (work + miss) // n
        res = {"scene": {"name": "cornell", "source": str(CORNELL)}, "mode": "rcast", "fps": 1e9 / thru,
               "timing": {"pipelines": [per] * n, "throughput_estimate": {"steady": True, "frames": 5}},
               "cycles": {"vertex": 1000, **per, "latency": 1000 + thru, "throughput": thru}}
        spec["points"].append({"point": i, "hash": h, "factors": factors})
        if rows_of is None or n in rows_of:
            rows.append({"point": i, "hash": h, "status": "ok", "error": None, "scene": "cornell", "mode": "rcast",
                         **factors, "fps": res["fps"], "cycles.throughput": res["cycles"]["throughput"],
                         "idle.vertex": 0.5, "idle.traversal": 0.1})
        (folder / "points" / h).mkdir()
        (folder / "points" / h / "results.json").write_text(json.dumps({**res, "factors": factors}))
        (folder / "points" / h / "config.resolved.yaml").write_text(yaml.safe_dump(
            {"scene": "cornell", "mode": "rcast", "seed": 0, "resolution": [16, 16],
             "arch": {"pipelines": n, "scheduler": "static", "frames": 5, "page_miss_cycles": miss}}))
    (folder / "sweep.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


def _scaling(sweep: Path, out: Path) -> Path:
    assert main(["scaling", str(sweep), "--out", str(out), "--no-report"]) == 0
    return out


def _scale_line(inputs, out: Path) -> str:
    lead = " ".join(re.sub(r"<[^>]+>", " ", summary_section(inputs, out).lead).split())
    said = re.search(r"Does it scale: (.*?) \(static tiles", lead)
    assert said, lead
    return said.group(1)


def _shown(inputs, tmp_path: Path, name: str) -> tuple[list[str], list[str], list[str], str]:
    """(§3's fit sources, its scaling figures, its notes, the summary's "Does it scale" curves)."""
    out = tmp_path / name
    out.mkdir()
    notes: list[str] = []
    labels = [label for _, label, *_ in fit_sources(inputs, notes)]
    sec = scaling_section(inputs, out)
    return labels, sorted(f.file for f in sec.figures if f.file.startswith("scaling_")), sec.notes, \
        _scale_line(inputs, out)


# ------------------------------------------------------------------ 1: a sweep the study's fit does not show


def test_a_sweep_run_again_with_a_second_factor_since_its_study_was_fitted_is_fitted_by_the_report(tmp_path):
    sw = _sweep(tmp_path / "sw", [(1, 12), (2, 12)])
    eq = _scaling(sw, tmp_path / "eq")
    inputs = read([eq, sw])  # (as it was fitted: shown through the study alone)
    assert fitted_sweeps(inputs) == {sw.resolve(): "eq"}
    labels, figures, notes, scale = _shown(inputs, tmp_path, "then")
    assert (labels, figures) == (["eq"], ["scaling_eq_cornell.png"])
    assert "sw: fitted by the scaling study eq among the inputs: shown through that fit, not fitted again" in notes
    assert re.fullmatch(r"cornell \d+\.\dx at N = 2", scale), scale
    shutil.rmtree(sw)  # the same folder, run again over the page-miss cost too: the study fitted one combination
    _sweep(sw, [(1, 0), (2, 0), (1, 48), (2, 48)], salt="b")
    inputs = read([eq, sw])
    assert fitted_sweeps(inputs) == {} and fitted_sweeps(inputs, current=False) == {sw.resolve(): "eq"}
    labels, figures, notes, scale = _shown(inputs, tmp_path, "rep")
    assert labels == ["eq", "sw"] and figures == ["scaling_eq_cornell.png", "scaling_sw_cornell.png"], figures
    assert not any("fitted by the scaling study" in n for n in notes), notes
    assert any(n.startswith("eq: out of date: its sweep ") for n in notes), notes
    assert "cornell (sw) [arch.page_miss_cycles = 48]" in scale and "cornell (eq) (out of date)" in scale, scale


def test_a_study_copied_without_its_sweep_beside_another_of_that_name_leaves_that_one_to_the_report(tmp_path):
    eq = _scaling(_sweep(tmp_path / "a" / "sw", [(1, 12), (2, 12)]), tmp_path / "a" / "eq")
    shutil.copytree(eq, tmp_path / "b" / "eq")  # (its eq52.json: sweeps ["../sw"], which leads to b/sw now)
    other = _sweep(tmp_path / "b" / "sw", [(1, 12), (4, 12)], work=30000, salt="c")
    inputs = read([tmp_path / "b" / "eq", other])
    labels, figures, notes, scale = _shown(inputs, tmp_path, "rep")
    assert labels == ["eq", "sw"] and len(figures) == 2, (labels, figures)
    assert not any("fitted by the scaling study" in n for n in notes), notes
    assert re.search(r"cornell \(sw\) \d+\.\dx at N = 4", scale), scale  # (the sweep the study did not fit)


def test_of_two_studies_listing_a_sweep_the_note_names_the_one_whose_fit_shows_it(tmp_path):
    sw = _sweep(tmp_path / "sw", [(1, 12), (2, 12), (4, 12)], rows_of={1, 2})  # interrupted: N = 4 not run yet
    old = _scaling(sw, tmp_path / "old")
    _sweep(tmp_path / "full", [(1, 12), (2, 12), (4, 12)])
    shutil.copy(tmp_path / "full" / "sweep.jsonl", sw / "sweep.jsonl")  # the same command finished it
    new = _scaling(sw, tmp_path / "new")
    inputs = read([old, new, sw])
    assert fitted_sweeps(inputs) == {sw.resolve(): "new"}
    labels, _, notes, _ = _shown(inputs, tmp_path, "rep")
    assert labels == ["old", "new"]
    assert "sw: fitted by the scaling study new among the inputs: shown through that fit, not fitted again" in notes


# ------------------------------------------------------------------ 2: points of one N in a sweep over N


def test_points_of_one_n_of_a_sweep_over_n_are_said_to_lack_the_other_ns_points():
    pts = [{"pipelines": 2, "T_vert0": 100, "sum_max": 1000, "max_max": 500, "latency": 2000 + m,
            "throughput": 1000 + m, "factors": {"arch.pipelines": 2, "arch.page_miss_cycles": m},
            "settings": {"arch.pipelines": "2", "arch.page_miss_cycles": str(m)}} for m in (0, 48)]
    with pytest.raises(InputError) as e:
        fit_group(pts, "throughput")
    said = str(e.value)
    assert "all have N = 2 (they differ in arch.page_miss_cycles): no point of another value of N has finished " \
           "(the sweep has no other, or those points failed or have not run yet" in said, said
    assert "the sweep has one value of N" not in said, said


def test_tlm_scaling_of_an_interrupted_sweep_over_n_does_not_say_it_has_one_n(tmp_path, capsys):
    sw = _sweep(tmp_path / "sw", [(1, 0), (1, 48), (2, 0), (2, 48)], rows_of={2})
    assert main(["scaling", str(sw), "--out", str(tmp_path / "eq"), "--no-report"]) == 2
    err = capsys.readouterr().err
    assert "no point of another value of N has finished" in err and "one value of N" not in err, err
    assert not (tmp_path / "eq").exists()
