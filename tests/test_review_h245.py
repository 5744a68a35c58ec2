"""Review of 0affa44 (h245): a point's YAML read by libyaml's parser, whose composer recurses on the C stack."""

from __future__ import annotations

import subprocess
import sys

READ = """
import sys
from pathlib import Path
from tlm.errors import InputError
from tlm.report.checks import read_yaml
for name in sys.argv[1:]:
    try:
        read_yaml(Path(name))
    except InputError as e:
        print(e)
"""


def test_a_damaged_yaml_nested_deep_is_an_input_error_not_a_crash(tmp_path):
    """A damaged config.resolved.yaml of 100 kB of "[" (or of "- ") ended ``tlm report`` by SIGSEGV in libyaml's
    composer (0affa44); one nested a thousand deep by PyYAML's RecursionError, an internal error: each is an
    InputError naming the file, as any other damaged copy (the report leaves its point out, said)."""
    files = []
    for n, text in enumerate(("[" * 100_000 + "]" * 100_000, "- " * 30_000 + "1\n", "a: " + "{b: " * 1000 + "1"
                              + "}" * 1000 + "\n", "[" * 600 + "]" * 600)):
        files.append(tmp_path / f"c{n}.yaml")
        files[-1].write_text(text)
    got = subprocess.run([sys.executable, "-c", READ, *map(str, files)], capture_output=True, text=True, timeout=120)
    assert got.returncode == 0, (got.returncode, got.stderr[-2000:])
    lines = got.stdout.splitlines()
    assert len(lines) == len(files) and all(str(f) in line and "is nested too deeply to read" in line
                                            for f, line in zip(files, lines)), got.stdout
