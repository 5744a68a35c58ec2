"""A command interrupted while it computes a photon-map reference says that its rounds are kept (h461).

Since h454 an interrupted reference's finished cycles are saved in ``references/<key>.partial.npz`` and the next
compute resumes from them; but ``tlm run``, ``tlm reference`` or ``tlm error-vs-cost`` Ctrl-C'd (or SIGTERMed)
during it said only ``tlm: interrupted``: the user could not know the minutes spent were kept. Now the line says
how many rounds the file holds and that the same command resumes from there, or that none were saved yet (none
this command would resume: rounds of cycles of another length are not its own). A signal at another time of the
command (a render) keeps its own line. The in-process tests send the signal from ``reference_round`` (through
the command's own handler); the subprocess ones send it once the file is there.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import tlm.experiments.reference as reference
import tlm.experiments.run as run_mod
from tlm.cli import main
from tlm.experiments.reference_cache import partial_info, partial_rounds

REPO = Path(__file__).resolve().parents[1]
# cycles of 2 rounds, at most 6 of them; a tolerance no cycle meets
REF = {"photons": 500, "k_nearest": 8, "tolerance": 1e-9, "min_rounds": 2, "max_rounds": 12, "spp": 2}
BASE = {"scene": "cornell", "mode": "pmap", "resolution": [4, 4], "photons": {"count": 500}, "reference": REF}
SAID = {signal.SIGINT: "tlm: interrupted", signal.SIGTERM: "tlm: terminated (SIGTERM)"}
NONE_SAVED = ("while computing the reference, before its first rounds were saved: the same command computes it "
              "from round 1")


def _config(tmp_path: Path, **ref) -> Path:
    path = tmp_path / "ref.yaml"
    path.write_text(json.dumps({**BASE, "reference": {**REF, **ref}}))
    return path


def _signal_at(monkeypatch, at: int, sig: int) -> list[int]:
    """``reference_round`` counted, the process sent ``sig`` at call ``at`` (the command's handler raises it)."""
    real, calls = reference.reference_round, []

    def counted(*a, **k):
        calls.append(1)
        if len(calls) == at:
            os.kill(os.getpid(), sig)
        return real(*a, **k)

    monkeypatch.setattr(reference, "reference_round", counted)
    return calls


def _partial(cache: Path) -> Path:
    (path,) = (cache / "references").glob("*.partial.npz")
    return path


def _kept(sig: int, path: Path, rounds: int) -> str:
    return (f"{SAID[sig]} while computing the reference: its {rounds} rounds are kept in {path}; "
            f"run the same command to resume from round {rounds}")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_tlm_reference_interrupted_says_its_rounds_are_kept_and_resumes(sig, cache, tmp_path, monkeypatch, capsys):
    cfg = _config(tmp_path)
    _signal_at(monkeypatch, 7, sig)  # (rounds 1-6: cycles 1-3 finished and saved; round 7 starts cycle 4)
    assert main(["reference", str(cfg), "--no-progress"]) == 128 + sig
    path = _partial(cache)
    assert partial_rounds(partial_info(path)) == 6
    assert capsys.readouterr().err.strip().splitlines()[-1] == _kept(sig, path, 6)
    calls = _signal_at(monkeypatch, 0, sig)  # (no signal: the same command resumes from round 6)
    assert main(["reference", str(cfg), "--no-progress"]) == 1  # (not converged: the tolerance is out of reach)
    assert len(calls) == 6 and "resuming from round 6" in capsys.readouterr().out
    assert not path.exists()


def test_tlm_reference_interrupted_before_its_first_save_says_none_are_kept(cache, tmp_path, monkeypatch, capsys):
    _signal_at(monkeypatch, 1, signal.SIGINT)
    assert main(["reference", str(_config(tmp_path)), "--no-progress"]) == 130
    assert capsys.readouterr().err.strip().splitlines()[-1] == f"tlm: interrupted {NONE_SAVED}"
    assert not list((cache / "references").glob("*.partial.npz"))


def test_rounds_the_same_command_does_not_resume_are_not_said_kept(cache, tmp_path, monkeypatch, capsys):
    """Rounds saved in cycles of another length (``reference.spp``) stay in the file, but the same command
    computes from round 1: interrupted before its own first save, it says none are saved."""
    _signal_at(monkeypatch, 7, signal.SIGINT)
    assert main(["reference", str(_config(tmp_path)), "--no-progress"]) == 130
    path = _partial(cache)
    assert partial_rounds(partial_info(path)) == 6
    capsys.readouterr()
    _signal_at(monkeypatch, 2, signal.SIGINT)  # (cycles of 3 rounds: none finished)
    assert main(["reference", str(_config(tmp_path, spp=3)), "--no-progress"]) == 130
    out, err = capsys.readouterr()
    assert "not resuming from round 6" in out
    assert err.strip().splitlines()[-1] == f"tlm: interrupted {NONE_SAVED}"
    assert partial_rounds(partial_info(path)) == 6  # (still the earlier compute's)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_tlm_run_interrupted_as_its_reference_is_computed_says_its_rounds_are_kept(sig, cache, tmp_path,
                                                                                   monkeypatch, capsys):
    out = tmp_path / "runs" / "r"
    _signal_at(monkeypatch, 5, sig)
    assert main(["run", str(_config(tmp_path)), "--out", str(out), "--no-report", "--no-progress"]) == 128 + sig
    path = _partial(cache)
    assert capsys.readouterr().err.strip().splitlines()[-1] == _kept(sig, path, 4)
    assert not out.exists()


