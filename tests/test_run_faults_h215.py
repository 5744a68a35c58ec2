"""Faults around ``tlm run`` and ``tlm report`` (probe h207): a damaged numba cache entry, a
results.json of the wrong types, a lock's holder read before it wrote its record, what a
refused or failed report says, a signal once the run is in place, a traceback on a full disk."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests._subproc import held_claim, probe_copy
from tlm.errors import InputError
from tlm.report import collect

PROBE = """from tlm.kernels._numba_cache import njit


@njit(cache=True)
def probe(a, b):
    return a * 10.0 + b
"""


@pytest.mark.slow
def test_a_damaged_numba_cache_entry_is_named_removed_and_compiled_again(tmp_path):
    """A copy of the package with a cached probe kernel: its cache entry cut off, zeroed, its
    index overwritten. Each: a warning naming the file, the right answer, the entry written
    again (the next run is quiet). Before: ``UnpicklingError`` on every run, naming no file."""
    root, run_copy = probe_copy(tmp_path, PROBE, {"TLM_CACHE": str(tmp_path / "cache")})
    cache = root / "tlm" / "kernels" / "__pycache__"

    def run() -> str:
        done = run_copy()  # (its exit status 0 asserted there)
        assert done.stdout.strip() == "12.0"
        return done.stderr

    assert "warning" not in run()
    (data,) = cache.glob("_jit_probe.probe-*.nbc")
    (index,) = cache.glob("_jit_probe.probe-*.nbi")
    for damage, victim in ((lambda p: p.write_bytes(p.read_bytes()[:100]), data),
                           (lambda p: p.write_bytes(bytes(p.stat().st_size)), data),
                           (lambda p: p.write_bytes(p.read_bytes()[:40] + b"not a pickle" * 4), index)):
        damage(victim)
        err = run()
        said = [line for line in err.splitlines() if line.startswith("tlm: warning:")]
        assert len(said) == 1 and str(victim) in said[0] and "damaged" in said[0] and "compiled again" in said[0], err
        assert data.is_file() and index.is_file(), "the entry is written again"
        assert run() == "", "the entry written again loads"


# -- tlm report: a results.json of the wrong types ---------------------------------------------------------------

GOOD = {
    "tlm": "results/1", "mode": "refract", "overrides": ["resolution=[32,32]"],
    "scene": {"name": "cornell", "source": "/x/scenes/cornell.yaml", "triangles": 2604, "resolution": [32, 32],
              "bsp": {"levels": 7}},
    "work": {"rcast": {"primary_rays": 4096, "tri_tests": 355088, "tri_tests_per_ray": 86.7}},
    "photons": None,
    "cycles": {"vertex": 1448093, "traversal": 4972366, "intersection": 7510856, "fragment": 481612,
               "throughput": 8226108, "latency": 16452216},
    "fps": 72.9,
    "timing": {"frames": 5, "images_in_flight": 2, "frame_times": [], "pipelines": [],
               "units": {"xbar": {"T_norm": 7, "busy": 7, "idle_measured": True, "stall": {"swap": 0},
                                          "fractions": {"busy": 0.5}}}},
    "image": {"exposure": 3.4}, "error": None, "warnings": [],
}


def edited(key: str, value) -> dict:
    out = json.loads(json.dumps(GOOD))
    *path, last = key.split(".")
    at = out
    for k in path:
        at = at[k]
    at[last] = value
    return out


DAMAGE = [("cycles.throughput", "8226108"), ("scene", "x"), ("mode", "banana"), ("fps", math.nan),
          ("cycles.throughput", math.inf), ("cycles", None), ("timing", []), ("timing.units", None),
          ("work.rcast.tri_tests", -5), ("timing.units.xbar.busy", "7"), ("scene.resolution", [32]),
          ("image.exposure", -1), ("scene.name", {"a": 1})]


def write_run(folder: Path, results: dict) -> Path:
    folder.mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps(results))  # (NaN, Infinity: as json writes them)
    return folder


@pytest.mark.parametrize(("key", "value"), DAMAGE, ids=[f"{k}={v!r}" for k, v in DAMAGE])
def test_a_results_file_of_the_wrong_types_is_named_and_its_run_left_out(tmp_path, key, value):
    """Before: a TypeError, AttributeError or ValueError in a section (the whole report down), or
    a report with no note for NaN, Infinity, a null, a negative count."""
    write_run(tmp_path / "runs" / "good", GOOD)
    write_run(tmp_path / "runs" / "untimed", {**GOOD, "cycles": None, "fps": None, "timing": None})  # (all three)
    bad = write_run(tmp_path / "runs" / "bad", edited(key, value))
    with pytest.raises(InputError) as e:
        collect._run(bad, "", "run")
    assert str(bad / "results.json") in str(e.value)
    inputs = collect.read([tmp_path / "runs"])
    assert sorted(r.path.name for r in inputs.runs) == ["good", "untimed"]
    assert len(inputs.damaged) == 1 and str(bad / "results.json") in inputs.damaged[0]
    assert "left out" in inputs.damaged[0]


# -- tlm run --out X twice at once: the holder named though its record is not written yet ------------------------

HOLD = """import fcntl, os, sys, time
fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT)
fcntl.flock(fd, fcntl.LOCK_EX)  # (its record not written: as a holder between its flock and its write)
print("held", flush=True)
time.sleep(60)
"""


def test_a_claims_holder_that_has_not_written_its_record_is_named(tmp_path):
    """Before: ``another run is writing into 'c2' (process ?)``, the holder's record read empty."""
    from tlm import claims

    out = tmp_path / "c2"
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(tmp_path / ".c2.tlm-running")], stdout=subprocess.PIPE,
                              text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(InputError) as e, claims.claimed(out, "run"):
            pass
        said = str(e.value)
        assert f"(process {holder.pid} on this machine, " in said and "process ?" not in said, said
        assert " -c " in said and "python" in said, said  # (its command line, as lock_holder shows it)
    finally:
        holder.kill()
        holder.wait()


