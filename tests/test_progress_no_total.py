"""A progress bar with no total (loading the scene, building the BSP) reads its stage and elapsed
time, not tqdm's count of steps ("0step") and rate ("?step/s") nor a dangling ": "."""

import io
import sys

from tlm import api
from tlm.experiments.loading import load_frame
from tlm.progress import progress_bar


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_the_bsp_build_bar_shows_its_stage_and_elapsed_time(monkeypatch):
    out = Terminal()
    monkeypatch.setattr(sys, "stderr", out)
    cfg = api.load_config("cornell", {"resolution": [8, 8]})
    with progress_bar(True, desc="load scene", total=None, unit="step", leave=True) as bar:
        load_frame(cfg, bar=bar)
        bar.refresh()
    drawn = [line.strip() for line in out.getvalue().replace("\n", "\r").split("\r") if line.strip()]
    assert drawn[0].startswith("load scene [00:")
    assert drawn[-1].startswith("build BSP (2604 triangles) [00:"), drawn[-1]
    assert not any("step" in line or "?" in line or ": " in line for line in drawn), drawn


def test_a_bar_with_a_total_keeps_its_count(monkeypatch):
    out = Terminal()
    monkeypatch.setattr(sys, "stderr", out)
    with progress_bar(True, desc="render", total=4, unit="step", leave=True) as bar:
        bar.refresh()
    assert "0/4" in out.getvalue()
