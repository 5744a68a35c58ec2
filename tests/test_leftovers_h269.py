"""Six leftovers of the config and command-line side (h269).

1. ``storage.check_destination("")`` named the empty path as the ``'.'`` it becomes; now as given.
2. ``tlm.load_scene(..., base=...)`` took a ``base`` that is no folder (a built-in scene's name ignored it
   unsaid, a scene file's path was looked for nowhere); now refused, as ``tlm.load_config``'s.
3. A config or scene file was read whole, whatever it was: ``tlm run /dev/zero`` ran out of memory. A device
   is refused unread, a file over ``config.MAX_TEXT_BYTES`` by its size, a pipe read no further than that.
4. ``tlm run dd/`` (a folder) said ``the built-in experiment dd`` (``./my.yaml`` too: ``my.yaml``), then that
   it cannot read it; now one line: a folder, not a config file.
5. A sweep's ``sweep.yaml``, a point's ``config.resolved.yaml`` (``tlm scaling``, the report's labels and
   seeds) were read by ``yaml.safe_load``, with no bound on what their aliases expand to.
6. A numba whose llvmlite cannot load (an ``OSError``) made every command an internal error; now the
   kernels run on numpy, with one warning naming the cause.
"""

from __future__ import annotations

import builtins
import contextlib
import os
import resource
import subprocess
import sys
import threading
from pathlib import Path

import pytest

import tlm
from tlm import config, storage
from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments import scaling
from tlm.kernels import engine
from tlm.report import summary, tradeoff

ROOT = Path(__file__).resolve().parents[1]

# a document whose aliases expand it to 10**7 values: a few hundred bytes
BOMB = "".join(f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 10) if i else ', '.join(['x'] * 10)}]\n" for i in range(7))


def test_an_empty_destination_is_named_as_given():
    with pytest.raises(InputError, match=r"^--out: '' is the current folder \(an empty path\); name a new folder$"):
        storage.check_destination("", "results.json")


@pytest.mark.parametrize("what", ["missing", "file"])
def test_load_scene_refuses_a_base_that_is_no_folder(tmp_path, what):
    base = tmp_path / "nope"
    if what == "file":
        base.write_text("x")
    (tmp_path / "s.yaml").write_text("geometry:\n  - builder: cornell_box\n")
    for scene in ("cornell", "s.yaml"):
        with pytest.raises(InputError, match=r"^base: .* is not a folder \((not found|a file)\)"):
            tlm.load_scene(scene, base=base)
    assert tlm.load_scene("cornell", base=tmp_path).triangles.shape[0] > 0  # (a folder that is there: as before)


def test_a_device_is_refused_unread():
    with pytest.raises(InputError, match=r"^/dev/null: is a device, not a file to read"):
        tlm.load_config("/dev/null")


