"""tlm's readers read its files as UTF-8, whatever the locale's encoding; a piped mesh is told by its bytes as read.

1. The files tlm writes are UTF-8 (:func:`tlm.storage.write_atomic`); those it reads back were read in the
   locale's encoding, so that a non-ASCII string in one (a host name, a path, a scene name, a comment) failed
   under ``LC_ALL=C PYTHONUTF8=0 PYTHONCOERCECLOCALE=0`` (or a Latin-1 locale): ``tlm scaling`` refused a sweep
   (``cannot read its folder ('ascii' codec can't decode ...)``), or lost its plan quietly; a study's list of
   its own files (``.tlm-files``) read as no list, so that a rerun replaced the user's files in its folder
   too; ``git rev-parse --show-toplevel`` of a checkout in a non-ASCII folder raised. A check of tlm's source
   keeps a text-mode read or write without an encoding out (/proc's and a control group's files aside).
2. A binary STL piped to ``tlm run`` whose bytes are UTF-8 holding ``\\r\\n`` pairs was parsed as YAML: its
   newlines were made ``\\n`` before the mesh check saw its size.
"""

from __future__ import annotations

import ast
import json
import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from tlm.cli import main

REPO = Path(__file__).resolve().parents[1]
# a process whose locale's encoding is ASCII: no C.UTF-8 coercion, no UTF-8 mode
C_LOCALE = {"LC_ALL": "C", "LANG": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0", "PYTHONIOENCODING": "ascii"}
HOST = "Jürgen's Rechner — ü"  # (a host name, a comment, a path: anything a user's tool may write in UTF-8)


def _c_locale(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, **C_LOCALE, "TLM_CACHE": str(cwd / "cache")}
    env.pop("LC_CTYPE", None)
    return subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, timeout=300, check=False)


def _config(n: int) -> dict:
    return {"scene": "cornell", "mode": "rcast", "seed": 0, "resolution": [16, 16],
            "arch": {"pipelines": n, "scheduler": "static", "page_miss_cycles": 0}}


def _results(n: int, host: str) -> dict:
    per = {"traversal": 9000 // n, "intersection": 12000 // n, "fragment": 3000 // n}
    return {"scene": {"name": "cornell"}, "host": host, "timing": {"pipelines": [per] * n},
            "cycles": {"vertex": 1000, **per, "latency": 2000 + 12000 // n, "throughput": 1000 + 12000 // n}}


def _sweep(folder: Path, host: str = HOST) -> Path:
    """A sweep folder over N = 1, 2, 4 (without rendering) whose files hold ``host`` (non-ASCII text), in UTF-8."""
    (folder / "points").mkdir(parents=True)
    spec = {"tlm": "sweep/1", "points": []}
    rows = []
    for i, n in enumerate((1, 2, 4)):
        h = f"{i:016x}"
        spec["points"].append({"point": i, "hash": h, "factors": {"arch.pipelines": n}})
        rows.append({"point": i, "hash": h, "status": "ok", "error": None, "arch.pipelines": n, "host": host})
        (folder / "points" / h).mkdir()
        (folder / "points" / h / "results.json").write_text(json.dumps(_results(n, host), ensure_ascii=False),
                                                            encoding="utf-8")
        (folder / "points" / h / "config.resolved.yaml").write_text(
            f"# rendered on {host}\n" + yaml.safe_dump(_config(n), allow_unicode=True), encoding="utf-8")
    (folder / "sweep.yaml").write_text(f"# {host}\n" + yaml.safe_dump(spec, sort_keys=False), encoding="utf-8")
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r, ensure_ascii=False) + "\n" for r in rows),
                                        encoding="utf-8")
    return folder


# ------------------------------------------------------------------ 1: tlm's files read as UTF-8


