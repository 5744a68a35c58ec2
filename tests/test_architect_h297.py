"""An architect's findings (h297): report words on the tables, eq. 5.2 and the timeline.

4. The report's Tables I-III show errors against the thesis of hundreds of percent (Room PMap TVert +555%)
   with no reason or link: docs/fidelity.md "By cell" explains each kind of cell. The legend now points to it,
   by a link relative to the report folder where the docs are beside the package (a checkout), by name alone in
   an installed copy (the wheel ships no docs: no link that leads nowhere).
5. Eq. 5.2 fitted to N = 1 and one other N has two points for its two parameters A and B: it meets them
   exactly, and "largest |error| 0.0%" tested nothing. The caption and the legend say so.
2. A dynamic queue of tiles_per_pipeline x pipelines tiles (each key at most 4096) is at most 65536 tiles
   (config.MAX_TILES): more is refused by the config check, naming both keys, for a run and a sweep's point.
3. ``tlm params`` says a cache block's transfer is free (a block-size sweep measures locality alone).
Minor: the timeline's time axis at arch.clock_hz = 1 read "ms at 1e-06 MHz" with an offset of x1e10 on its
ticks: its time unit and the clock's are chosen by the clock now (years at 1 Hz, ms at 600 MHz);
arch.clock_hz = 0 said "must be > 0.0 and >= 1.0"; ``tlm params`` says how many memory modules a setting gives;
``tlm scaling`` says a fit of two N tests nothing.
"""

from __future__ import annotations

import html
import os
import re
from pathlib import Path

import pytest

from tests.test_report_big_sweeps import sweep_folder
from tests.test_review_h281 import _sweep
from tlm import api
from tlm.cli import main
from tlm.cli_tables import print_scaling
from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.report import tables
from tlm.report.collect import read
from tlm.report.cycles import cycles_unit, time_axis
from tlm.report.scaling import scaling_section
from tlm.report.tables import tables_section

# ------------------------------------------------------------------ 4: the tables point to fidelity.md


def _fidelity_line(page: str) -> str:
    lines = [p for p in re.findall(r'<p class="legend">(.*?)</p>', page, re.S) if "fidelity.md" in p]
    assert len(lines) == 1, page[:2000]
    return lines[0]


def test_the_tables_link_to_fidelity_by_cell_from_the_report_folder(tmp_path, monkeypatch):
    inputs = read([sweep_folder(tmp_path / "S")])  # (cornell points: Table III)
    real = tables.FIDELITY_DOC
    # (h302) a link only from a report folder inside the checkout: a checkout in tmp_path, not /work/main
    doc = tmp_path / "checkout" / "docs" / "fidelity.md"
    doc.parent.mkdir(parents=True)
    doc.write_text(real.read_text(encoding="utf-8"), encoding="utf-8")
    monkeypatch.setattr(tables, "FIDELITY_DOC", doc)
    out = tmp_path / "checkout" / "deep" / "report"
    out.mkdir(parents=True)
    line = _fidelity_line(tables_section(inputs, out).html)
    href = html.unescape(re.search(r'<a href="([^"]+)">docs/fidelity\.md, “By cell”</a>', line).group(1))
    file, _, part = href.partition("#")
    assert not os.path.isabs(file) and file == "../../docs/fidelity.md" and (out / file).resolve() == doc, href
    headings = re.findall(r"^#+ (.+)$", real.read_text(encoding="utf-8"), re.M)
    assert part == "by-cell" and "By cell" in headings  # (the anchor GitHub and Markdown viewers give it)


def test_an_installed_copy_names_the_page_without_a_dead_link(tmp_path, monkeypatch):
    monkeypatch.setattr(tables, "FIDELITY_DOC", tmp_path / "no-docs" / "fidelity.md")
    line = _fidelity_line(tables_section(read([sweep_folder(tmp_path / "S")]), tmp_path).html)
    assert "<a " not in line and "docs/fidelity.md, “By cell” in tlm's source" in line, line


# ------------------------------------------------------------------ 5: eq. 5.2 of two N tests nothing


def _caption(tmp_path: Path, name: str, ns: list[int]) -> str:
    out = tmp_path / f"{name}_report"
    out.mkdir()
    sec = scaling_section(read([_sweep(tmp_path / name, [(n, 12) for n in ns])]), out)
    (caption,) = [f.caption for f in sec.figures if f.file.startswith("scaling_")]
    return caption


def test_a_fit_of_two_values_of_n_says_its_zero_error_tests_nothing(tmp_path):
    two = _caption(tmp_path, "two", [1, 4])
    assert "static throughput 0.0% (N = 1 and 4 alone: exact by construction)" in two, two
    assert "A fit of two values of N tests nothing" in two, two
    three = _caption(tmp_path, "three", [1, 2, 4])  # (a third N: a test, its error said plainly)
    assert "exact by construction" not in three and "tests nothing" not in three, three
    assert re.search(r"static throughput \d+\.\d%[,.]", three), three


# ------------------------------------------------------------------ minor: the timeline's units


