"""``--out`` on a bind mount of a folder of the same file system (``mount --bind D D``): a mount
point, which no rename can replace (EBUSY), though ``os.path.ismount`` compares devices and says
it is none. It is refused before any work as a tmpfs mount point is (exit 2, "is a mount point,
which cannot be replaced; name a folder inside it"), not found after the render as "cannot
write: device or resource busy" (exit 1); where the mount is missed all the same (no
``/proc/self/mountinfo``), the busy rename is that refusal, the folder left as it was and nothing
half-written beside it. The mounts are made in a mount namespace of their own (``unshare -m``,
as root); without one the tests are skipped."""

from __future__ import annotations

import functools
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tlm import storage
from tlm.errors import InputError

REPO = Path(__file__).resolve().parents[1]
REFUSED = "is a mount point, which cannot be replaced; name a folder inside it"


@functools.cache
def _namespaces() -> str | None:
    """Why mounts cannot be made here, or None."""
    if not sys.platform.startswith("linux") or shutil.which("unshare") is None or shutil.which("mount") is None:
        return "no unshare/mount here"
    if os.geteuid() != 0:
        return "mounting needs root"
    try:
        done = subprocess.run(["unshare", "-m", "sh", "-c", "mount -t tmpfs none /mnt 2>/dev/null || "
                               "mount --bind / / "], capture_output=True, timeout=30)
    except (OSError, subprocess.SubprocessError) as e:
        return f"unshare -m failed: {e}"
    return None if done.returncode == 0 else f"unshare -m cannot mount here: {done.stderr.decode().strip()}"


def in_namespace(script: str, cwd: Path, cache: Path) -> subprocess.CompletedProcess:
    """``script`` (sh) in a mount namespace of its own, tlm of this checkout on its path."""
    why = _namespaces()
    if why is not None:
        pytest.skip(why)
    env = {**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(cache)}
    return subprocess.run(["unshare", "-m", "sh", "-c", script], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=600)


def test_check_destination_refuses_a_mount_point_that_ismount_misses(tmp_path, monkeypatch):
    """A folder /proc/self/mountinfo lists as a mount point (as it lists a bind mount) is refused
    as one though :func:`os.path.ismount` says no; a folder inside it is a destination as ever."""
    d = tmp_path / "mnt rw"  # (mountinfo writes the space as \\040)
    d.mkdir()
    assert not os.path.ismount(d)
    monkeypatch.setattr(storage, "_mount_points", lambda: frozenset({os.fsencode(d.resolve())}))
    with pytest.raises(InputError, match=REFUSED):
        storage.check_destination(d, "results.json")
    assert storage.check_destination(d / "inside", "results.json") == (d / "inside").resolve()


@pytest.mark.slow
def test_tlm_run_into_a_bind_mount_is_refused_before_any_work(tmp_path, cache):
    """The probe's case (/tmp/h69/rw_test.sh): ``tlm run --out D`` with D bind-mounted onto itself,
    empty and writable, its name with a space (mountinfo's ``\\040``): exit 2 with the mount point's
    line, before the render, D and its parent as they were; ``--out D/inside`` runs."""
    d = tmp_path / "mnt rw"
    d.mkdir()
    args = "--mode rcast --set 'resolution=[16,16]' --no-progress --no-reference --no-report --outputs images"
    done = in_namespace(f"mount --bind '{d}' '{d}' || exit 9\n"
                        f"python -m tlm run cornell {args} --out '{d}'; echo \"rc=$?\"\n"
                        f"python -m tlm run cornell {args} --out '{d}/inside' >/dev/null; echo \"rc=$?\"\n",
                        tmp_path, cache)
    assert done.returncode == 0, done
    assert done.stdout.split()[-2:] == ["rc=2", "rc=0"], done
    lines = [line for line in done.stderr.splitlines() if line.startswith("tlm: error:")]
    assert lines == [f"tlm: error: --out: {str(d)!r} {REFUSED}"], done.stderr
    assert "wrote" not in done.stdout.split("rc=2")[0]  # (nothing rendered, nothing written)
    assert os.listdir(d) == ["inside"] and (d / "inside" / "results.json").is_file()
    assert sorted(os.listdir(tmp_path)) == sorted(["mnt rw", *(["cache"] if cache.exists() else [])])


SWAP = """
import os, sys
from pathlib import Path
from tlm import storage
from tlm.errors import InputError

storage._mount_points = lambda: frozenset()  # (no mountinfo to read: the mount is missed)
d = Path(sys.argv[1])
for what in ("empty", "an earlier output"):
    try:
        with storage.atomic_folder(d, "results.json", owned=("results.json", "notes.txt")) as tmp:
            (tmp / "results.json").write_text("new")
    except InputError as e:
        print(what, "refused:", e)
    except Exception as e:
        print(what, "failed:", type(e).__name__, e)
    else:
        print(what, "written")
    print(what, "holds", sorted(os.listdir(d)), "beside", sorted(os.listdir(d.parent)))
    if what == "empty":
        (d / "results.json").write_text("old")
print("old kept:", (d / "results.json").read_text())
"""


@pytest.mark.slow
def test_a_bind_mount_the_checks_miss_is_refused_at_the_swap_leaving_nothing(tmp_path, cache):
    """Where the mount is missed (no mountinfo), the rename that would move the mount point aside
    fails busy: that is the mount point's refusal (an InputError, exit 2), the temporary folder is
    removed, and D, empty or an earlier output, is left as it was."""
    d = tmp_path / "mnt"
    d.mkdir()
    script = tmp_path / "swap.py"
    script.write_text(SWAP)
    done = in_namespace(f"mount --bind '{d}' '{d}' || exit 9\npython '{script}' '{d}'\n", tmp_path, cache)
    assert done.returncode == 0, done
    refused = f"refused: --out: {str(d)!r} {REFUSED}"
    beside = sorted(["mnt", "swap.py", *(["cache"] if cache.exists() else [])])
    assert done.stdout.splitlines() == [
        f"empty {refused}", f"empty holds [] beside {beside}",
        f"an earlier output {refused}", f"an earlier output holds ['results.json'] beside {beside}",
        "old kept: old"], done