@pytest.mark.slow
def test_scaling_reads_a_sweep_whose_files_hold_non_ascii_text_under_an_ascii_locale(tmp_path):
    """Its results.json and config.resolved.yaml (read, or ``cannot read its folder``) and its sweep.yaml
    (the points it planned: read, or quietly none)."""
    _sweep(tmp_path / "sw")
    got = _c_locale(["-m", "tlm", "scaling", "sw", "--out", "eq", "--no-report"], tmp_path)
    assert got.returncode == 0, got.stderr.decode("utf-8", "replace")
    meta = json.loads((tmp_path / "eq" / "eq52.json").read_text(encoding="utf-8"))
    assert [f["planned"] for f in meta["fitted_from"]] == [[f"{i:016x}" for i in range(3)]]


@pytest.mark.slow
def test_a_study_rerun_under_an_ascii_locale_replaces_its_own_non_ascii_names_and_keeps_the_users(tmp_path):
    """``.tlm-files`` naming a file of a non-ASCII name (written by a run in a UTF-8 locale): a rerun under
    ``LC_ALL=C`` replaces that file, the study's, and keeps the user's notes (the list was read as none: the
    folder replaced whole, the notes lost). The sweep's files are ASCII here: the list is the one non-ASCII file."""
    _sweep(tmp_path / "sw", host="localhost")
    assert main(["scaling", str(tmp_path / "sw"), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    eq = tmp_path / "eq"
    old = "scaling_eq_cornell—ü.png"  # (the figure of a scene of that name, before)
    (eq / old).write_bytes(b"")
    with open(eq / ".tlm-files", "ab") as f:
        f.write(old.encode("utf-8") + b"\n")
    (eq / "notes.txt").write_text("mine\n", encoding="utf-8")
    got = _c_locale(["-m", "tlm", "scaling", "sw", "--out", "eq", "--no-report"], tmp_path)
    assert got.returncode == 0, got.stderr.decode("utf-8", "replace")
    assert (eq / "notes.txt").read_text(encoding="utf-8") == "mine\n"
    assert old not in os.listdir(eq)
    mine = (eq / ".tlm-files").read_bytes().split()
    assert b"eq52.json" in mine and b"notes.txt" not in mine


@pytest.mark.slow
def test_git_output_of_a_checkout_in_a_non_ascii_folder_is_read_under_an_ascii_locale(tmp_path):
    """provenance's ``git rev-parse --show-toplevel``: the folder as Python names it, not a UnicodeDecodeError."""
    repo = tmp_path / "dépôt"
    repo.mkdir()
    if subprocess.run(["git", "init", "-q", str(repo)], capture_output=True, check=False).returncode != 0:
        pytest.skip("no git")
    script = ("import os, sys; from pathlib import Path; from tlm.experiments.provenance import _git; "
              "top = _git('rev-parse', '--show-toplevel', cwd=Path(sys.argv[1])); "
              "print(top == os.path.realpath(sys.argv[1]))")
    got = _c_locale(["-c", script, os.fsencode(repo)], tmp_path)
    assert got.returncode == 0, got.stderr.decode("utf-8", "replace")
    assert got.stdout.strip() == b"True"


# what may read or write text without naming its encoding: files of the kernel's, ASCII by their format
_LOCALE_OK = {("tlm/kernels/threads.py", "self_cgroup.read_text()"),  # (/proc/self/cgroup)
              ("tlm/kernels/threads.py", "path.read_text()")}  # (a control group's cpu.max, cpu.cfs_quota_us)
# open-like calls: (the position of their mode, of their encoding); a mode of None is the default, "r"
_OPENS = {"open": (1, 3), "io.open": (1, 3), "os.fdopen": (1, 3), "codecs.open": (1, 2)}
# compressed files' opens, binary unless their mode says "t"; their encoding's position (lzma's is a keyword)
_COMPRESSED = {"gzip.open": 3, "bz2.open": 3, "lzma.open": None}
# temporary files, "w+b" unless their mode says otherwise: (the position of their mode, of their encoding)
_TEMPORARY = {"TemporaryFile": (0, 2), "NamedTemporaryFile": (0, 2), "SpooledTemporaryFile": (1, 3)}
_SUBPROCESS = ("run", "Popen", "check_output", "check_call", "call")  # (text=, errors=: their output as text)
_ALWAYS_TEXT = ("os.popen", "subprocess.getoutput", "subprocess.getstatusoutput")  # (text in the locale's, always)


def _arg(call: ast.Call, keyword: str, at: int | None) -> ast.expr | None:
    """The argument ``keyword`` of a call: given by name, else its positional argument ``at`` (None: none)."""
    for kw in call.keywords:
        if kw.arg == keyword:
            return kw.value
    return call.args[at] if at is not None and len(call.args) > at else None


def _mode(call: ast.Call, at: int) -> ast.expr | None:
    """The mode argument of an ``open``-like call: its ``mode=``, else its positional argument ``at``."""
    return _arg(call, "mode", at)


def _text_mode(mode: ast.expr | None) -> bool:
    """Whether a mode (None: the default, ``"r"``) opens a file as text: a literal without ``b``."""
    if mode is None:
        return True
    return isinstance(mode, ast.Constant) and isinstance(mode.value, str) and "b" not in mode.value


def _given(value: ast.expr | None) -> bool:
    """Whether an argument is given, and is no literal None (``encoding=None``: the locale's)."""
    return value is not None and not (isinstance(value, ast.Constant) and value.value is None)


def _locale_text(call: ast.Call) -> bool:
    """Whether ``call`` reads or writes text in the locale's encoding (no encoding named, by name or position)."""
    func = call.func
    callee = ast.unparse(func)
    last = func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else ""
    if isinstance(func, ast.Attribute) and last in ("read_text", "write_text"):
        # (importlib.metadata's Distribution.read_text(filename) reads UTF-8 itself)
        return callee != "dist.read_text" and not _given(_arg(call, "encoding", 0 if last == "read_text" else 1))
    if callee in _OPENS:
        mode_at, encoding_at = _OPENS[callee]
        return _text_mode(_mode(call, mode_at)) and not _given(_arg(call, "encoding", encoding_at))
    if callee in _COMPRESSED:
        mode = _mode(call, 1)
        return (isinstance(mode, ast.Constant) and isinstance(mode.value, str) and "t" in mode.value
                and not _given(_arg(call, "encoding", _COMPRESSED[callee])))
    if callee.removeprefix("tempfile.") in _TEMPORARY:  # (tempfile.X, or X imported from it)
        mode_at, encoding_at = _TEMPORARY[callee.removeprefix("tempfile.")]
        mode = _mode(call, mode_at)
        return mode is not None and _text_mode(mode) and not _given(_arg(call, "encoding", encoding_at))
    if callee in ("io.TextIOWrapper", "TextIOWrapper"):
        return not _given(_arg(call, "encoding", 1))
    if callee in _ALWAYS_TEXT:
        return True
    if isinstance(func, ast.Attribute) and last == "open" and callee != "os.open":
        mode = _mode(call, 0)  # (Path.open(mode); zf.open(name, ...), Image.open(path): no mode first)
        return ((mode is None and not call.args) or (
            isinstance(mode, ast.Constant) and isinstance(mode.value, str)
            and set(mode.value) <= set("rwxat+") and _text_mode(mode))) and not _given(_arg(call, "encoding", 2))
    # (a subprocess's output as text: text=, universal_newlines= or errors=; a text= of another function is its own)
    flags = ("text", "universal_newlines", "errors") if last in _SUBPROCESS else ("universal_newlines",)
    return not _given(_arg(call, "encoding", None)) and any(
        kw.arg in flags and not (isinstance(kw.value, ast.Constant) and not kw.value.value)
        for kw in call.keywords)


def locale_reads(source: str, name: str) -> list[str]:
    """The calls of ``source`` (the module ``name``, ``tlm/...py``) that read or write text in the locale's
    encoding: ``.read_text()``/``.write_text()``, a text-mode ``open``/``os.fdopen``/``io.open``/``codecs.open``/
    ``Path.open``, a ``gzip``/``bz2``/``lzma`` open in a ``t`` mode, a text-mode temporary file, an
    ``io.TextIOWrapper``, ``os.popen``, a ``subprocess`` call with ``text=True`` (or ``universal_newlines``,
    ``errors``), each without an encoding (by name or position; ``encoding=None`` is none); a call given
    ``**kwargs`` is left to its caller, /proc's files and :data:`_LOCALE_OK` aside."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Call) or None in {kw.arg for kw in node.keywords}:
            continue
        text = ast.unparse(node)
        if "/proc/" in text or (name, text) in _LOCALE_OK:
            continue
        if _locale_text(node):
            found.append(f"{name}:{node.lineno}: {text}")
    return found


def test_no_text_read_or_write_in_tlm_leaves_its_encoding_to_the_locale():
    found = []
    for path in sorted((REPO / "tlm").rglob("*.py")):
        name = path.relative_to(REPO).as_posix()
        found += locale_reads(path.read_text(encoding="utf-8"), name)
    assert not found, "name encoding='utf-8' (tlm writes its files as UTF-8, whatever the locale):\n" + "\n".join(
        found)


def test_the_check_finds_each_kind_of_locale_read():
    src = ("from pathlib import Path\nimport io, os, subprocess\n"
           "Path('a').read_text()\nPath('a').write_text('x')\nopen('a')\nopen('a', 'w')\nio.open('a', mode='r')\n"
           "os.fdopen(3, 'w')\nPath('a').open()\nPath('a').open('a')\nsubprocess.run(['git'], text=True)\n"
           # and what is no such read or write
           "Path('a').read_text(encoding='utf-8')\nopen('a', 'rb')\nopen('a', mode, **kw)\nos.open('a', 0)\n"
           "zf.open(f'{n}.npy', 'w')\nPath('/proc/1/stat').read_text()\ndist.read_text('RECORD')\n"
           "subprocess.run(['git'], capture_output=True)\nsubprocess.run(['git'], text=True, encoding='utf-8')\n")
    assert [line.split(": ", 1)[0] for line in locale_reads(src, "x.py")] == [f"x.py:{n}" for n in range(3, 12)]


# ------------------------------------------------------------------ 2: a piped binary STL holding \r\n


def _crlf_stl() -> bytes:
    """A binary STL of one triangle whose bytes are UTF-8 (a header of ASCII lines ended by ``\\r\\n``; floats of
    ASCII bytes: 0.0, 0.5): 134 bytes, 84 and 50 a triangle, which the newlines made ``\\n`` are not."""
    header = b"binary STL\r\nwritten on Windows\r\n".ljust(80, b" ")
    data = header + struct.pack("<I", 1) + struct.pack("<12fH", 0, 0, 0.5, 0, 0, 0, 0.5, 0, 0, 0, 0.5, 0, 0)
    data.decode("utf-8")  # (else it is told as no UTF-8 text, a case of its own)
    assert b"\r\n" in data and len(data) == 134
    return data


def test_a_piped_binary_stl_of_utf8_bytes_with_crlf_pairs_gets_the_piped_mesh_line(piped, tmp_path, capsys):
    path = piped(_crlf_stl())
    assert main(["run", path, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [err[0]] and err[0].startswith(f"tlm: error: {path}: is an STL mesh file given as a pipe, "), err
    assert "save it as a file, mesh.stl" in err[0] and "YAML" in err[0]
    assert not (tmp_path / "o").exists()


def test_read_yaml_tells_the_piped_stl_by_its_bytes_before_they_are_decoded(pipes):
    from tlm.config import read_yaml
    from tlm.errors import InputError

    with pytest.raises(InputError, match=r"is an STL mesh file given as a pipe, not a YAML file: save it as a file"):
        read_yaml(pipes(_crlf_stl()))


def test_a_piped_yaml_config_with_crlf_reads_as_before(pipes):
    """The text decoded after the check: universal newlines, as ``Path.read_text`` gives it."""
    from tlm.config import read_yaml

    assert read_yaml(pipes(b"scene: cornell\r\nseed: 3\r\n")) == {"scene": "cornell", "seed": 3}
