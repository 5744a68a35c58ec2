"""h521: ``tlm --version`` says what identifies the code (the version, the git commit and whether the checkout is
modified, the code fingerprint ``results.json`` records), on one line, in a checkout and in an installed copy; and an
output folder of any name ``mkdir`` takes (231-255 bytes) is written, its hidden siblings (``.<name>.tlm-running``,
the temporary folder, ...) kept within NAME_MAX by a prefix of the name and a hash (:func:`tlm.storage.sibling_stem`),
still found by what cleans them up; a name past NAME_MAX is one line, exit 2."""

from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import tlm.experiments.run as run_mod
from tlm import claims, storage
from tlm.cli import main
from tlm.experiments import provenance
from tlm.fingerprint import fingerprint

REPO = Path(__file__).resolve().parents[1]
SMALL = ["--mode", "rcast", "--set", "resolution=[16,16]", "--set", "render.light_samples=1", "--no-progress",
         "--no-reference", "--no-report"]


def test_version_names_the_commit_and_the_code_on_one_line(capsys, monkeypatch):
    """In this checkout: ``git <commit>`` (``, modified`` where it differs from it), ``code <fingerprint>``, the
    same as results.json's keys; one line however narrow the terminal (argparse's own wraps it)."""
    monkeypatch.setenv("COLUMNS", "40")
    before = provenance.code_state()
    assert main(["--version"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and out.startswith("tlm "), out
    state = provenance.code_state()
    if state["git_revision"] is not None:  # (as results.json says it; a commit made meanwhile: either)
        said = {f"; git {st['git_revision']}{', modified' if st['git_modified'] else ''};" for st in (before, state)}
        assert any(s in out for s in said), (out, said)
    assert out.startswith(f"tlm {provenance.tlm_version()} (Python {sys.version.split()[0]}; "), out
    assert out.rstrip().endswith(f"; code {state['code_fingerprint']})"), out


def test_an_installed_copy_says_its_code_fingerprint(tmp_path):
    """A copy of the package outside any checkout (as installed): no commit, ``no git checkout``, and the code
    fingerprint, the same as the checkout's for the same code."""
    root = tmp_path / "site"
    shutil.copytree(REPO / "tlm", root / "tlm", ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "PYTHONPATH": str(root), "COLUMNS": "30"}
    done = subprocess.run([sys.executable, "-m", "tlm", "--version"], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("\n") == 1, done.stdout
    assert f"; no git checkout; code {fingerprint(root / 'tlm')})" in done.stdout, done.stdout


def name_max(folder: Path) -> int:
    """The most bytes a name may have in ``folder``."""
    return os.pathconf(folder, "PC_NAME_MAX")


def long_name(parent: Path, room: int = 0) -> str:
    """A name of NAME_MAX bytes in ``parent`` less ``room``."""
    return "x" * (name_max(parent) - room)


@pytest.mark.parametrize("room", [0, 13, 24])
def test_an_output_folder_of_a_long_name_is_written_and_written_again(tmp_path, room):
    """A folder named up to NAME_MAX bytes: claimed, written through its temporary sibling and swapped in, twice;
    every name beside it (the claim's, a leftover's) within NAME_MAX, and nothing left beside it at the end."""
    out = tmp_path / long_name(tmp_path, room)
    for n in range(2):
        with claims.claimed(out, "run"), storage.atomic_folder(out, "results.json", owned=()) as tmp:
            assert len(os.fsencode(tmp.name)) <= name_max(tmp_path)
            storage.write_file(tmp / "results.json", f'{{"n": {n}}}')
        assert (out / "results.json").read_text() == f'{{"n": {n}}}'
        assert os.listdir(tmp_path) == [out.name]
    file = tmp_path / ("f" * name_max(tmp_path))  # (a file of the longest name: its temporary file too)
    storage.write_file(file, "text")
    assert file.read_text() == "text"
    assert storage.claim_folder(tmp_path / ("c" * name_max(tmp_path)), "marker.json", "{}")


def test_the_siblings_of_long_names_stay_unique_and_their_leftovers_are_removed(tmp_path):
    """Two long names that share their first 240 bytes get two stems; a temporary folder a process now gone left
    beside a long name (its stem's) is removed by the next write of that folder."""
    a, b = tmp_path / ("y" * 240 + "a"), tmp_path / ("y" * 240 + "b")
    stems = storage.sibling_stem(a), storage.sibling_stem(b)
    assert stems[0] != stems[1] and all(len(s) + 1 + 80 <= name_max(tmp_path) for s in stems), stems
    assert storage.sibling_stem(tmp_path / "short") == "short"
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    left = tmp_path / f".{stems[0]}.tmp-{storage._host()}-{dead.pid}-0"
    left.mkdir()
    assert storage.stale_folders(tmp_path) == [left]
    with storage.atomic_folder(a, "results.json") as tmp:
        storage.write_file(tmp / "results.json", "{}")
    assert not left.exists() and os.listdir(tmp_path) == [a.name]


def test_a_long_folder_another_process_is_writing_is_refused(tmp_path, cache, elsewhere, monkeypatch, capsys):
    """The claim of a long-named folder held (its lock taken by another open file, as another process holds it):
    ``tlm run`` into it exits 2 before the render, naming the holder; a claim such a run leaves behind, its process
    gone, is removed (:func:`tlm.claims.drop_stale`)."""
    out = tmp_path / "o" / long_name(tmp_path, 3)
    out.parent.mkdir()
    path = out.parent / f".{storage.sibling_stem(out)}.tlm-running"
    held = os.open(path, os.O_RDWR | os.O_CREAT)
    try:
        fcntl.flock(held, fcntl.LOCK_EX)
        os.pwrite(held, f"{storage._host()}-4242".ljust(63).encode() + b"\n", 0)
        monkeypatch.setattr(run_mod, "render", lambda *a, **k: pytest.fail("the refused run rendered"))
        assert main(["run", "cornell", *SMALL, "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert "another run is writing into" in err[-1] and "(process 4242 on this machine, " in err[-1], err
    finally:
        os.close(held)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    os.pwrite(fd := os.open(path, os.O_RDWR), f"{storage._host()}-{dead.pid}".ljust(63).encode() + b"\n", 0)
    os.close(fd)
    assert claims.drop_stale(out) and not path.exists()


def test_a_name_past_name_max_is_one_line_exit_2(tmp_path, cache, elsewhere, capsys):
    """``--out`` of a name longer than the file system allows: one line naming it and the limit, exit 2."""
    out = tmp_path / long_name(tmp_path, -1)
    assert main(["run", "cornell", *SMALL, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    limit = name_max(tmp_path)
    assert err[-1].startswith("tlm: error: ") and f"past the {limit} this file system allows" in err[-1], err
    assert not os.listdir(tmp_path / "work") if (tmp_path / "work").is_dir() else True
