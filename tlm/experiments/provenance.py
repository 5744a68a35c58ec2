"""Where a result came from: the versions of tlm and its libraries, and tlm's git revision.

``results.json`` of a run, every sweep point's row and a study's ``provenance.json``
record them, so that a number can be traced to the code that produced it.
"""

from __future__ import annotations

import platform
import subprocess
from pathlib import Path

PACKAGES = ("tlm", "numpy", "scipy", "simpy", "trimesh", "pyyaml", "pillow")  # whose versions are recorded


def versions() -> dict[str, str]:
    """Python's, the platform's and :data:`PACKAGES`' versions ("not installed" for one missing)."""
    import importlib.metadata as md

    out = {"python": platform.python_version(), "platform": platform.platform()}
    for pkg in PACKAGES:
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def git_revision() -> str | None:
    """The commit of tlm's checkout (None outside a git checkout, or without git)."""
    try:
        here = Path(__file__).resolve().parent
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True,
                             text=True, timeout=5, check=False)
        return out.stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        return None


def provenance(study: str | None, host_seconds: float | None) -> dict:
    """What a study folder records of where it came from (``provenance.json``)."""
    return {"study": study, "versions": versions(), "git_revision": git_revision(),
            "host_seconds": None if host_seconds is None else round(host_seconds, 3)}