# -- tlm report DIR while a run's report holds DIR/report; a full disk as a run's report is written -----------------

def test_tlm_report_dir_refused_for_its_report_folder_names_dir_not_out(tmp_path):
    """Before: ``tlm: error: --out: another report is writing into 'c3/report'``, no --out given."""
    from tlm.cli_report import report_claimed

    fd = held_claim(tmp_path / "c3" / "report")
    try:
        with pytest.raises(InputError) as e, report_claimed(tmp_path / "c3" / "report", of=str(tmp_path / "c3")):
            pass
        said = str(e.value)
        assert said.startswith(f"{tmp_path / 'c3'}: another report is writing into its report folder "), said
        assert "--out:" not in said and said.endswith("or give another folder with --out"), said
        with pytest.raises(InputError) as e, report_claimed(tmp_path / "c3" / "report"):  # (--out given: as before)
            pass
        assert str(e.value).startswith("--out: another report is writing into "), e.value
    finally:
        os.close(fd)


def test_a_full_disk_during_a_runs_report_says_the_run_is_kept_whole(tmp_path, monkeypatch):
    """Before: ``tlm: error: .../report: cannot write: no space left on device`` alone."""
    import argparse

    from tlm import api, cli_report
    from tlm.errors import EnvironmentFailure

    out = tmp_path / "c3"
    out.mkdir()

    def full(*a, **k):
        raise EnvironmentFailure("cannot write: no space left on device", source=str(out / "report"))

    monkeypatch.setattr(api, "write_report", full)
    args = argparse.Namespace(no_report=False, formats=None, dpi=None)
    with pytest.raises(EnvironmentFailure) as e:
        cli_report.report_after(args, out, "the run", "results.json and its files")
    said = str(e.value)
    assert said.startswith(f"{out / 'report'}: cannot write: no space left on device; "), said
    assert f"the run in {out} is kept, whole (results.json and its files)" in said, said
    assert said.endswith(f"write it with: tlm report {out}"), said
    assert e.value.source == str(out / "report")


# -- a signal once the run is in place, before its report (tlm/cli.py: /tmp/h215/cli.patch) ----------------------

@pytest.mark.parametrize("no_report", [False, True])
def test_a_signal_after_the_run_is_in_place_says_it_is_kept(tmp_path, cache, monkeypatch, capsys, no_report):
    """``print_run`` interrupted (the run swapped in, its report not begun). Before: a bare ``tlm: interrupted``."""
    from tlm import api, cli

    out = tmp_path / "c4"

    def ran(cfg, out, **k):
        out.mkdir()
        (out / "results.json").write_text(json.dumps(GOOD))
        return GOOD

    def printed(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(api, "run", ran)
    monkeypatch.setattr(cli, "print_run", printed)
    argv = ["run", "cornell", "--set", "resolution=[32,32]", "--out", str(out), *(["--no-report"] * no_report)]
    assert cli.main(argv) == 130
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith("tlm: interrupted") and f"the run in {out} is kept, whole (results.json and its files)" \
        in last, last
    assert ("tlm report" in last) != no_report, last
    assert (out / "results.json").is_file()


def test_a_traceback_that_cannot_be_written_leaves_no_empty_file(tmp_path, monkeypatch):
    """A full disk: the traceback's file made (O_EXCL), its write failing (tlm/cli_signals.py:
    /tmp/h215/cli_signals.patch). Before: a 0-byte tlm-traceback-*.txt left in each folder."""
    import errno
    import tempfile

    from tlm import cli_signals

    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()

    class Full:
        def __init__(self, fd, *a, **k):
            self.fd = fd

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            os.close(self.fd)

        def write(self, text):
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(cli_signals.os, "fdopen", Full)
    try:
        raise RuntimeError("boom")
    except RuntimeError as e:
        assert cli_signals.save_traceback(e) is None
    assert list(tmp_path.rglob("tlm-traceback-*")) == []


def test_an_interrupt_a_c_extension_made_an_error_of_after_the_run_says_it_is_kept(tmp_path, monkeypatch):
    """kept_whole caught a KeyboardInterrupt alone: a Ctrl-C that a C extension turned into an error of its own
    (tlm.errors.interrupted_by) as the run's lines were printed gave a bare 'tlm: interrupted'."""
    import argparse

    from tlm import cli_report, errors
    from tlm.cli_signals import Interrupted

    monkeypatch.setattr(cli_report, "interrupted_by", lambda e: e if isinstance(e, TypeError) else None)
    args = argparse.Namespace(no_report=True)
    with pytest.raises(Interrupted, match="is kept, whole"), cli_report.kept_whole(args, tmp_path, "the run", "f"):
        raise TypeError("could not export nb::ndarray: ... KeyboardInterrupt")
    with pytest.raises(ValueError), cli_report.kept_whole(args, tmp_path, "the run", "f"):  # (a real bug: raised)
        raise ValueError("a bug")
    assert errors.interrupted_by(ValueError("a bug")) is None
