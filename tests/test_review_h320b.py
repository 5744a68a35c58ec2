"""For tests/test_review_h320.py, with /tmp/h320/thesis_utf8.patch: ``tlm calibrate --write`` keeps a programs
table's non-ASCII comment under an ASCII locale (was: UnicodeDecodeError, a traceback). Under a Latin-1 locale the
table's UTF-8, read as Latin-1 and written back as UTF-8, would double each non-ASCII character (by reading the code:
no Latin-1 locale here to run it under)."""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CALIBRATE = """
import sys
from pathlib import Path
from tlm.arch.costs import load_programs
from tlm.experiments.thesis import write_calibrated
write_calibrated(load_programs(Path(sys.argv[1])), {"cells": {}}, Path(sys.argv[2]), "tlm calibrate")
"""


def test_a_calibrated_tables_non_ascii_comment_is_kept_under_an_ascii_locale(tmp_path):
    table = tmp_path / "table.yaml"
    head = "# Tabelle f\u00fcr \u00b5-Programme\n".encode()
    table.write_bytes(head + (ROOT / "tlm" / "arch" / "programs.yaml").read_bytes())
    env = {**os.environ, "PYTHONPATH": str(ROOT), "LC_ALL": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
    done = subprocess.run([sys.executable, "-c", CALIBRATE, str(table), str(tmp_path / "out.yaml")],
                          capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr  # (was: UnicodeDecodeError: 'ascii' codec can't decode byte 0xc3)
    assert (tmp_path / "out.yaml").read_bytes().startswith(head)
