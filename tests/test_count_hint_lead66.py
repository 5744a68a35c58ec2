"""The hint for a pmap run left without photons quotes the built-in scenes' photon counts (stop 66, after probe h387,
which found "give the scene file photons: N" with no number to start from): the figures it quotes are those the
shipped scene files give, so an edited scene file fails this test rather than the hint going stale."""

import re
from pathlib import Path

import yaml

from tlm.experiments.run_warnings import _COUNT_HINT

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def test_the_hint_quotes_the_shipped_scenes_photon_counts():
    counts = {p.stem: yaml.safe_load(p.read_text()).get("photons") for p in SCENES.glob("*.yaml")}
    counts.update({f"thesis/{p.stem}": yaml.safe_load(p.read_text()).get("photons")
                   for p in (SCENES / "thesis").glob("*.yaml")})
    given = [c for c in counts.values() if c]
    low, high = map(int, re.search(r"give (\d+) to (\d+)", _COUNT_HINT).groups())
    assert (low, high) == (min(given), max(given)), counts
    for name, count in re.findall(r"(\w+) (\d+)(?=[,)])", _COUNT_HINT.split("to ", 1)[1]):
        assert counts[name] == int(count), (name, counts)