def test_a_run_interrupted_elsewhere_keeps_its_own_line(cache, tmp_path, monkeypatch, capsys):
    """Rounds saved by an earlier compute, and a signal as the run renders (before its reference): its line is
    the bare one."""
    cfg, out = _config(tmp_path), tmp_path / "runs" / "r"
    _signal_at(monkeypatch, 7, signal.SIGINT)
    assert main(["run", str(cfg), "--out", str(out), "--no-report", "--no-progress"]) == 130
    path = _partial(cache)
    assert partial_rounds(partial_info(path)) == 6
    assert capsys.readouterr().err.strip().splitlines()[-1] == _kept(signal.SIGINT, path, 6)
    real = run_mod.render

    def render(*a, **k):
        os.kill(os.getpid(), signal.SIGINT)
        return real(*a, **k)

    monkeypatch.setattr(run_mod, "render", render)
    assert main(["run", str(cfg), "--out", str(out), "--no-report", "--no-progress"]) == 130
    assert capsys.readouterr().err.strip() == "tlm: interrupted"


def test_tlm_error_vs_cost_interrupted_as_its_reference_is_computed(cache, tmp_path, monkeypatch, capsys):
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({"base": {k: v for k, v in BASE.items() if k != "mode"},
                               "points": [{"estimate.filter": ["disk"]}]}))
    _signal_at(monkeypatch, 9, signal.SIGTERM)
    out = tmp_path / "evc"
    assert main(["error-vs-cost", str(exp), "--out", str(out), "--truth-spp", "0", "--no-report"]) == 143
    path = _partial(cache)
    assert capsys.readouterr().err.strip().splitlines()[-1] == _kept(signal.SIGTERM, path, 8)


def _signalled_once_saved(tmp_path: Path, cache: Path, sig: int, *command: str) -> tuple[int, str]:
    """``tlm COMMAND`` in a process of its own, sent ``sig`` once its reference's rounds are saved (polled for):
    its exit status and stderr."""
    env = {**os.environ, "TLM_CACHE": str(cache), "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, "-m", "tlm", *command], cwd=tmp_path, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120  # (a hang guard, not a timing)
        while proc.poll() is None and time.monotonic() < deadline and not list(cache.glob("references/*.partial.npz")):
            time.sleep(0.02)
        assert proc.poll() is None, "the command ended before its rounds were saved"
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, err


@pytest.mark.slow
@pytest.mark.parametrize(("sig", "command"), [(signal.SIGINT, "reference"), (signal.SIGTERM, "run")],
                         ids=["reference-SIGINT", "run-SIGTERM"])
def test_a_command_signalled_once_its_rounds_are_saved(sig, command, cache, tmp_path):
    cfg = _config(tmp_path, max_rounds=10000)  # (rounds until the signal)
    args = [command, str(cfg), "--no-progress"] + (["--out", str(tmp_path / "r"), "--no-report"] if command == "run"
                                                   else [])
    status, err = _signalled_once_saved(tmp_path, cache, sig, *args)
    path = _partial(cache)
    rounds = partial_rounds(partial_info(path))  # (what the file holds as the command ended)
    assert status == 128 + sig and rounds >= 2
    assert err.strip().splitlines()[-1] == _kept(sig, path, rounds), err
