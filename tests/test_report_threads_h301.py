"""h301: two reports written at once from two threads of one process draw what each draws alone.

:func:`tlm.write_report` (:func:`tlm.report.build_report`) called from several threads at once drew
some figures wrong, or failed: matplotlib parses and measures text through state every thread shares
(mathtext's one parser and its cache of parsed labels, which hold the parsing thread's fonts), so a
tick label parsed by two threads at once came out wrong ("10^6" drawn as "0^6", a stray "1"), the
constrained layout sized from it left a legend over an axis label, or FreeType failed ("failed to
load glyph", "raster overflow"). Now a report's figures are drawn by one report at a time in a
process (:data:`tlm.report.DRAWING`), and each report's PNG files are those it writes alone, byte
for byte. The lock is released by a report that raised half way (a later report in another thread
would otherwise wait for ever), and a report written from inside another's drawing, in its thread,
does not wait for itself.

The race shows where a label is parsed for the first time in the process: the test empties the text
caches before the reports in threads (the first reports of a notebook meet them empty).
"""

from __future__ import annotations

import threading
from pathlib import Path

import pytest
import yaml

import tlm.report as report
from tlm.cli import main
from tlm.report import build_report
from tlm.report.common import Section, _text_size

# a sweep over N = 1, 2 of a tiny Cornell box: its report draws tables, scaling, idle, cycles, peers, summary figures
BASE = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False}}
THREADS = 3
WAIT_S = 300  # (a report that waits for a lock no one will release fails the test, not the suite)


def _quiet(line: str) -> None:
    pass


def _empty_text_caches() -> None:
    """Forget every label parsed and measured (matplotlib's mathtext cache, the report's sizes)."""
    from matplotlib.mathtext import MathTextParser

    clear = getattr(MathTextParser._parse_cached, "cache_clear", None)
    if clear is not None:
        clear()
    _text_size.cache_clear()


def _catch(raised: list, call) -> None:
    """``call()``; what it raised, into ``raised``."""
    try:
        call()
    except BaseException as e:  # (said by the test)
        raised.append(e)


def _in_thread(call) -> list:
    """Run ``call`` in a new thread; what it raised, if anything (a thread still waiting fails)."""
    raised: list = []
    t = threading.Thread(target=_catch, args=(raised, call), daemon=True)
    t.start()
    t.join(WAIT_S)
    assert not t.is_alive(), "a report waited for ever for the figures' lock"
    return raised


def _pngs(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*.png"))}


@pytest.mark.slow
def test_reports_in_threads_write_the_pngs_each_writes_alone(tmp_path, cache, monkeypatch):
    (tmp_path / "n.yaml").write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.pipelines": [1, 2]}}))
    sweep = tmp_path / "sweep"
    assert main(["sweep", str(tmp_path / "n.yaml"), "--out", str(sweep), "--jobs", "1", "--no-progress",
                 "--no-report"]) == 0
    build_report([sweep], tmp_path / "alone", note=_quiet)
    alone = _pngs(tmp_path / "alone")
    assert len(alone) >= 6

    # a report that raises half way, in this thread, leaves the lock to the next report in another
    with monkeypatch.context() as mp:
        def boom(inputs, out):
            raise RuntimeError("half way")

        mp.setattr(report, "section_makers", lambda: (boom,))
        with pytest.raises(RuntimeError, match="half way"):
            build_report([sweep], tmp_path / "raised", note=_quiet)
    assert not (tmp_path / "raised").exists()

    # a report written from inside another's drawing, in the same thread: no wait for itself
    with monkeypatch.context() as mp:
        inner: list = []  # (the inner report's sections: none, its summary alone)

        def nest(inputs, out):
            inner.append("begun")
            inner.append(build_report([sweep], tmp_path / "inner", note=_quiet))
            return Section("nest", "A report written from inside this one", absent="a test's")

        mp.setattr(report, "section_makers", lambda: () if inner else (nest,))
        assert _in_thread(lambda: build_report([sweep], tmp_path / "outer", note=_quiet)) == []
    assert inner[-1].is_file() and (tmp_path / "outer" / "report.html").is_file()

    _empty_text_caches()
    raised: list = []
    threads = [threading.Thread(target=_catch, args=(raised, lambda i=i: build_report(
        [sweep], tmp_path / f"thread{i}", note=_quiet)), daemon=True) for i in range(THREADS)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(WAIT_S)
    assert not any(t.is_alive() for t in threads), "a report waited for ever for the figures' lock"
    assert raised == []
    for i in range(THREADS):
        drawn = _pngs(tmp_path / f"thread{i}")
        assert sorted(drawn) == sorted(alone)
        assert [name for name in alone if drawn[name] != alone[name]] == [], f"thread {i}"

