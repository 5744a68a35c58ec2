"""docs/usage.md, read as a user runs its commands: what `tlm sweep --dry-run --json` prints and what
`tlm scaling` writes into `eq52.json` are the keys the page names (h383: the page listed neither the
plan's `dry_run`, `sweep`, `out` and `remote`, nor where `latency_multiple` is and what JSON writes
for "not")."""

from __future__ import annotations

import json
import re
from pathlib import Path

from tlm.cli import main

REPO = Path(__file__).resolve().parents[1]
USAGE = (REPO / "docs" / "usage.md").read_text(encoding="utf-8")
SWEEP = """base: {scene: cornell, mode: rcast, resolution: [8, 8], render: {spp: 1, light_samples: 1}}
grid:
  arch.pipelines: [1, 2]
"""


def _between(start: str, end: str) -> str:
    text = " ".join(USAGE.split())  # (the page wraps its lines anywhere)
    i = text.index(start)
    return text[i:text.index(end, i)]


def test_dry_run_json_prints_the_keys_the_page_names(tmp_path, capsys):
    (tmp_path / "sw.yaml").write_text(SWEEP)
    assert main(["sweep", str(tmp_path / "sw.yaml"), "--out", str(tmp_path / "out"), "--dry-run", "--json"]) == 0
    plan = json.loads(capsys.readouterr().out)
    said = _between("`--json` (with `--dry-run` only) prints the same as one JSON object", "It loads what")
    named = set(re.findall(r"`([a-z_]+)`", said))
    assert set(plan) <= named, f"keys the page does not name: {sorted(set(plan) - named)}"
    assert not (tmp_path / "out").exists()


def test_latency_multiple_is_where_the_page_says(tmp_path, capsys):
    (tmp_path / "sw.yaml").write_text(SWEEP)
    assert main(["sweep", str(tmp_path / "sw.yaml"), "--out", str(tmp_path / "sw"), "--jobs", "1",
                 "--no-progress", "--no-report"]) == 0
    assert main(["scaling", str(tmp_path / "sw"), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    capsys.readouterr()
    eq52 = json.loads((tmp_path / "eq" / "eq52.json").read_text())
    assert "latency_multiple" not in eq52
    fits = {f["target"]: f for f in eq52["fits"]}
    assert "latency_multiple" in fits["latency"] and "latency_multiple" not in fits["throughput"]
    said = _between("the latency fit is the throughput fit scaled", "say so")
    assert "`fits`" in said and "null" in said and "None" not in said  # (JSON has null, not Python's None)
