"""A config read once, and ``tlm sweep`` checking ``--out`` before it speaks (h285).

1. ``tlm run <(cat configs/cornell.yaml)`` (and a named FIFO) failed with ``is empty``: ``tlm.api.load_config``
   read the file twice (once to tell a scene file from a run config, once to load it), ``tlm run`` up to three
   times more, and every YAML read peeked at the file's first 4 KiB for a mesh's magic first: a pipe's text
   was gone by the read that parsed it. ``tlm sweep`` and ``tlm thesis`` of a pipe failed alike (the peek).
   Now the text is read once and parsed from memory; the peek is of a regular file alone.
2. ``tlm sweep`` said its warnings (``render.threads`` past the CPUs, ...) before it checked ``--out``, and
   ``tlm run SCENE.yaml`` its note on the scene file: a bad ``--out`` is now its one line, nothing before it.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from pathlib import Path

import pytest

from tlm import api, config
from tlm.cli import main

ROOT = Path(__file__).resolve().parents[1]
CONFIG = (ROOT / "configs" / "cornell.yaml").read_text()
SWEEP = "base: {scene: cornell, mode: rcast, resolution: [16, 16]}\ngrid:\n  arch.fifo_depth: [1, 2]\n"
THESIS = "scenes: [cornell]\nmodes: [rcast]\nbase: {resolution: [16, 16]}\n"

needs_dev_fd = pytest.mark.skipif(not os.path.isdir("/dev/fd"), reason="no /dev/fd here")


@pytest.fixture
def piped():
    """``piped(text)``: a path that reads as ``<(printf ... )`` does, ``/dev/fd/N`` of a pipe holding ``text``
    whose writer closed (a second open of it finds the pipe empty, as the shell's does)."""
    fds = []

    def make(text: str) -> str:
        r, w = os.pipe()
        fds.append(r)
        os.write(w, text.encode())  # (a few hundred bytes: within the pipe's buffer)
        os.close(w)
        return f"/dev/fd/{r}"

    yield make
    for fd in fds:
        os.close(fd)


@needs_dev_fd
def test_load_config_of_a_pipe(piped):
    cfg = api.load_config(piped(CONFIG), {"resolution": [16, 16]})
    assert cfg.scene == "cornell" and cfg.resolution == (16, 16) and not cfg.scene_file


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_load_config_of_a_named_fifo(tmp_path):
    fifo = tmp_path / "c.yaml"
    os.mkfifo(fifo)

    stop = threading.Event()

    def write():  # (its text to the first reader; nothing to any later one, as a shell's `cat c.yaml > fifo`)
        text = CONFIG
        while not stop.is_set():
            with open(fifo, "w") as f, contextlib.suppress(BrokenPipeError):
                f.write(text)
            text = ""

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    try:
        cfg = api.load_config(fifo, ["resolution=[16,16]"])
    finally:  # (the writer's next open let through, and it stops)
        stop.set()
        deadline = time.monotonic() + 10
        while writer.is_alive() and time.monotonic() < deadline:
            os.close(os.open(fifo, os.O_RDONLY | os.O_NONBLOCK))
            writer.join(0.05)
    assert cfg.scene == "cornell" and cfg.resolution == (16, 16)


def test_a_config_file_is_read_once(tmp_path, monkeypatch, capsys):
    path = tmp_path / "c.yaml"
    path.write_text(CONFIG)
    seen = []
    read = config.read_bytes  # (the one read of a text file tlm reads whole: read_text's, read_yaml's)
    monkeypatch.setattr(config, "read_bytes", lambda p: seen.append(str(p)) or read(p))
    api.load_config(path)
    assert seen.count(str(path)) == 1  # (was 2: the scene file's test, then the load)
    seen.clear()
    (tmp_path / "afile").write_text("")
    assert main(["run", str(path), "--out", str(tmp_path / "afile")]) == 2
    assert seen.count(str(path)) == 1  # (was 3)


@needs_dev_fd
def test_tlm_run_of_a_pipe_reaches_its_out(tmp_path, piped, capsys):
    (tmp_path / "afile").write_text("")
    assert main(["run", piped(CONFIG), "--out", str(tmp_path / "afile"), "--set", "resolution=[16,16]"]) == 2
    out, err = capsys.readouterr()
    assert (out, err) == ("", f"tlm: error: --out: '{tmp_path / 'afile'}' exists and is not a folder\n")


@needs_dev_fd
def test_a_scene_file_given_as_a_pipe_is_said_so(tmp_path, piped, capsys):
    pipe = piped((ROOT / "scenes" / "cornell.yaml").read_text())
    assert main(["run", pipe, "--out", str(tmp_path / "r")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1  # (was `/proc/PID/fd/pipe:[N]: file not found`)
    assert err.startswith(f"tlm: error: {pipe}: is a scene file given as a pipe, a device or a deleted file (a "
                          "here-document's), which a render reads again")
    assert not (tmp_path / "r").exists()


@needs_dev_fd
def test_a_piped_config_names_files_from_the_working_folder(piped, monkeypatch):
    monkeypatch.chdir(ROOT)  # (a pipe, /proc/PID/fd/pipe:[N], is in no folder: its paths were typed here)
    cfg = api.load_config(piped("scene: cornell\narch: {programs: tlm/arch/programs.yaml}\n"))
    assert (cfg.arch.programs, cfg.base) == (str(ROOT / "tlm" / "arch" / "programs.yaml"), ROOT)


@needs_dev_fd
@pytest.mark.parametrize("base", ["{scene: cornell, mode: rcast, resolution: [16, 16]}", "configs/cornell.yaml"])
def test_tlm_sweep_of_a_pipe(tmp_path, piped, capsys, cache, monkeypatch, base):
    monkeypatch.chdir(ROOT)  # (a base file named from the working folder, where the pipe's text was typed)
    sweep = SWEEP.replace(SWEEP.splitlines()[0], f"base: {base}")
    assert main(["sweep", piped(sweep), "--out", str(tmp_path / "sw"), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "2 points: 0 done already (skipped), 2 to run" in out  # (was: must be a mapping with description, ...)
    assert not (tmp_path / "sw").exists()


@needs_dev_fd
def test_tlm_thesis_of_a_pipe_reaches_its_out(tmp_path, piped, capsys):
    (tmp_path / "afile").write_text("")
    assert main(["thesis", piped(THESIS), "--out", str(tmp_path / "afile")]) == 2
    out, err = capsys.readouterr()  # (was: must be a mapping with base, scenes, modes: the study's text gone)
    assert (out, err) == ("", f"tlm: error: --out: '{tmp_path / 'afile'}' exists and is not a folder\n")


@pytest.mark.parametrize("bad", ["a file", "a folder of no tlm output"])
def test_a_sweep_checks_its_out_before_its_warnings(tmp_path, capsys, cache, bad):
    sweep = tmp_path / "s.yaml"
    sweep.write_text(SWEEP)
    out = tmp_path / "out"
    if bad == "a file":
        out.write_text("")
        line = f"tlm: error: --out: '{out}' exists and is not a folder\n"
    else:
        out.mkdir()
        (out / "mine.txt").write_text("")
    # (a --set that no point reads: a warning of the sweep's, said on the old code before --out was checked)
    assert main(["sweep", str(sweep), "--out", str(out), "--set", "photons.count=1000"]) == 2
    said, err = capsys.readouterr()
    assert said == "" and err.count("\n") == 1 and err.startswith(f"tlm: error: --out: '{out}'"), err
    if bad == "a file":
        assert err == line
    assert out.is_file() or [p.name for p in out.iterdir()] == ["mine.txt"]  # (nothing written in it)


def test_a_run_of_a_scene_file_checks_its_out_before_its_note(tmp_path, capsys):
    (tmp_path / "afile").write_text("")
    assert main(["run", str(ROOT / "scenes" / "cornell.yaml"), "--out", str(tmp_path / "afile")]) == 2
    out, err = capsys.readouterr()  # (was: the note "... is a scene file: rendering it ..." on stdout first)
    assert (out, err) == ("", f"tlm: error: --out: '{tmp_path / 'afile'}' exists and is not a folder\n")
