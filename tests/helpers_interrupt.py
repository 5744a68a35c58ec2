"""The script body both interrupt tests run after their import hook: ``tlm run`` of a small
reflect frame through :func:`tlm.cli.main`, reporting its exit status, whether the hooked module
was imported whole and whether the run folder was written (tests/test_api_interrupt.py with
SIGINT, tests/test_whole_imports_sigterm.py with SIGTERM)."""

import textwrap

CLI_RUN = textwrap.dedent("""
    from tlm.cli import main
    rc = main(["run", "cornell", "--out", "r", "--no-report", "--set", "mode=reflect", "--set",
               "resolution=[16,16]", "--set", "render.spp=1", "--set", "render.light_samples=1"])
    report.update(rc=rc, target_whole=TARGET in sys.modules, out=os.path.exists("r"))
    print(json.dumps(report))
""")


def signalled_call(tmp_path, monkeypatch, signum: int, module: str, installed: list | None = None):
    """``(call, reached)``: ``call(import_it)``, wrapped by :func:`tlm.whole_imports.imports_whole`,
    either imports ``module`` (written into ``tmp_path``: it raises ``signum`` while it is being
    imported, then sets ``WHOLE``) or raises ``signum`` itself, outside any import; ``reached``
    gets ``import_it`` when the call gets to its end, ``installed`` (if given) the handler of
    ``signum`` the call ran under."""
    import importlib
    import signal

    from tlm.whole_imports import imports_whole

    name = signal.Signals(signum).name
    (tmp_path / f"{module}.py").write_text(f"import signal\nsignal.raise_signal(signal.{name})\nWHOLE = True\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    reached: list[bool] = []

    @imports_whole
    def call(import_it: bool) -> None:
        if installed is not None:
            installed.append(signal.getsignal(signum))
        if import_it:
            importlib.import_module(module)
        else:
            signal.raise_signal(signum)
        reached.append(import_it)

    return call, reached


def run_script(script: str, *args: str, cwd, cache) -> dict:
    """``script`` run by a fresh Python (``-c``, ``args`` after it) in ``cwd``, with the tlm of this
    checkout, the functional cache ``cache`` and the default (compiled) kernels: the JSON of its last
    line of output, with its ``stderr``; it must exit 0."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    env = {**os.environ, "TLM_CACHE": str(cache), "PYTHONPATH": str(repo)}
    env.pop("TLM_KERNELS", None)  # (the default: numba)
    proc = subprocess.run([sys.executable, "-c", script, *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=300)
    # (the status too: a process killed by a signal, or CPython's kill of itself at exit after an
    # unhandled KeyboardInterrupt in an exec'd string, leaves stderr empty)
    assert proc.returncode == 0, f"exit status {proc.returncode}; stdout {proc.stdout[-500:]!r}; " + proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1]) | {"stderr": proc.stderr}


def running(pid: int) -> bool:
    """The process ``pid`` is there and not a zombie (which an init that reaps none leaves)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False
