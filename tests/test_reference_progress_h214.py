"""A reference a run computes says how its rounds go where no bar is drawn, and its bar's status
says that it stops before its total, in a few words that fit 80 columns."""

from __future__ import annotations

import tlm.experiments.reference as reference
from tlm.config import config_from_dict
from tlm.experiments.loading import load_frame

CONFIG = {"scene": "cornell", "mode": "pmap", "resolution": [4, 4], "photons": {"count": 500},
          # (a tolerance no round meets: every cycle runs, up to max_rounds)
          "reference": {"photons": 500, "k_nearest": 8, "tolerance": 1e-6, "max_rounds": 6}}


class _Bar:
    def __init__(self, **kwargs):
        self.kwargs, self.postfixes = kwargs, [kwargs.get("postfix")]

    def update(self, n=1):
        pass

    def set_postfix_str(self, text):
        self.postfixes.append(text)

    def close(self):
        pass


def test_a_runs_reference_says_its_rounds_where_no_bar_is_drawn(monkeypatch, cache):
    """``tlm run``'s reference (522 s on the conference room at 64x64) said one line and nothing
    more for minutes where stderr is no terminal (under pytest it is not)."""
    monkeypatch.setattr(reference, "ROUND_LINE_SECONDS", 0.0, raising=False)
    frame = load_frame(config_from_dict(CONFIG))
    said: list[str] = []
    found = reference.ensure_reference(frame, compute=True, bar=True, say=said.append)
    rounds = [line for line in said if line.startswith("  round")]
    assert found.meta["rounds"] >= 4 and len(rounds) == found.meta["rounds"]
    assert "of at most" in rounds[0]
    assert "relative standard error" in rounds[-1] and "stops below 1e-06" in rounds[-1]


def test_the_bar_says_it_stops_when_converged_in_80_columns(monkeypatch, cache):
    from tqdm import tqdm

    bars: list[_Bar] = []
    monkeypatch.setattr(reference, "progress_bar", lambda enabled, **kw: bars.append(_Bar(**kw)) or bars[-1])
    # (the default tolerance, 0.03: its status as a run shows it; two cycles at least)
    frame = load_frame(config_from_dict({**CONFIG, "reference": {**CONFIG["reference"], "tolerance": 0.03}}))
    settings = reference.ReferenceSettings.from_config(frame.scene, frame.cfg)
    reference.compute_reference(frame, None, settings, bar=True)
    (bar,) = bars
    assert len(bar.postfixes) >= 2
    for text in bar.postfixes:
        assert "stop" in text and len(text) <= 24
        line = tqdm.format_meter(n=16, total=128, elapsed=83.0, ncols=79, prefix="reference", unit="round",
                                 postfix=text)
        assert line.endswith(f"{text}]")  # (the status whole, not cut at the terminal's edge)