@pytest.mark.parametrize(("end", "clock", "unit", "length"), [
    (44e6, 600e6, "ms at 600 MHz", 44e6 / 600e3),  # (the thesis's clock: as before)
    (500, 600e6, "ns at 600 MHz", 500 / 0.6),
    (44e6, 1.0, "years at 1 Hz", 44e6 / (365.25 * 86400)),  # (was "ms at 1e-06 MHz", ticks x1e10)
    (7200, 1.0, "h at 1 Hz", 2.0),
    (44e6, 1e12, "µs at 1 THz", 44.0),
    (44e6, 2.5e3, "h at 2.5 kHz", 44e6 / 2.5e3 / 3600),
])
def test_the_timeline_takes_its_time_unit_and_clock_unit_from_the_clock(end, clock, unit, length):
    k, label = time_axis(end, clock)
    assert label == f"time ({unit})"
    assert end * k == pytest.approx(length)
    assert 1 <= end * k < 1000 or unit.startswith("years")  # (no offset on the ticks)


def test_cycle_axes_name_their_scale():
    assert cycles_unit(44e6) == (1e6, "million cycles")
    assert cycles_unit(5e4) == (1e3, "thousand cycles")
    assert cycles_unit(900) == (1.0, "cycles")


# ------------------------------------------------------------------ 2: a dynamic queue the model cannot run

BIG = {"pipelines": 4096, "tiles_per_pipeline": 4096, "scheduler": "dynamic"}
SAID = ("arch.tiles_per_pipeline: 4096 x arch.pipelines (4096) = 16777216 tiles in the dynamic queue, more than "
        "65536")


def test_a_dynamic_queue_past_its_cap_is_refused_naming_both_keys():
    """Each key alone at its cap of 4096 passed: 16.7 M tiles ran past 120 s and 3 GB, growing, writing nothing."""
    with pytest.raises(InputError) as e:
        config_from_dict({"arch": BIG}, "big.yaml")
    assert str(e.value) == f"big.yaml: {SAID}"
    assert config_from_dict({"arch": {**BIG, "tiles_per_pipeline": 16}}).arch.tiles_per_pipeline == 16  # (2**16)
    with pytest.raises(InputError, match=r"17 x arch.pipelines \(4096\) = 69632 tiles"):
        config_from_dict({"arch": {**BIG, "tiles_per_pipeline": 17}})
    assert config_from_dict({"arch": {**BIG, "scheduler": "static"}}).arch.pipelines == 4096  # (4096 tiles)


def test_tlm_run_of_such_a_queue_exits_2_before_any_work(tmp_path, capsys, monkeypatch):
    def ran(*_a, **_k):
        raise AssertionError("the run started")

    monkeypatch.setattr(api, "run", ran)
    sets = [x for k, v in BIG.items() for x in ("--set", f"arch.{k}={v}")]
    assert main(["run", "cornell", "--set", "resolution=[32,32]", *sets, "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.endswith(f"{SAID}\n") and err.count("tlm: error:") == 1, err
    assert not (tmp_path / "r").exists()


def test_a_sweep_with_such_a_point_is_refused_before_it_runs(tmp_path, capsys):
    spec = tmp_path / "tiles.yaml"
    spec.write_text("base: cornell\nset:\n  resolution: [32, 32]\n  arch.pipelines: 4096\n"
                    "  arch.tiles_per_pipeline: 4096\ngrid:\n  arch.scheduler: [static, dynamic]\n")
    assert main(["sweep", str(spec), "--dry-run", "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert f"(point 1: arch.scheduler=dynamic): {SAID}\n" in err and err.count("tlm: error:") == 1, err
    assert main(["sweep", str(spec), "--out", str(tmp_path / "s")]) == 2
    assert not (tmp_path / "s").exists()


# ------------------------------------------------------------------ 3 and minor: the parameters' words


def test_tlm_params_say_a_block_costs_nothing_to_transfer_and_how_many_modules():
    said = {key: text for key, _, text in api.params()}
    block = said["cache.block_words"]
    assert "transfer free" in block and "arch.page_miss_cycles at any size" in block and "locality" in block
    assert "the same at every cache.block_words: the block's transfer costs nothing" in said["arch.page_miss_cycles"]
    assert "memory modules: 2 x images_in_flight x pipelines" in said["arch.images_in_flight"]
    assert "x pipelines <= 65536" in said["arch.tiles_per_pipeline"]


def test_a_clock_of_zero_names_its_one_bound():
    with pytest.raises(InputError) as e:
        config_from_dict({"arch": {"clock_hz": 0}})
    assert str(e.value).endswith("arch.clock_hz: 0 must be >= 1.0"), str(e.value)


def test_tlm_scaling_says_a_fit_of_two_n_tests_nothing(tmp_path, capsys):
    fit = {"scene": "ring", "mode": "rcast", "scheduler": "static", "target": "throughput", "A": 1.0, "B": 1.0,
           "max_abs_rel_error": 0.0, "slowest": {"max_abs_rel_error": 0.0}}
    print_scaling({"notes": [], "fits": [{**fit, "pipelines": [1, 4]}, {**fit, "pipelines": [1, 2, 4]}]}, tmp_path)
    two, three = capsys.readouterr().out.splitlines()[1:3]
    assert two.endswith("(N = 1, 4 alone: two points fit A and B exactly, a test of nothing)"), two
    assert three.endswith("(N = 1, 2, 4)"), three
