"""Review of ca4a95e (tlm's files read as UTF-8 whatever the locale): the source check of
tests/test_encoding_h332.py (``locale_reads``).

1. It flagged legitimate code: any call given ``text=`` (tlm's own ``safe_load(text=...)``,
   ``error_line(text=...)``, ``escaped_line(text=...)`` take a ``text`` argument), and an encoding given by
   position (``path.read_text("utf-8")``, ``open(path, "r", -1, "utf-8")``).
2. It let locale reads through: ``encoding=None`` (the locale's, named), a ``gzip``/``bz2``/``lzma`` open in
   a ``t`` mode (its mode is second, where ``zf.open(name)``'s is no mode), a text-mode temporary file, an
   ``io.TextIOWrapper`` of no encoding, ``os.popen``, a ``subprocess`` call with ``errors=`` (text mode).
"""

from __future__ import annotations

from tests.test_encoding_h332 import locale_reads

HEAD = "import bz2, codecs, gzip, io, lzma, os, subprocess, tempfile\nfrom pathlib import Path\n"


def _flagged(lines: list[str]) -> list[str]:
    """The lines of ``lines`` (statements, one a line) the check flags."""
    got = locale_reads(HEAD + "".join(f"{line}\n" for line in lines), "x.py")
    return [lines[int(g.split(":")[1]) - 3] for g in got]  # (HEAD is lines 1 and 2)


def test_the_check_leaves_a_text_argument_of_another_function_and_a_positional_encoding_alone():
    fine = ["safe_load(text=s)", "error_line(text=t, whole=w)", "InputError(text=msg)", "label.set(text='x')",
            "Path(p).read_text('utf-8')", "Path(p).write_text(s, 'utf-8')", "open(p, 'r', -1, 'utf-8')",
            "io.open(p, 'w', -1, 'utf-8')", "codecs.open(p, 'r', 'utf-8')", "Path(p).open('r', -1, 'utf-8')",
            "os.fdopen(fd, 'w', -1, 'utf-8')", "subprocess.run(cmd, capture_output=True, text=False)"]
    assert _flagged(fine) == []


def test_the_check_finds_the_locale_reads_it_let_through():
    bad = ["Path(p).read_text(encoding=None)", "open(p, 'w', encoding=None)", "gzip.open(p, 'rt')",
           "lzma.open(p, mode='wt')", "bz2.open(p, 'at')", "tempfile.NamedTemporaryFile('w')",
           "tempfile.TemporaryFile(mode='w+')", "NamedTemporaryFile(mode='w')", "io.TextIOWrapper(buf)",
           "os.popen('ls')", "subprocess.getoutput('ls')", "subprocess.run(cmd, capture_output=True, errors='replace')",
           "subprocess.check_output(cmd, universal_newlines=True)", "subprocess.run(cmd, text=True)"]
    fine = ["gzip.open(p)", "gzip.open(p, 'rb')", "gzip.open(p, 'rt', encoding='utf-8')", "lzma.open(p, 'wb')",
            "tempfile.NamedTemporaryFile()", "tempfile.NamedTemporaryFile('w+b')",
            "tempfile.NamedTemporaryFile('w', encoding='utf-8')", "io.TextIOWrapper(buf, 'utf-8')",
            "subprocess.run(cmd, errors='replace', encoding='utf-8')", "zf.open(name, 'w')", "os.open(p, 0)"]
    assert _flagged(bad + fine) == bad
