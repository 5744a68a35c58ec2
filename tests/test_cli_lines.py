"""The command line's printed lines: values as their YAML writes them, lists of N without
Python's brackets, one name per scene whatever else is fitted, every varied setting of an
error-vs-cost row, 3 significant figures of a run's frame rate, the real ``tlm reference``
command, fixed notation in the thesis's per-item table, and a run stopped at
``arch.max_events`` said as such, not as a deadlock."""

from __future__ import annotations

import re

import pytest
import yaml

from tests.test_model import SWAP_PROGRAM, arch
from tlm import api
from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.provenance import scene_identity
from tlm.experiments.scaling import fit_group, groups
from tlm.experiments.thesis import METRICS, describe_items, describe_rows
from tlm.scenes.loader import scenes_dir


def test_params_prints_each_default_as_its_yaml_reads_back(capsys):
    """``'cornell'``, ``None``, ``True``, ``600000000.0`` were Python's reprs (``None`` reads back as
    the text "None"); now ``cornell``, ``null``, ``true``, ``6.0e+08``, which YAML reads as the default."""
    assert main(["params"]) == 0
    lines = capsys.readouterr().out.splitlines()
    params = api.params()
    assert len(lines) == len(params)
    for line, (key, default, _) in zip(lines, params, strict=True):
        assert line.startswith(f"{key:24s} "), line
        shown = line[len(f"{key:24s} "):].lstrip().split("  ", 1)[0]
        back = yaml.safe_load(shown)
        assert type(back) is type(default) and back == default, (key, shown, default)
        assert not re.search(r"\bNone\b|\bTrue\b|\bFalse\b|'", shown), (key, shown)
    clock = next(line for line in lines if line.startswith("arch.clock_hz "))
    assert " 6.0e+08  " in clock, clock


def _fit(scene: str, target: str) -> dict:
    return {"scene": scene, "scene_file": None, "mode": "rcast", "scheduler": "static", "target": target,
            "A": 1.0, "B": 1.0, "max_abs_rel_error": 0.01, "slowest": {"max_abs_rel_error": 0.02},
            "pipelines": [1, 2, 4, 8, 16, 32, 64]}


