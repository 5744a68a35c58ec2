"""`tlm report` of damaged study folders, and a damaged Mitsuba ground truth in the cache.

A file the report reads that is empty, cut off, or not of the shape tlm writes is one
line naming the file; where it is the report's only input, that line is the error (exit 2)
and no report folder is written (with other inputs, the damaged one is named and left
out: tests/test_report_probe_mends.py); a sweep point whose results.json is
gone is not counted as ok. A damaged ground-truth cache entry is a warning naming the
file, removed and rendered again, never an internal error.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from tlm.cli import main

BASE = {"seed": 0, "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1}, "photons": {"count": 2000},
        "arch": {"frames": 2, "packet_size": 64, "trace": False}}


@pytest.fixture(scope="module")
def studies(tmp_path_factory):
    """Tiny real outputs of tlm thesis, sweep, scaling, extreme and error-vs-cost (their own cache)."""
    root = tmp_path_factory.mktemp("damaged")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        (root / "thesis.yaml").write_text(yaml.safe_dump({"base": BASE, "scenes": ["cornell"], "modes": ["rcast"]}))
        (root / "sweep.yaml").write_text(yaml.safe_dump({
            "base": {**BASE, "scene": "cornell", "mode": "rcast"},
            "grid": {"arch.scheduler": ["static"], "arch.pipelines": [1, 2]}}))
        (root / "extreme.yaml").write_text(yaml.safe_dump({"base": BASE, "cases": [{
            "name": "cornell-rcast", "category": "geometry", "expect": "a finite frame",
            "config": {"scene": "cornell", "mode": "rcast"}, "checks": ["finite", "invariants"]}]}))
        (root / "evc.yaml").write_text(yaml.safe_dump({
            "base": {**BASE, "scene": "cornell", "reference": {"photons": 1500, "k_nearest": 20, "tolerance": 0.5,
                                                               "min_rounds": 2, "max_rounds": 2}},
            "points": [{"estimate.filter": ["disk"], "photons.count": [500]}]}))
        for argv in (["thesis", str(root / "thesis.yaml"), "--out", str(root / "thesis"), "--no-progress"],
                     ["sweep", str(root / "sweep.yaml"), "--out", str(root / "sweep"), "--jobs", "1", "--no-progress"],
                     ["scaling", str(root / "sweep"), "--out", str(root / "scaling")],
                     ["extreme", str(root / "extreme.yaml"), "--out", str(root / "extreme")],
                     ["error-vs-cost", str(root / "evc.yaml"), "--out", str(root / "evc"), "--truth-spp", "0"]):
            assert main([*argv, "--no-report"]) == 0, argv
        yield root


def _copy(studies: Path, name: str, tmp_path: Path) -> Path:
    folder = tmp_path / name
    shutil.copytree(studies / name, folder)
    assert not (folder / "report").exists()
    return folder


def _refused(folder: Path, damaged: str, says: str, capsys) -> None:
    """`tlm report folder` exits 2 with one line naming the damaged file, and writes nothing."""
    capsys.readouterr()
    assert main(["report", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "internal error" not in err
    assert err.startswith(f"tlm: error: {folder / damaged}: ") and err.count("\n") == 1, err
    assert says in err, err
    assert not (folder / "report").exists()


def _cut_mid_row(text: str) -> str:
    """The text cut inside its third line (after a cell or two of it)."""
    lines = text.splitlines(keepends=True)
    return "".join(lines[:2]) + lines[2][:len(lines[2]) // 3]


def _fewer_cells(text: str) -> str:
    """The third line cut after its second cell, the file still ending in a newline."""
    lines = text.splitlines(keepends=True)
    return "".join(lines[:2]) + ",".join(lines[2].split(",")[:2]) + "\r\n"


DAMAGE = {  # (folder, file, new content from the old, what the error says)
    "thesis-csv-cut-mid-row": ("thesis", "thesis_comparison.csv", _cut_mid_row, "is cut off"),
    "thesis-csv-row-short": ("thesis", "thesis_comparison.csv", _fewer_cells, "fewer cells than its header"),
    "thesis-csv-no-metric": ("thesis", "thesis_comparison.csv", lambda _: "scene,mode\ncornell,rcast\n",
                             "has no 'metric'"),
    "thesis-csv-empty": ("thesis", "thesis_comparison.csv", lambda _: "", "is empty"),
    "thesis-summary-list": ("thesis", "thesis_summary.json", lambda _: "[]\n", "not a tlm thesis summary"),
    "thesis-summary-per-item": ("thesis", "thesis_summary.json", lambda _: '{"per_item": 5}\n',
                                "'per_item' is 5, not a mapping"),
    "eq52-fits-text": ("scaling", "eq52.json", lambda _: '{"fits": "x"}\n', "'fits' is 'x', not a list"),
    "eq52-list": ("scaling", "eq52.json", lambda _: "[]\n", "not a tlm eq. 5.2 file"),
    "extreme-row-no-passed": ("extreme", "extreme.jsonl", lambda _: '{"case": 1}\n', "'passed'"),
    "sweep-points-number": ("sweep", "sweep.yaml", lambda t: yaml.safe_dump({**yaml.safe_load(t), "points": 5}),
                            "'points' is 5, not a list"),
    "evc-only-row-cut-off": ("evc", "rows.jsonl", lambda t: t[:len(t) // 2], "is cut off"),
    "evc-rows-empty": ("evc", "rows.jsonl", lambda _: "", "is empty"),
    "extreme-rows-empty": ("extreme", "extreme.jsonl", lambda _: "", "is empty"),
}


@pytest.mark.parametrize("case", list(DAMAGE))
def test_a_damaged_study_file_is_one_line_naming_it(studies, tmp_path, capsys, case):
    name, file, damage, says = DAMAGE[case]
    folder = _copy(studies, name, tmp_path)
    path = folder / file
    with open(path, newline="") as f:
        text = f.read()
    with open(path, "w", newline="") as f:
        f.write(damage(text))
    _refused(folder, file, says, capsys)


def test_a_sweep_point_without_its_results_is_not_ok(studies, tmp_path):
    folder = _copy(studies, "sweep", tmp_path)
    rows = [json.loads(line) for line in (folder / "sweep.jsonl").read_text().splitlines()]
    assert len(rows) == 2 and all(r["status"] == "ok" for r in rows)
    gone = folder / "points" / rows[1]["hash"] / "results.json"
    gone.unlink()
    assert main(["report", str(folder)]) == 0
    page = (folder / "report" / "report.html").read_text(encoding="utf-8")
    assert "(1 of 2 points ok" in page and "2 of 2 points ok" not in page
    assert f"its results.json is missing ({gone})" in page
    sweeps = page[page.index('<section id="sweeps">'):]
    assert "2 points, 1 failed" in sweeps[:sweeps.index("</section>")]


def test_a_damaged_ground_truth_is_a_warning_removed_and_rendered_again(cache, capsys):
    """A cut-off image.npy in $TLM_CACHE/oracle/<key>/ (fabricated: no Mitsuba needed)."""
    from tlm.oracle import mitsuba as om

    image = np.linspace(0.0, 1.0, 4 * 5 * 3).reshape(4, 5, 3)
    meta = {"scene": "x", "integrator": "path", "spp": 4, "width": 5, "height": 4}
    entry = om.save_ground_truth("k0", image, meta)
    got, got_meta = om.load_ground_truth("k0")
    assert np.allclose(got, image) and got_meta["key"] == "k0"
    npy = entry / "image.npy"
    npy.write_bytes(npy.read_bytes()[:50])
    capsys.readouterr()
    assert om.load_ground_truth("k0") is None
    err = capsys.readouterr().err
    assert err.startswith("tlm: warning: damaged Mitsuba ground-truth cache entry ") and err.count("\n") == 1
    assert str(npy) in err
    assert not entry.exists()
    om.save_ground_truth("k0", image, meta)  # computed again: the entry is written anew and read back
    assert np.allclose(om.load_ground_truth("k0")[0], image)
    (entry / "meta.json").unlink()  # half an entry would block the new one's write: removed as well
    assert om.load_ground_truth("k0") is None and not entry.exists()
    assert "meta.json" in capsys.readouterr().err
    om.save_ground_truth("k0", image, meta)  # bytes changed but still an array of that shape: its checksum says so
    raw = bytearray(npy.read_bytes())
    raw[-1] ^= 0x01
    npy.write_bytes(bytes(raw))
    assert om.load_ground_truth("k0") is None and "checksum differs" in capsys.readouterr().err
