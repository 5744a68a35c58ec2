"""Runs of two scene files that share a config are two sources of the thesis tables, not one.

Two config files in two folders both say ``scene: ring.yaml``: each names the ``ring.yaml``
beside it, two files (here of different content, both ``name: ring``). Their resolved configs
are equal (the config keeps the path as written), so the report took runs of both files, in
two modes, for the columns of one Table I. The runs are grouped by their scene file as the
report names it, too: a table holds the runs of one scene file.

Real ``tlm run`` folders at 16x12 pixels, one frame; the tables as the report's section builds them.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from tlm.cli import main
from tlm.report.collect import read
from tlm.report.tables import collect_sources, table_html
from tlm.scenes.loader import scenes_dir


def _project(folder: Path, edit: bool) -> Path:
    """``folder`` with a run config naming ``ring.yaml`` and, beside it, the thesis's ring scene
    (``name: ring``), its light moved and its ring coarser if ``edit``."""
    text = (scenes_dir() / "thesis" / "ring.yaml").read_text()
    if edit:
        assert "position: [18.0, 6.0, 8.0]" in text and "n_seg: 48 " in text
        text = text.replace("position: [18.0, 6.0, 8.0]", "position: [-18.0, 12.0, 8.0]")
        text = text.replace("n_seg: 48 ", "n_seg: 24 ")
    folder.mkdir(parents=True)
    (folder / "ring.yaml").write_text(text)
    (folder / "run.yaml").write_text("scene: ring.yaml\nresolution: [16, 12]\nseed: 0\narch: {frames: 1}\n")
    return folder / "run.yaml"


def _run(config: Path, mode: str, out: Path) -> None:
    assert main(["run", str(config), "--mode", mode, "--out", str(out), "--no-progress", "--outputs", "images",
                 "--no-report", "--no-reference"]) == 0


def test_two_scene_files_of_one_config_fill_two_tables(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    a = _project(tmp_path / "a", edit=False)
    b = _project(tmp_path / "b", edit=False)  # (h389: a copy of the thesis's ring; an edited one has no table)
    runs = tmp_path / "runs"
    _run(a, "rcast", runs / "a_rcast")
    _run(a, "reflect", runs / "a_reflect")
    _run(b, "refract", runs / "b_refract")
    inputs = read([runs])
    assert {r.path.name: r.scene_label for r in inputs.runs} == {
        "a_rcast": "a/ring.yaml", "a_reflect": "a/ring.yaml", "b_refract": "b/ring.yaml"}
    # (their resolved configs name the two files by their absolute paths: equal but for mode and scene)
    assert len({json.dumps({k: v for k, v in r.config.items() if k not in ("mode", "scene")}, sort_keys=True,
                           default=str) for r in inputs.runs}) == 1
    assert {r.config["scene"] for r in inputs.runs} == {str(tmp_path / d / "ring.yaml") for d in ("a", "b")}
    sources = collect_sources(inputs, [])["ring"]
    # one table per scene file: a's two modes together, b's refract alone
    assert sorted((s.scene_label, tuple(s.modes)) for s in sources) == [
        ("a/ring.yaml", ("rcast", "reflect")), ("b/ring.yaml", ("refract",))]
    for s in sources:
        assert {r.scene_label for r in s.runs} == {s.scene_label}
    # and so the report's tables: two Table I, each naming one scene file
    captions = [re.search(r"<caption>(.*?)</caption>", table_html(s)).group(1) for s in sources]
    assert sum(", scene a/ring.yaml" in c and "b/ring.yaml" not in c for c in captions) == 1
    assert sum(", scene b/ring.yaml" in c and "a/ring.yaml" not in c for c in captions) == 1
