"""h286: a report reads each of its inputs' files once, and the report's YAML loader is config_words'.

1. One ``tlm report`` of a ``tlm scaling`` folder read the sweep it was fitted from (its ``sweep.yaml`` and
   ``sweep.jsonl``) six times: once as an input (:func:`tlm.report.collect.read`), then once per check of
   whether the study's fit still shows the sweep (:func:`tlm.experiments.scaling.sweep_points`, from
   ``fitted_sweeps``, ``fit_sources`` and the summary). Now once a report (:class:`tlm.report.once.Reads`, on
   the report's ``Inputs``: the next report, in the same process, reads them again).
2. ``tlm.report.checks`` had its own PyYAML SafeLoader with the alias check (``_Safe``), a copy of
   :func:`tlm.config_words.safe_load`'s: read_yaml now uses that.
"""

from __future__ import annotations

import builtins
import io
import os
from collections import Counter
from pathlib import Path

import yaml

import tlm.config_words as config_words
import tlm.report.checks as checks
from tests.test_report_leftovers import CORNELL, pipelines_sweep
from tlm.cli import main
from tlm.report import build_report
from tlm.report.collect import read
from tlm.report.once import Reads, reading
from tlm.report.scaling import scaling_section


def _fitted(tmp_path: Path) -> tuple[Path, Path]:
    """A sweep over N = 1, 2, 4 (``sweep``) and the ``tlm scaling`` folder fitted from it (``eq``)."""
    sweep = pipelines_sweep(tmp_path / "sweep", [(n, "cornell", CORNELL, "cornell") for n in (1, 2, 4)])
    assert main(["scaling", str(sweep), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    return sweep, tmp_path / "eq"


def _opens(monkeypatch, under: Path) -> Counter:
    """The files under ``under`` opened from now on, counted by their resolved paths (``open`` and
    ``Path.read_text``, which opens with ``io.open``)."""
    seen: Counter = Counter()
    real = io.open
    root = str(under.resolve())

    def counted(file, *args, **kwargs):
        if isinstance(file, (str, os.PathLike)) and str(Path(file).resolve()).startswith(root):
            seen[Path(file).resolve()] += 1
        return real(file, *args, **kwargs)

    monkeypatch.setattr(io, "open", counted)
    monkeypatch.setattr(builtins, "open", counted)
    return seen


def _sweep_reads(seen: Counter, sweep: Path) -> dict[str, int]:
    return {name: seen[(sweep / name).resolve()] for name in ("sweep.yaml", "sweep.jsonl")}


def test_a_report_of_a_scaling_study_reads_its_sweeps_files_once(tmp_path, monkeypatch):
    sweep, eq = _fitted(tmp_path)
    seen = _opens(monkeypatch, tmp_path / "sweep")
    build_report([eq], tmp_path / "rep")
    assert _sweep_reads(seen, sweep) == {"sweep.yaml": 1, "sweep.jsonl": 1}  # (was 6 and 6)
    points = [p for p in seen if p.name in ("results.json", "config.resolved.yaml")]
    assert len(points) == 6 and all(seen[p] == 1 for p in points), seen  # (each point's files once, as before)


def test_the_scaling_section_of_the_study_and_its_sweep_reads_the_sweeps_files_once(tmp_path, monkeypatch):
    """The sweep an input too (its points' results here are eq. 5.2's alone: §3 only, as build_report calls it)."""
    sweep, eq = _fitted(tmp_path)
    seen = _opens(monkeypatch, tmp_path / "sweep")
    inputs = read([eq, sweep])
    (tmp_path / "rep").mkdir()
    with reading(inputs.reads):
        sec = scaling_section(inputs, tmp_path / "rep")
    assert any("shown through that fit" in n for n in sec.notes), sec.notes  # (the study's fit shows the sweep)
    assert _sweep_reads(seen, sweep) == {"sweep.yaml": 1, "sweep.jsonl": 1}  # (was 3 and 3)


def test_each_report_of_one_process_reads_the_files_again(tmp_path, monkeypatch):
    """What one report read is not kept for the next (write_report from a notebook, a sweep run again
    between two reports): two reports, two reads of each file; the second sees the sweep as it is then."""
    sweep, eq = _fitted(tmp_path)
    seen = _opens(monkeypatch, tmp_path / "sweep")
    build_report([eq], tmp_path / "rep1")
    assert "out of date" not in (tmp_path / "rep1" / "report.html").read_text()
    rows = (sweep / "sweep.jsonl").read_text().splitlines(keepends=True)
    (sweep / "sweep.jsonl").write_text("".join(rows[:-1]))  # (N = 4 unfinished now: the fit is out of date)
    seen.clear()
    build_report([eq], tmp_path / "rep2")
    assert _sweep_reads(seen, sweep) == {"sweep.yaml": 1, "sweep.jsonl": 1}
    assert "out of date: its sweep" in (tmp_path / "rep2" / "report.html").read_text()


def test_reads_reads_a_file_again_once_it_changed(tmp_path):
    """Keyed by the resolved path and its stat: the same file through another path is read once; a file
    written meanwhile is read again."""
    (tmp_path / "d").mkdir()
    path = tmp_path / "d" / "sweep.yaml"
    path.write_text("points: []\n")
    reads = Reads()
    first = reads(path)
    assert first == {"points": []}
    assert reads(tmp_path / "d" / ".." / "d" / "sweep.yaml") is first  # (the same file: not read again)
    path.write_text("points: [{hash: abc}]\n")
    assert reads(path) == {"points": [{"hash": "abc"}]}
    rows = tmp_path / "d" / "sweep.jsonl"
    rows.write_text('{"hash": "abc", "status": "ok"}\n')
    assert reads(rows) == [(1, {"hash": "abc", "status": "ok"})]
    assert Reads()(rows) is not reads(rows)  # (another report: its own reads)


def test_reading_sets_sweep_points_reader_for_its_length_alone(tmp_path):
    import tlm.experiments.scaling as eq52

    reads = Reads()
    with reading(reads):
        assert eq52.SWEEP_READ.get() is reads
    assert eq52.SWEEP_READ.get() is not reads  # (after the report: as before it, tlm scaling's own reads)


def test_read_yaml_reads_with_config_words_loader_where_libyaml_does_not(tmp_path, monkeypatch):
    """read_yaml's PyYAML parser (no libyaml, or a file nested past C_DEPTH) is config_words.safe_load's
    loader, the alias check in one place (was a copy, checks._Safe)."""
    used = []
    real = yaml.load

    def load(text, Loader):
        used.append(Loader)
        return real(text, Loader=Loader)

    monkeypatch.setattr(yaml, "load", load)
    monkeypatch.setattr(checks, "_C_LOADER", None)
    path = tmp_path / "config.resolved.yaml"
    path.write_text("a: &a [1, 2]\nb: *a\n")
    assert checks.read_yaml(path) == {"a": [1, 2], "b": [1, 2]}
    assert used == [config_words._CheckedSafeLoader]
    assert not hasattr(checks, "_Safe")
