"""A YAML file written for a test: a config, a sweep or a study file (shared by the ``--set`` tests)."""

from __future__ import annotations

from pathlib import Path

import yaml


def yaml_file(folder: Path, name: str, content: dict) -> Path:
    """``content`` written as YAML to ``folder / name`` (keys in their order); the path."""
    path = folder / name
    path.write_text(yaml.safe_dump(content, sort_keys=False))
    return path
