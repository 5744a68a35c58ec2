"""The one photon-map reference a test's cache holds (the reference tests' common read)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def held_reference(cache: Path) -> tuple[dict, np.ndarray]:
    """The metadata and the image of the one reference under ``cache`` (``TLM_CACHE``)."""
    (folder,) = (cache / "references").iterdir()
    return json.loads((folder / "meta.json").read_text()), np.load(folder / "reference.npy")