def test_scaling_lines_say_n_without_brackets_in_columns_as_wide_as_the_longest_name(monkeypatch, capsys, tmp_path):
    fits = [_fit(s, t) for s in ("thesis/ring", "cornell") for t in ("latency", "throughput")]
    monkeypatch.setattr(api, "scaling", lambda dirs, out: {"fits": fits, "rows": [], "notes": []})
    assert main(["scaling", str(tmp_path / "sw"), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("  ")]
    assert len(lines) == 4
    assert all(line.endswith("(N = 1, 2, 4, 8, 16, 32, 64)") for line in lines), lines
    assert len({line.index(" rcast ") for line in lines}) == 1, lines  # (was {scene:8s}: thesis/ring pushed it)
    assert lines[0].startswith("  thesis/ring rcast ") and lines[2].startswith("  cornell     rcast ")


def test_values_text():
    from tlm.errors import values_text

    assert values_text([1, 2, 4]) == "1, 2, 4"
    assert values_text(range(1, 13)) == "1, 2, 3, ..., 12 (12 values)"


def _point(n: int, **kw) -> dict:
    return {"pipelines": n, "T_vert0": 100, "sum_max": 1000, "max_max": 1000 // n, "latency": 2000 // n,
            "throughput": 1000 // n, **kw}


@pytest.mark.parametrize(("ns", "said"), [
    ([1, 1, 2, 2], "have the same N (N = 1, 1, 2, 2)"),
    ([2], "needs at least two values of N, the group has N = 2"),
    ([2, 4], "fitted through N = 1, and the group has N = 2, 4"),
])
def test_eq52_errors_say_n_without_brackets(ns, said):
    with pytest.raises(InputError) as e:
        fit_group([_point(n) for n in ns], "throughput")
    assert said in str(e.value) and "[" not in str(e.value), str(e.value)


def _rec(source, n: int, name: str = "ring", ref: str | None = None) -> dict:
    return {"scene": name, "scene_file": str(source), "scene_id": scene_identity(source) if source.is_file() else None,
            "scene_ref": ref, "mode": "rcast", "scheduler": "static", "pipelines": n}


def test_eq52_names_a_scene_by_one_rule_whatever_else_is_fitted(tmp_path):
    """thesis/ring alone was 'ring' (its name inside the file), beside the built-in ring
    'thesis/ring': now 'thesis/ring' both ways, as the report names it; a file of another
    checkout's scenes folder by its built-in name too; a user's file by the path its config gave."""
    ring, thesis_ring = scenes_dir() / "ring.yaml", scenes_dir() / "thesis" / "ring.yaml"
    alone = [_rec(thesis_ring, n) for n in (1, 2)]
    assert list(groups(alone)) == [("thesis/ring", "rcast", "static")]
    both = alone + [_rec(ring, n) for n in (1, 2)]
    assert sorted(k[0] for k in groups(both)) == ["ring", "thesis/ring"]
    elsewhere = tmp_path / "checkout" / "scenes" / "thesis" / "ring.yaml"  # (not on this machine)
    assert list(groups([_rec(elsewhere, n) for n in (1, 2)])) == [("thesis/ring", "rcast", "static")]
    mine = tmp_path / "mine" / "ring.yaml"
    mine.parent.mkdir()
    mine.write_text(thesis_ring.read_text() + "# mine\n")
    assert list(groups([_rec(mine, n, ref="mine/ring.yaml") for n in (1, 2)])) == [("mine/ring.yaml", "rcast",
                                                                                    "static")]


def _items(value: float) -> dict:
    it = {"ours": {"trav_cycles_per_ray": value, "tests_per_ray": 3.25, "frag_cycles_per_pixel": 0.0123,
                   "vert_cycles_per_triangle": None},
          "thesis": {"trav_cycles_per_ray": 900.0, "tests_per_ray": None, "frag_cycles_per_pixel": 12.5,
                     "vert_cycles_per_triangle": 20.0},
          "rays": 256, "tests_per_leaf": 12345.6}
    return {"ring/rcast": it, "cornell/rcast": it}


def test_thesis_per_item_table_is_in_fixed_notation():
    text = describe_items(_items(21470.3))
    assert "e+" not in text and "e-" not in text, text
    assert " 21470 (    900.0)" in text and "0.01230 (    12.50)" in text and " 12346" in text, text


def test_thesis_tables_name_the_thesis_scenes_by_their_files(tmp_path):
    from tlm.experiments.thesis import scene_names  # (new)

    names = scene_names(["thesis/ring", "cornell"], tmp_path, str(tmp_path / "study.yaml"))
    assert names == {"ring": "thesis/ring", "cornell": "cornell"}
    items = describe_items(_items(1.0), names).splitlines()
    assert items[1].startswith("thesis/ring rcast ") and items[2].startswith("cornell     rcast "), items
    rows = [{"scene": s, "mode": "rcast", "metric": m, "thesis": 1.0, "ours": 1.0}
            for s in ("ring", "cornell") for m in METRICS]
    table = describe_rows(rows, names).splitlines()
    assert table[1].startswith("thesis/ring rcast ") and table[2].startswith("cornell     rcast "), table


def test_thesis_table_of_ours_is_in_fixed_notation():
    rows = [{"scene": "cornell", "mode": "rcast", "metric": m, "thesis": 14.0,
             "ours": 1586.63 if m == "FPS" else 0.0638} for m in METRICS]
    line = describe_rows(rows).splitlines()[1]
    assert "e+" not in line and "   1587 (    14)" in line and " 0.0638 (    14)" in line, line


def _evc_row(i: int, fps: float | None, factors: str) -> dict:
    return {"point": i, "factors": factors, "filter": "knn", "photons": 1000, "radius": 0.1, "k": None,
            "k_nearest": 8, "rel_mse": 0.5, "truth_rel_mse": None, "photons_tested": 100, "gather_seconds": 0.1,
            "fps": fps}


def test_error_vs_cost_lines_say_every_varied_setting_and_a_null_frame_rate(monkeypatch, capsys, tmp_path):
    """Two rows that differ in estimate.final_gather alone printed the same label; a null fps crashed."""
    rows = [_evc_row(0, None, "estimate.final_gather=0"), _evc_row(1, 0.25, "estimate.final_gather=16")]

    def error_vs_cost(config, out, truth_spp, progress, note):
        for i, row in enumerate(rows):
            progress(i, len(rows), row)
        return rows

    monkeypatch.setattr(api, "error_vs_cost", error_vs_cost)
    config = tmp_path / "evc.yaml"
    config.write_text("base: {}\n")
    assert main(["error-vs-cost", str(config), "--out", str(tmp_path / "o"), "--no-report"]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("  [")]
    assert len(lines) == 2 and lines[0].split("]", 1)[1] != lines[1].split("]", 1)[1], lines
    assert "simulated - fps" in lines[0] and "estimate.final_gather=0" in lines[0], lines
    assert "simulated 0.25 fps" in lines[1] and "estimate.final_gather=16" in lines[1], lines


def _run_results(fps: float) -> dict:
    return {"scene": {"name": "cornell", "triangles": 34, "resolution": [16, 16], "bsp": {"levels": 2, "leaves": 4}},
            "plan": {"run": [], "left_out": {}, "notes": []}, "work": {},
            "error": {"available": False, "reference": "0123abcd"},
            "cycles": dict.fromkeys(("vertex", "traversal", "intersection", "fragment", "throughput", "latency"), 1e6),
            "timing": {"frames": 1, "packet_size": 64, "clock_hz": 6e8}, "fps": fps, "warnings": []}


def test_run_says_fps_to_3_figures_and_the_reference_command_as_typed(monkeypatch, capsys, tmp_path):
    monkeypatch.setattr(api, "run", lambda cfg, out, **kw: _run_results(0.0504))
    assert main(["run", "cornell", "--out", str(tmp_path / "o"), "--no-report", "--mode", "pmap",
                 "--set", "photons.count=1000", "--no-reference"]) == 0
    out = capsys.readouterr().out
    assert "  0.0504 frames per second\n" in out, out
    assert ("no reference 0123abcd cached; compute it with: tlm reference cornell --set photons.count=1000 "
            "--set mode=pmap\n") in out, out


def test_a_run_stopped_at_max_events_says_so_not_deadlock():
    from tlm.arch.model import simulate_program
    from tlm.arch.units import MaxEventsReached

    with pytest.raises(MaxEventsReached) as e:
        simulate_program(SWAP_PROGRAM, arch(frames=3, max_events=5))
    said = str(e.value)
    assert said.startswith("stopped at arch.max_events = 5 events, the cap the config sets (raise it if the run "
                           "is only long), unfinished at cycle "), said
    assert "cannot finish" not in said


def test_thesis_progress_lines_give_fps_to_three_figures(monkeypatch, capsys, tmp_path):
    """``tlm thesis``' line per scene-mode: fps as ``tlm run`` prints it (3 figures; ``0.05`` was
    ``0.0503``), a frame of no cycles (fps null) as ``-`` (it raised a TypeError)."""
    from tlm import api
    from tlm.cli import main
    from tlm.errors import InputError

    def thesis(config, out, progress, bar):
        progress("cornell", "pmap", {"cycles": {"throughput": 11917411000}, "fps": 600e6 / 11917411000})
        progress("cornell", "rcast", {"cycles": {"throughput": 0}, "fps": None})
        raise InputError("stop here")

    monkeypatch.setattr(api, "thesis", thesis)
    assert main(["thesis", "thesis", "--out", str(tmp_path / "t"), "--no-report", "--no-progress"]) == 2
    out = capsys.readouterr().out
    assert "  cornell pmap: throughput 11917.41 M cycles, 0.0503 fps" in out, out
    assert "  cornell rcast: throughput 0.00 M cycles, - fps" in out, out
