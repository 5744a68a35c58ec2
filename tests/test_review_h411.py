"""Review of b2af9d6 (h411): one YAML writer (h406) and bounded ties in a sweep's findings (h408).

- :func:`tlm.config_words.flow_text` said "on one line", but a list or a mapping holding a string of a line
  break came out on several (``['a\\n\\n    b']``: a ``--set`` hint, a default in ``tlm params``), and one
  of U+0085 did not even read back as itself; such a string is now double-quoted and escaped in a list or a
  mapping too (``["a\\nb"]``), as it already was alone.
- A sweep folder the old writer left, whose ``sweep.yaml`` holds a point hash that tlm's reader takes for a
  float (``8e91000000000000``, written bare by YAML 1.1), is still that sweep's: a rerun reads the points'
  folders, never the marker's hashes, skips every point done and writes the marker anew, the hash quoted.
"""

from __future__ import annotations

import re

import pytest
import yaml

import tlm.experiments.sweep as sweep_mod
import tlm.experiments.sweep_file as sweep_file
from tlm.config_words import flow_text, parse_yaml
from tlm.experiments.scaling_dated import sweep_points
from tlm.experiments.sweep import run_sweep

BROKEN = ["a\nb", "x\r", "\x85", "p\u2028q", "\u2029"]


@pytest.mark.parametrize("text", BROKEN)
def test_flow_text_writes_a_list_or_mapping_of_a_line_break_on_one_line(text):
    from tlm.cli_tables import yaml_text

    for value in ([text], {"k": text}, {text: [1, text]}, [{"spp": 2, "name": text}, "1e3"]):
        said = flow_text(value)
        assert not any(c in said for c in BROKEN), repr(said)
        assert parse_yaml(said) == value and yaml.safe_load(said) == value, repr(said)
        assert yaml_text(value) == said
    assert flow_text(["a\nb", 2]) == '["a\\nb", 2]'
    # what holds no line break is written as before
    assert [flow_text(v) for v in ([16, 16], {"spp": 2}, ["1e3", 1e3], ["é", "a b"])] == [
        "[16, 16]", "{spp: 2}", "['1e3', 1000.0]", "[é, a b]"]


FLOAT = re.compile(r"^[0-9]+[eE][0-9]+$")  # (a float to tlm's reader, text to YAML 1.1)


@pytest.fixture
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def test_an_old_sweep_folder_with_a_hash_that_reads_as_a_float_resumes(tmp_path, monkeypatch, _own_cache):
    """One point in about 1,300 has such a hash: here every point's key is made one (its digits kept)."""
    key = sweep_file._key

    def floaty(*args):  # (16 characters: a digit, e, 14 digits)
        digits = f"{int(key(*args), 16) % 10**15:015d}"
        return f"{digits[0]}e{digits[1:]}"

    monkeypatch.setattr(sweep_file, "_key", floaty)
    base = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
            "arch": {"trace": False}}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": base, "grid": {"arch.fifo_depth": [1, 2]}}))
    out = tmp_path / "o"
    first = run_sweep(path, out, jobs=1)
    hashes = [r["hash"] for r in first.rows]
    assert first.ok == 2 and all(FLOAT.match(h) for h in hashes), hashes
    marker = (out / "sweep.yaml").read_text(encoding="utf-8")
    assert all(f"hash: '{h}'" in marker for h in hashes), marker  # (quoted: tlm's reader takes it for a float)
    assert [p["hash"] for p in parse_yaml(marker)["points"]] == hashes
    # the marker as tlm before b2af9d6 wrote it (YAML 1.1's resolver: the hash bare)
    old = marker
    for h in hashes:
        old = old.replace(f"hash: '{h}'", f"hash: {h}")
    assert old != marker and [p["hash"] for p in yaml.safe_load(old)["points"]] == hashes
    (out / "sweep.yaml").write_text(old, encoding="utf-8")
    assert sweep_points(out) == (sorted(hashes), sorted(hashes))  # (a scaling study's read of it)
    ran = []
    point = sweep_mod.run_point
    monkeypatch.setattr(sweep_mod, "run_point", lambda task: ran.append(task.hash) or point(task))
    again = run_sweep(path, out, jobs=1)
    assert ran == [] and (again.ok, again.failed, again.skipped) == (0, 0, 2)
    assert (out / "sweep.yaml").read_text(encoding="utf-8") == marker
    assert [r["hash"] for r in again.rows] == hashes
