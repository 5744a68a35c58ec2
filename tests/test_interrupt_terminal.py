"""Ctrl-C typed at a terminal: ``tlm: interrupted`` starts a line of its own, after the
``^C`` the terminal echoed or a progress bar still drawn, and there is no empty line
where a progress bar closed on the interrupt has already ended its line."""

from __future__ import annotations

import fcntl
import os
import select
import signal
import struct
import subprocess
import sys
import termios
import time
from contextlib import suppress
from pathlib import Path

import pytest

from tlm import cli_signals

REPO = Path(__file__).resolve().parents[1]

# A command (``tlm params``, replaced) on a terminal of its own, its controlling terminal, so
# that a Ctrl-C typed there (^C written to the terminal's master side) is echoed and signals it.
CHILD = """
import fcntl, os, signal, sys, termios, time
fcntl.ioctl(0, termios.TIOCSCTTY, 0)
from tlm import cli
from tlm.progress import progress_bar

KIND = {kind!r}
KEEP = []

def command(args):
    if KIND == "closed":  # a bar drawn at the interrupt, closed as the interrupt leaves its block
        with progress_bar(True, desc="work", total=10, leave=False) as bar:
            bar.update(3)
            bar.refresh()
            wait()
    elif KIND == "closed-kept":  # the same with a bar that stays on the screen when closed
        with progress_bar(True, desc="work", total=10, leave=True) as bar:
            bar.update(3)
            bar.refresh()
            wait()
    elif KIND == "open":  # a bar still drawn when the interrupted line is printed
        KEEP.append(progress_bar(True, desc="work", total=10, leave=False))
        KEEP[0].update(3)
        KEEP[0].refresh()
        wait()
    elif KIND == "sigterm":  # no ^C is echoed for a SIGTERM
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(60)
    else:
        wait()
    return 0

def wait():
    print("ready", flush=True)
    time.sleep(60)

cli._cmd_params = command
sys.exit(cli.main(["params"]))
"""


def _typed_ctrl_c(tmp_path: Path, kind: str) -> tuple[bytes, int]:
    """What the terminal shows of the command's stderr (and the echo), and its exit status."""
    master, slave = os.openpty()
    fcntl.ioctl(master, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, "-c", CHILD.format(kind=kind)], cwd=tmp_path, env=env,
                            stdin=slave, stdout=subprocess.PIPE, stderr=slave, start_new_session=True)
    # (the slave is kept open here until the command has ended and its output is read: Linux drops what a pty
    # holds unread once its last slave closes, so a loaded machine lost the command's last line)
    shown = b""
    try:
        if kind != "sigterm":
            assert select.select([proc.stdout], [], [], 60)[0], "the command never got ready"
            assert proc.stdout.readline() == b"ready\n"
            os.write(master, b"\x03")  # Ctrl-C
        deadline = time.monotonic() + 60
        with suppress(OSError):
            while time.monotonic() < deadline:
                ended = proc.poll() is not None
                if not select.select([master], [], [], 0.2 if ended else 1)[0]:
                    if ended:  # (ended, and nothing more to read)
                        break
                    continue
                if not (chunk := os.read(master, 4096)):
                    break
                shown += chunk
        return shown, proc.wait(timeout=60)
    finally:
        os.close(slave)
        os.close(master)
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()


def test_the_interrupted_line_starts_a_line_of_its_own_at_a_terminal(tmp_path):
    # no bar: the line goes after the echoed ^C, on the next line (a terminal writes \n as \r\n)
    shown, status = _typed_ctrl_c(tmp_path, "none")
    assert (shown, status) == (b"^C\r\ntlm: interrupted\r\n", 130)
    # a bar still drawn: the line goes below it and its ^C
    shown, status = _typed_ctrl_c(tmp_path, "open")
    assert status == 130
    assert b"work:  30%" in shown and b"^C\r\ntlm: interrupted\r\n" in shown, shown
    # a bar closed by the interrupt (cleared, the cursor back at the line's start): no empty line
    shown, status = _typed_ctrl_c(tmp_path, "closed")
    assert status == 130
    assert b"^C" in shown and shown.endswith(b"\rtlm: interrupted\r\n") and shown.count(b"\n") == 1, shown
    # a bar kept on the screen when closed ends its own line: the line goes right below it
    shown, status = _typed_ctrl_c(tmp_path, "closed-kept")
    assert status == 130
    assert shown.endswith(b"]\r\ntlm: interrupted\r\n") and shown.count(b"\n") == 2, shown
    # SIGTERM echoes nothing: its line is printed where the cursor is, at a line's start
    assert _typed_ctrl_c(tmp_path, "sigterm") == (b"tlm: terminated (SIGTERM)\r\n", 143)
    # through a pipe the stderr is the line alone, no line break before it
    for sig in (signal.SIGINT, signal.SIGTERM):
        script = CHILD.format(kind="none").replace("fcntl.ioctl(0, termios.TIOCSCTTY, 0)", "")
        script = script.replace('print("ready", flush=True)', f"os.kill(os.getpid(), {int(sig)})")
        proc = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, timeout=120,
                              env={**os.environ, "PYTHONPATH": str(REPO)})
        said = b"tlm: interrupted\n" if sig == signal.SIGINT else b"tlm: terminated (SIGTERM)\n"
        assert (proc.stderr, proc.returncode) == (said, 128 + sig)


def test_the_first_signal_notes_the_bars_drawn(monkeypatch):
    """What the line break is decided on: the bars on the screen when the signal came."""
    from tqdm import tqdm

    class Screen:  # (a stand-in for a terminal: tqdm draws on it)
        text = ""

        def write(self, s):
            self.text += s

        def flush(self):
            pass

        def isatty(self):
            return True

    screen = Screen()
    monkeypatch.setattr(sys, "stderr", screen)
    try:
        with cli_signals.signals():
            bar = tqdm(total=4, file=screen, leave=False)
            with pytest.raises(KeyboardInterrupt):
                cli_signals.on_signal(signal.SIGINT, None)
            assert [r() for r in cli_signals._BARS] == [bar]
            assert cli_signals.line_break(signal.SIGINT) == "\n"  # still drawn
            bar.close()
            assert cli_signals.line_break(signal.SIGINT) == ""  # closed: its line ended
    finally:
        cli_signals._SIGNALS.clear()
        cli_signals._BARS.clear()
