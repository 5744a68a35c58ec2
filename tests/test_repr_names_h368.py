"""A message that quotes a path or a name the user gave (``'dir_\\xff/out' exists and is not a folder``) shows a byte
of a name not UTF-8 as ``\\xff``, as the rest of a ``tlm:`` line, stdout and a CSV cell show it (docs/usage.md,
"Commands tlm prints, and file names of bytes not UTF-8"), not as Python's ``repr`` writes the surrogate it is read
as, ``'dir_\\udcff/out'`` (probe h352): :func:`tlm.errors.quoted`, in place of ``{path!r}``."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

from tlm.api_common import shown
from tlm.render.checks import light_name

REPO = Path(__file__).resolve().parents[1]
DIR = os.fsdecode(b"dir_\xff")  # (dir_\udcff)
SHOWN = "dir_\\xff"  # (what a tlm: line shows of it)


def _tlm(args: list, cwd: Path) -> subprocess.CompletedProcess:
    """``python -m tlm ARGS`` in ``cwd`` (its arguments as bytes: a name not UTF-8 as it is on disk)."""
    env = {**os.environ, "TLM_CACHE": str(cwd / "cache"), "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-m", "tlm", *args], cwd=cwd, env=env, capture_output=True,
                          timeout=300, check=False)


def _err(done: subprocess.CompletedProcess) -> str:
    err = done.stderr.decode("utf-8")  # (UTF-8 text: the byte is escaped, not written)
    assert done.returncode == 2, err
    assert "\\udc" not in err and "Traceback" not in err, err
    return err


def test_quoted_shows_a_byte_as_a_tlm_line_does():
    from tlm.errors import quoted

    assert quoted(f"{DIR}/out") == f"'{SHOWN}/out'" and quoted(Path(DIR)) == f"'{SHOWN}'"
    assert quoted([DIR]) == f"['{SHOWN}']" and quoted("it's") == '"it\'s"' and quoted(3) == "3"
    # (a folder literally named with a backslash is as repr writes it, told from the byte)
    assert quoted("dir_\\udcff") == "'dir_\\\\udcff'" and quoted("a\\" + DIR) == f"'a\\\\{SHOWN}'"
    assert quoted("a\tb") == "'a\\tb'" and quoted("\ud800") == "'\\ud800'"
    assert shown(Path(DIR)) == f"'{SHOWN}'" and shown(DIR) == f"'{SHOWN}'"
    assert light_name(0, SimpleNamespace(kind="point", name=DIR)) == f"lights[0] (point '{SHOWN}')"


def test_an_output_folder_not_utf8_refused(tmp_path):
    folder = tmp_path / DIR
    folder.mkdir()
    (folder / "afile").write_text("x")
    (folder / "notout").mkdir()
    (folder / "notout" / "mine.txt").write_text("x")
    cfg = str(REPO / "configs" / "cornell.yaml")
    err = _err(_tlm(["run", cfg, "--out", os.fsencode(folder / "afile")], tmp_path))
    assert f"--out: '{tmp_path}/{SHOWN}/afile' exists and is not a folder" in err
    err = _err(_tlm(["run", cfg, "--out", b"dir_\xff/notout"], tmp_path))
    assert f"--out: '{SHOWN}/notout' exists and is not an earlier tlm output" in err
    err = _err(_tlm(["run", cfg, "--out", b"dir_\xff/afile/sub"], tmp_path))
    assert f"'{SHOWN}/afile/sub' cannot be made: '{tmp_path}/{SHOWN}/afile' is a file, not a folder" in err
    assert (folder / "notout" / "mine.txt").read_text() == "x" and not (folder / "afile" / "sub").exists()


def test_a_config_file_a_base_and_a_set_not_utf8(tmp_path):
    (tmp_path / DIR).mkdir()
    err = _err(_tlm(["config", "export", "cornell", b"dir_\xff/none/x.yaml"], tmp_path))
    assert f"{SHOWN}/none/x.yaml: folder '{SHOWN}/none' does not exist" in err
    (tmp_path / "sw.yaml").write_text('base: "dir_\\udcff"\ngrid:\n  render.spp: [1, 2]\n', encoding="utf-8")
    err = _err(_tlm(["sweep", "sw.yaml", "--out", "o", "--no-progress"], tmp_path))
    assert f"sw.yaml: base: '{SHOWN}' is a folder: name a run config file" in err and not (tmp_path / "o").exists()
    err = _err(_tlm(["run", str(REPO / "configs" / "cornell.yaml"), "--set", b"dir_\xff"], tmp_path))
    assert f"--set: '{SHOWN}' is not of the form dotted.key=value" in err


# files of other helpers' at h368, whose paths shown with {str(...)!r} were theirs to change (none since h370)
LEFT: set[str] = set()


def test_no_path_of_str_or_fspath_shown_with_repr():
    """A path made text to be quoted (``{str(out)!r}``, ``{os.fspath(path)!r}``) is quoted by
    :func:`tlm.errors.quoted`, which shows a byte not UTF-8 as ``\\xff``, not by ``repr``."""
    found = []
    for file in sorted((REPO / "tlm").rglob("*.py")):
        name = file.relative_to(REPO).as_posix()
        if name in LEFT:
            continue
        for node in ast.walk(ast.parse(file.read_text(encoding="utf-8"))):
            if not (isinstance(node, ast.FormattedValue) and node.conversion == ord("r")):
                continue
            call = node.value
            if isinstance(call, ast.Call) and ast.unparse(call.func) in ("str", "os.fspath"):
                found.append(f"{name}:{node.lineno}: {{{ast.unparse(call)}!r}}")
    assert not found, "\n".join(found)
