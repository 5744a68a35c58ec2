"""Another process, as a test stands one in: a run's claim of a folder held as another process
holds it (tests/test_leftovers_h248.py, tests/test_run_faults_h215.py), and a probe kernel of a
copy of the package run in a child Python (tests/test_run_faults_h215.py, tests/test_numba_cache.py)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

# the child's script: the copy's tlm (not this checkout's), its probe kernel called on (1.0, 2.0)
RUN = """import sys
sys.path.insert(0, {root!r})
import tlm
assert tlm.__file__.startswith({root!r}), tlm.__file__
from tlm.kernels._jit_probe import probe
print(probe(1.0, 2.0))
"""


def held_claim(folder: Path) -> int:
    """The claim of ``folder`` held, as another process holds it (another open file's flock), with a
    record (this host, process 4242). Returns the open file's descriptor: closing it frees the claim."""
    import fcntl

    from tlm import storage

    folder.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(folder.parent / f".{folder.name}.tlm-running", os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)
    os.pwrite(fd, f"{storage._host()}-4242".ljust(63).encode() + b"\n", 0)
    return fd


def probe_copy(tmp_path: Path, probe: str, env: dict[str, str] | None = None
               ) -> tuple[Path, Callable[[], subprocess.CompletedProcess]]:
    """A copy of the package at ``tmp_path/copy`` (no ``__pycache__``) with ``probe`` (the source of a
    cached kernel ``probe(a, b)``) as ``tlm/kernels/_jit_probe.py``, and ``run``: ``probe(1.0, 2.0)``
    in a child Python (in ``tmp_path``, numba's cache where numba keeps it by default: this
    environment less ``NUMBA_CACHE_DIR`` and ``NUMBA_DISABLE_JIT``, plus ``env``), asserted to exit
    0 (its stderr shown where not). Returns ``(root of the copy, run)``; ``run()`` returns the finished
    process, its output as text."""
    root = tmp_path / "copy"
    shutil.copytree(REPO / "tlm", root / "tlm", ignore=shutil.ignore_patterns("__pycache__"))
    (root / "tlm" / "kernels" / "_jit_probe.py").write_text(probe)
    child = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    child.update(env or {})

    def run() -> subprocess.CompletedProcess:
        done = subprocess.run([sys.executable, "-c", RUN.format(root=str(root))], capture_output=True, text=True,
                              env=child, cwd=tmp_path, timeout=300)
        assert done.returncode == 0, done.stderr
        return done

    return root, run
