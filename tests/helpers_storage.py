"""Failures of the file system staged for the storage tests (tlm.storage's atomic folders)."""

from __future__ import annotations

import errno
from pathlib import Path


def refuse_to_carry(monkeypatch, name: str):
    """``Path.rename`` patched so that the user's entry ``name`` cannot be carried into a new
    output's temporary folder (``.tmp-``): EACCES, as for a read-only folder of theirs or a
    mount point; every other rename is the real one. Returns the real ``Path.rename``, to restore."""
    rename = Path.rename

    def refused(self, target):
        if self.name == name and ".tmp-" in str(target):
            raise OSError(errno.EACCES, "Permission denied", str(self))
        return rename(self, target)

    monkeypatch.setattr(Path, "rename", refused)
    return rename
