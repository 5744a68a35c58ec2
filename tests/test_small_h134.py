"""Small defects: a factor that leaves the cycles as they are splits no eq. 5.2 fit, a ``.glb``
whose header says a few bytes more than its whole chunks hold loads (with a note), ``tlm
report``'s progress bar, and the report's tables write each column's numbers in one notation."""

from __future__ import annotations

import json
import os
import re
import struct
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml

from tlm.errors import InputError
from tlm.experiments.scaling import fit, record

ROOT = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------ 1: eq. 5.2 and no-effect factors


def _config(n: int, trace: bool) -> dict:
    return {"scene": "cornell", "mode": "rcast", "seed": 0, "resolution": [16, 16],
            "arch": {"pipelines": n, "scheduler": "static", "trace": trace}}


def _results(n: int, extra: int = 0) -> dict:
    per = {"traversal": 9000 // n, "intersection": 12000 // n, "fragment": 3000 // n}
    return {"scene": {"name": "cornell"}, "timing": {"pipelines": [per] * n},
            "cycles": {**per, "vertex": 1000, "latency": 2000 + 12000 // n + extra, "throughput": 1000 + 12000 // n}}


def _records(extra: dict | None = None) -> list[dict]:
    """A grid of N and arch.trace (as a sweep's collect reads it); ``extra``: latency added at (N, trace)."""
    return [{**record(_results(n, (extra or {}).get((n, t), 0)), _config(n, t)), "sweep": "runs/sc",
             "factors": {"arch.pipelines": n, "arch.trace": t}}
            for n in (1, 2, 4) for t in (False, True)]


def test_a_grid_of_n_and_arch_trace_is_one_fit_one_point_per_n():
    notes: list[str] = []
    fits = fit(_records(), notes)
    assert set(fits) == {("cornell", "rcast", "static", "latency"), ("cornell", "rcast", "static", "throughput")}
    rows = fits[("cornell", "rcast", "static", "latency")]["rows"]
    assert [r["pipelines"] for r in rows] == [1, 2, 4]
    assert [r["simulated"] for r in rows] == [14000, 8000, 5000]
    assert notes == []  # (their cycles agree: nothing to say)


def test_points_of_one_n_whose_cycles_disagree_are_fitted_once_with_a_note():
    notes: list[str] = []
    fits = fit(_records({(2, True): 50}), notes)
    rows = fits[("cornell", "rcast", "static", "latency")]["rows"]
    assert [(r["pipelines"], r["simulated"]) for r in rows] == [(1, 14000), (2, 8000), (4, 5000)]  # (the first)
    (note,) = notes
    assert note.startswith("runs/sc (cornell/rcast/static): N = 2: 2 points differ only in keys that leave the "
                           "cycles as they are (arch.trace = false, true), yet their cycles disagree "
                           "(latency = 8000, 8050)")
    assert "fitted from the first (arch.pipelines = 2, arch.trace = false, runs/sc)" in note
    # points of one N that differ in a key that changes the cycles are still refused, naming it
    recs = _records()
    recs[3]["settings"] = {**recs[3]["settings"], "arch.page_miss_cycles": "100"}
    with pytest.raises(InputError, match=r"have the same N \(N = 1, 2, 2, 4\): they differ in arch\.page_miss_cycles"):
        fit(recs)


def _fake_sweep(folder: Path, factors: dict[str, list], row: Callable[[dict], dict]) -> Path:
    """A finished sweep folder over the grid ``factors`` (no render): each point's row is ``row(factors)``."""
    import itertools

    (folder / "points").mkdir(parents=True)
    spec = {"tlm": "sweep/1", "grid": factors, "zip": {}, "points": []}
    rows = []
    for i, values in enumerate(itertools.product(*factors.values())):
        fac = dict(zip(factors, values, strict=True))
        h = f"{i:016x}"
        n = fac.get("arch.pipelines", 1)
        spec["points"].append({"point": i, "hash": h, "factors": fac})
        rows.append({"point": i, "hash": h, "status": "ok", "error": None, **fac, "scene": "cornell",
                     "mode": "rcast", **row(fac)})
        cfg = {"scene": "cornell", "mode": "rcast", "seed": 0,
               "arch": {"pipelines": n, "scheduler": "static", "trace": fac.get("arch.trace", False)}}
        (folder / "points" / h).mkdir()
        (folder / "points" / h / "results.json").write_text(json.dumps(_results(n)))
        (folder / "points" / h / "config.resolved.yaml").write_text(yaml.safe_dump(cfg))
    (folder / "sweep.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


def _scaling_row(fac: dict) -> dict:
    n = fac["arch.pipelines"]
    return {"cycles.throughput": 1000 + 12000 // n, "idle.vertex": 0.1 * n, "idle.traversal": 0.0, "fps": 100.0 * n}


def test_the_reports_idle_figures_of_a_grid_of_n_and_arch_trace_are_one(tmp_path):
    from tlm.report.collect import read
    from tlm.report.scaling import idle_points

    sw = _fake_sweep(tmp_path / "sw", {"arch.pipelines": [1, 2, 4], "arch.trace": [False, True]}, _scaling_row)
    notes: list[str] = []
    groups = idle_points(read([sw]).sweeps[0], notes)
    assert {k: [p["pipelines"] for p in g["points"]] for k, g in groups.items()} == {("cornell", "rcast"): [1, 2, 4]}
    assert notes == []


# ------------------------------------------------------------------ 2: a .glb header a few bytes long


def _box_glb() -> bytes:
    trimesh = pytest.importorskip("trimesh")
    return trimesh.creation.box().export(file_type="glb")


def _with_length(data: bytes, total: int) -> bytes:
    return data[:8] + struct.pack("<I", total) + data[12:]


def test_a_glb_header_4_bytes_long_with_whole_chunks_loads_with_a_note(tmp_path):
    from tlm.scenes.meshes import load_mesh

    whole = _box_glb()
    assert struct.unpack_from("<I", whole, 8)[0] == len(whole)
    expected = load_mesh(_write(tmp_path / "whole.glb", whole)).triangles
    for extra in (4, 7):  # (a writer that rounded the length up; padding lost past the last chunk)
        path = _write(tmp_path / f"long{extra}.glb", _with_length(whole, len(whole) + extra))
        geom = load_mesh(path)
        assert geom.triangles.tolist() == expected.tolist()
        (note,) = geom.notes
        assert note == (f"{path}: the binary glTF header's length says {len(whole) + extra:,} bytes, the file has "
                        f"{len(whole):,} and its chunks are whole (the last ends at the file's end): read by its "
                        "chunks, as glTF libraries read it; glTF 2.0 wants the header's length to be the file's "
                        f"(fix it: write {len(whole):,} in bytes 8 to 11, little-endian, or export the file again)")
    # a chunk cut (the file cut by 4 bytes), or a whole chunk's head missing (8 bytes or more): truncated
    for name, data in (("cut.glb", whole[:-4]), ("long8.glb", _with_length(whole, len(whole) + 8))):
        path = _write(tmp_path / name, data)
        with pytest.raises(InputError, match=re.escape(f"{path}: the binary glTF file is truncated: its header says "
                                                       f"{struct.unpack_from('<I', data, 8)[0]:,} bytes, the file "
                                                       f"has {len(data):,}")):
            load_mesh(path)


def _write(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


# ------------------------------------------------------------------ 3: the report's progress bar

# runs the command given as its arguments with stderr a terminal of 100 columns; prints (exit status, stderr)
ON_A_TERMINAL = r"""
import fcntl, os, pty, struct, subprocess, sys, termios
master, slave = pty.openpty()
fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
p = subprocess.Popen(sys.argv[1:], stdin=slave, stdout=subprocess.DEVNULL, stderr=slave)
os.close(slave)
got = b""
while True:
    try:
        chunk = os.read(master, 4096)
    except OSError:
        break
    if not chunk:
        break
    got += chunk
sys.stdout.write(repr((p.wait(), got.decode("utf-8", "replace"))))
"""
BUILD = "import sys; from pathlib import Path; import tlm.report as R; " \
        "R.build_report([Path(sys.argv[1])], Path(sys.argv[2]), progress=sys.argv[3] == 'on')"


def _stderr_on_a_terminal(argv: list[str]) -> str:
    """What ``argv`` wrote on stderr, a terminal; it must end with exit status 0."""
    out = subprocess.run([sys.executable, "-c", ON_A_TERMINAL, *argv], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=300, check=True)
    rc, err = eval(out.stdout)  # (the repr of a tuple of an int and a str)
    assert rc == 0, err
    return err


def _has_the_bar(err: str) -> bool:
    return all(re.search(rf"report: {step}: +\d+%\|.*\| +\d+/12 \[00:\d\d\]", err)
               for step in ("read", "tables", "scaling", "cycles", "provenance", "summary", "page"))


@pytest.mark.skipif(sys.platform == "win32", reason="a pseudo-terminal")
def test_the_report_draws_a_bar_on_a_terminal_only_when_asked(tmp_path):
    sw = _fake_sweep(tmp_path / "sw", {"arch.pipelines": [1, 2]}, _scaling_row)
    err = _stderr_on_a_terminal([sys.executable, "-c", BUILD, str(sw), str(tmp_path / "on"), "on"])
    assert _has_the_bar(err), err[-400:]
    assert _stderr_on_a_terminal([sys.executable, "-c", BUILD, str(sw), str(tmp_path / "off"), "off"]) == ""
    # not a terminal: nothing, the bar asked for or not
    done = subprocess.run([sys.executable, "-c", BUILD, str(sw), str(tmp_path / "pipe"), "on"], capture_output=True,
                          text=True, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=300, check=True)
    assert done.stderr == ""


@pytest.mark.skipif(sys.platform == "win32", reason="a pseudo-terminal")
def test_tlm_report_draws_its_bar_unless_no_progress(tmp_path):
    sw = _fake_sweep(tmp_path / "sw", {"arch.pipelines": [1, 2]}, _scaling_row)
    tlm_report = [sys.executable, "-m", "tlm", "report", str(sw), "--out"]
    assert _has_the_bar(_stderr_on_a_terminal([*tlm_report, str(tmp_path / "on")]))
    assert _stderr_on_a_terminal([*tlm_report, str(tmp_path / "off"), "--no-progress"]) == ""


def test_the_bar_counts_every_section():
    from tlm.report import SECTIONS, section_makers

    assert len(section_makers()) == SECTIONS


# ------------------------------------------------------------------ 4: one notation per column

SCIENTIFIC = re.compile(r"^-?\d(\.\d+)?e[+-]\d\d$")


def _one_notation(cells: list[str]) -> bool:
    numbers = [c for c in cells if re.fullmatch(r"-?[\d.]+(e[+-]\d\d)?", c)]
    return all(SCIENTIFIC.match(c) for c in numbers) or not any("e" in c for c in numbers)


def test_column_texts_chooses_one_notation_per_column():
    from tlm.report.sweep_lines import column_texts

    assert column_texts([340000, 1.2e6, 2e9, 5e10]) == ["3.4e+05", "1.2e+06", "2e+09", "5e+10"]
    assert column_texts([0.2348, 1381.0, 34528.4]) == ["0.2348", "1381", "34528"]
    assert column_texts([0.05, 0.0503, 0.0]) == ["0.05", "0.0503", "0"]
    assert column_texts([1e-5, 0.5]) == ["1e-05", "5e-01"]
    assert column_texts([1, 16, None, True], str) == ["1", "16", "None", "True"]  # (whole numbers as they are)


def test_the_sweep_table_writes_each_column_in_one_notation(tmp_path):
    from tlm.report.collect import read
    from tlm.report.sweeps import table

    fps = {340000: 0.2348, 1.2e6: 0.8287, 2e9: 1381.2, 5e10: 34528.4}
    sw = _fake_sweep(tmp_path / "sw", {"arch.clock_hz": list(fps)}, lambda fac: {
        "fps": fps[fac["arch.clock_hz"]], "cycles.throughput": 1448093, "cycles.vertex": 1,
        "seconds.functional": 51.31, "seconds.simulate": 0.00004})
    html = table(read([sw]).sweeps[0])
    rows = [re.findall(r"<t[dh]>(.*?)</t[dh]>", r) for r in re.findall(r"<tr>(.*?)</tr>", html)]
    head, body = rows[0], rows[1:]
    columns = {h: [r[i] for r in body] for i, h in enumerate(head)}
    assert columns["arch.clock_hz"] == ["3.4e+05", "1.2e+06", "2e+09", "5e+10"]
    assert columns["FPS"] == ["0.2348", "0.8287", "1381", "34528"]
    assert all(_one_notation(cells) for cells in columns.values()), columns


def test_the_per_item_table_writes_each_column_in_one_notation():
    from tlm.report.tables import per_item_html

    items = {f"s{i}/rcast": {"rays": 1000, "tests_per_leaf": leaf,
                             "ours": {"trav_cycles_per_ray": t, "tests_per_ray": 3.0, "frag_cycles_per_pixel": 2.0,
                                      "vert_cycles_per_triangle": v},
                             "thesis": {"trav_cycles_per_ray": t * 2, "tests_per_ray": 3.5,
                                        "frag_cycles_per_pixel": 2.5, "vert_cycles_per_triangle": v}}
             for i, (t, v, leaf) in enumerate([(12.5, 345.6, 0.05), (20.0, 12345.6, 0.0000503)])}
    html = per_item_html("th", items)
    body = [re.findall(r"<td>(.*?)</td>", r) for r in re.findall(r"<tr><th>s\d/rcast</th>(.*?)</tr>", html)]
    vert = [c for r in body for c in r[4].replace("(", "").replace(")", "").split()]
    assert vert == ["345.6", "345.6", "12,350", "12,350"]  # (4 significant digits, separated: h545)
    assert [r[5] for r in body] == ["5e-02", "5.03e-05"]
    for i in range(len(body[0])):
        assert _one_notation([c for r in body for c in r[i].replace("(", "").replace(")", "").split()])
