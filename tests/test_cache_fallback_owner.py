"""The folder a reference is kept in when the cache cannot take it, ``<tmp>/tlm-cache-<uid>``,
is in a temporary folder other users write too: one of them could make it first (a folder of
theirs, or a link to one) and read or replace what tlm keeps there. tlm writes into it only
when it is this user's own folder that no one else may write (made with mode 0700 when
absent), and says why it did not otherwise; ``tlm error-vs-cost``'s fallback is held to the same
rule."""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path

import numpy as np
import pytest

from tlm.errors import EnvironmentFailure
from tlm.experiments import error_cost, reference, reference_cache

KEY = "0123456789abcdef"
META = {"rounds": 2, "converged": True, "relative_standard_error": 0.01}
IMAGE = np.full((2, 2, 3), 0.5)
CACHE_ERROR = EnvironmentFailure("cannot write: /nowhere is a file, not a folder", source="/nowhere/references")


@pytest.fixture
def tmp(tmp_path, monkeypatch) -> Path:
    """The temporary folder, the test's own."""
    folder = tmp_path / "tmp"
    folder.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


def _mode(path: Path) -> int:
    return stat.S_IMODE(os.lstat(path).st_mode)


def _refused(capsys, why: str) -> None:
    """``tlm reference``'s fallback refuses the kept root: the cache's own error is raised (as
    when the temporary folder cannot be written) after one line saying why it was not kept."""
    root = reference_cache.kept_root()
    with pytest.raises(EnvironmentFailure) as raised:
        reference._kept_elsewhere(KEY, IMAGE, META, CACHE_ERROR)
    assert raised.value is CACHE_ERROR
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("tlm: warning: ")]
    assert len(lines) == 1 and lines[0].startswith(f"tlm: warning: reference {KEY}: not kept in {root} either ("), lines
    assert why in lines[0] and "another user could read or replace what is kept there" in lines[0], lines[0]


def test_the_kept_root_is_made_private_and_a_folder_of_ones_own_is_used(tmp, capsys):
    folder = reference._kept_elsewhere(KEY, IMAGE, META, CACHE_ERROR)
    root = reference_cache.kept_root()
    assert root.parent == tmp and folder == root / "references" / KEY
    assert _mode(root) == 0o700 and _mode(root / "references") == 0o700
    np.testing.assert_array_equal(np.load(folder / "reference.npy"), IMAGE.astype(np.float32))
    assert f"kept in {folder} instead, which later runs read with TLM_CACHE={root}" in capsys.readouterr().err
    # one of this user's made before (mode 0755, as an earlier tlm made it) is still used
    os.chmod(root, 0o755)
    os.chmod(root / "references", 0o755)
    again = reference._kept_elsewhere("fedcba9876543210", IMAGE, META, CACHE_ERROR)
    assert again == root / "references" / "fedcba9876543210" and (again / "meta.json").is_file()


def test_a_link_in_its_place_is_refused_and_nothing_is_written_where_it_points(tmp, tmp_path, capsys):
    theirs = tmp_path / "theirs"
    theirs.mkdir(mode=0o700)
    reference_cache.kept_root().symlink_to(theirs)
    _refused(capsys, f"{reference_cache.kept_root()} is a symbolic link (to {theirs})")
    assert list(theirs.iterdir()) == []


def test_a_folder_others_may_write_is_refused(tmp, capsys):
    root = reference_cache.kept_root()
    root.mkdir()
    os.chmod(root, 0o777)  # (as a folder another user made for everyone)
    _refused(capsys, f"{root} may be written by its group or others (mode 777)")
    assert list(root.iterdir()) == []
    # its references folder, group-writable, the same
    os.chmod(root, 0o700)
    (root / "references").mkdir()
    os.chmod(root / "references", 0o770)
    _refused(capsys, f"{root / 'references'} may be written by its group or others (mode 770)")
    assert list((root / "references").iterdir()) == []


def test_another_users_folder_is_refused(tmp, monkeypatch, capsys):
    """This process's uid taken as one more than its own: the folder it finds under its name,
    made by the real uid, is another user's."""
    real = os.getuid()
    monkeypatch.setattr(os, "getuid", lambda: real + 1)
    root = reference_cache.kept_root()
    assert root.name == f"tlm-cache-{real + 1}"
    root.mkdir(mode=0o700)
    _refused(capsys, f"{root} belongs to user {real}, not to this user ({real + 1})")
    assert list(root.iterdir()) == []


def test_error_vs_cost_does_not_keep_its_reference_in_another_users_folder(tmp, tmp_path, monkeypatch, capsys):
    theirs = tmp_path / "theirs"
    theirs.mkdir()
    reference_cache.kept_root().symlink_to(theirs)
    image, meta = error_cost._uncached_reference(KEY, IMAGE, META, CACHE_ERROR)
    err = capsys.readouterr().err
    assert "is a symbolic link" in err and err.rstrip().endswith("used by this study only"), err
    assert list(theirs.iterdir()) == []
    np.testing.assert_array_equal(image, IMAGE.astype(np.float32))
    assert meta["key"] == KEY