def test_dev_zero_is_one_line_not_out_of_memory(tmp_path):
    def limited():  # (the old read ran until this limit: out of memory, exit 1)
        resource.setrlimit(resource.RLIMIT_AS, (3 * 2**30, 3 * 2**30))

    done = subprocess.run([sys.executable, "-m", "tlm", "run", "/dev/zero"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, preexec_fn=limited, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 2, done.stderr
    assert done.stderr == "tlm: error: /dev/zero: is a device, not a file to read: name a YAML file\n"


def test_a_text_file_over_the_limit_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(config, "MAX_TEXT_BYTES", 1000)
    big = tmp_path / "big.yaml"
    big.write_text("scene: cornell\n" + "# padding\n" * 200)
    too_large = r"big.yaml: is too large to be a YAML file tlm reads \(2,015 bytes, at most 0 MiB\)"
    with pytest.raises(InputError, match=too_large):
        tlm.load_config(big)
    # under the limit: as Path.read_text gives it (universal newlines; a bad byte at its offset in the file)
    crlf = tmp_path / "crlf.yaml"
    crlf.write_bytes(b"a: 1\r\nb: 2\rc: 3\n")
    assert config.read_text(crlf) == "a: 1\nb: 2\nc: 3\n"
    bad = tmp_path / "bad.yaml"
    bad.write_bytes(b"#" * 900 + b"\xff")
    with pytest.raises(InputError, match=r"byte 0xff at offset 900"):
        config.read_text(bad)


def test_a_pipe_is_read_no_further_than_the_limit(tmp_path, monkeypatch):
    monkeypatch.setattr(config, "MAX_TEXT_BYTES", 1000)
    fifo = tmp_path / "p.yaml"
    os.mkfifo(fifo)

    def write():
        with open(fifo, "w") as f, contextlib.suppress(BrokenPipeError):
            f.write("scene: cornell\n" + "#" * 5000 + "\n")

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    with pytest.raises(InputError, match=r"p.yaml: is too large to be a YAML file tlm reads \(more than 0 MiB\)"):
        config.read_text(fifo)
    writer.join(10)


@pytest.mark.parametrize("given", ["dd/", "dd", "./dd"])
def test_a_folder_given_as_config_is_said_once(tmp_path, monkeypatch, capsys, given):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "dd").mkdir()
    assert main(["run", given]) == 2
    err = capsys.readouterr().err
    assert err == f"tlm: error: {given}: is a folder, not a config file: name a YAML file, or a built-in " \
                  "experiment ('tlm config list')\n"


def test_a_path_given_is_not_called_a_built_in_experiment(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "my.yaml").write_text("scene: cornell\nnosuchkey: 1\n")
    assert main(["run", "./my.yaml"]) == 2
    err = capsys.readouterr().err
    assert "built-in experiment" not in err and err.count("\n") == 1, err
    assert "nosuchkey" in err


def test_a_folder_given_to_the_api_is_no_file(tmp_path):
    (tmp_path / "dd").mkdir()
    with pytest.raises(InputError, match=r"dd: is a folder, not a file: name a YAML file$"):
        tlm.load_config(tmp_path / "dd")


def test_a_sweeps_yaml_is_read_with_its_aliases_bounded(tmp_path):
    from tlm.config_words import ExpansionError, safe_load

    assert safe_load("a: &a [1, 2]\nb: *a\n") == {"a": [1, 2], "b": [1, 2]}  # (a good file: as yaml.safe_load)
    with pytest.raises(ExpansionError, match="expand it to more than"):
        safe_load(BOMB)
    (tmp_path / "sweep.yaml").write_text(BOMB + "points: [{hash: abc}]\n")
    assert scaling.sweep_points(tmp_path) == ([], [])  # (refused: as a sweep.yaml that is no YAML, none listed)
    (tmp_path / "config.resolved.yaml").write_text(BOMB + "seed: 7\nscene: cornell\nmode: rcast\n")
    assert summary._base_seed(tmp_path) == f"the base of {tmp_path.name}"

    class Study:
        path = tmp_path

    assert tradeoff._gran_label(Study, "g") == "g"
    (tmp_path / "config.resolved.yaml").write_text("seed: 7\nscene: cornell\nmode: rcast\n")  # (good: as before)
    assert summary._base_seed(tmp_path) == "7" and tradeoff._gran_label(Study, "g") == "g (cornell/rcast)"


def test_a_points_config_whose_aliases_expand_is_a_bad_folder(tmp_path):
    (tmp_path / "sweep.jsonl").write_text('{"point": 0, "hash": "h0", "status": "ok"}\n')
    point = tmp_path / "points" / "h0"
    point.mkdir(parents=True)
    (point / "results.json").write_text("{}")
    (point / "config.resolved.yaml").write_text(BOMB)
    with pytest.raises(InputError, match=r"line 1: point 0: cannot read its folder \(.*expand it to more than"):
        scaling.collect(tmp_path)


def test_a_numba_that_cannot_load_falls_back_to_numpy(monkeypatch, capsys):
    monkeypatch.setenv(engine.SAID_BY, "")  # (none said yet; taken away after: it quiets the failure in children)
    real = builtins.__import__

    def no_llvmlite(name, *args, **kwargs):
        if name == "numba":
            raise OSError("Could not find/load shared object file 'libllvmlite.so'")
        return real(name, *args, **kwargs)

    cached = engine.numba_available.cache_info().currsize
    monkeypatch.delenv("TLM_KERNELS", raising=False)
    monkeypatch.setattr(builtins, "__import__", no_llvmlite)
    engine.numba_available.cache_clear()
    try:
        assert engine.engine() == "numpy"
        assert engine.engine() == "numpy"
    finally:
        monkeypatch.setattr(builtins, "__import__", real)
        engine.numba_available.cache_clear()
        if cached:
            engine.numba_available()
    err = capsys.readouterr().err
    assert err == ("tlm: warning: numba is installed but cannot load (OSError: Could not find/load shared object "
                   "file 'libllvmlite.so'): the kernels run on numpy (the same results, slower; TLM_KERNELS=numpy "
                   "says so without numba)\n")
