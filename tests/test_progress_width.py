"""The progress bars (tlm.progress.progress_bar) on a terminal that reports no size (0 x 0: a
pty whose size was never set, as under `script` and on some CI runners) are drawn 80 columns
wide, or $COLUMNS wide, and follow the terminal once it has a size; a bar given ``eta_after``
(a sweep's) shows no time left until that fraction of its steps is done, then the steps left
at the mean rate since it began."""

from __future__ import annotations

import fcntl
import os
import struct
import sys
import termios

import pytest

from tlm import progress
from tlm.progress import progress_bar


@pytest.fixture
def terminal(monkeypatch):
    """A fresh pty (0 x 0 until sized): (the master's fd, its other side as a file, which
    :func:`_on` makes stderr)."""
    master, slave = os.openpty()
    stderr = os.fdopen(slave, "w", buffering=1)
    monkeypatch.delenv("COLUMNS", raising=False)
    monkeypatch.delenv("LINES", raising=False)
    yield master, stderr
    stderr.close()
    os.close(master)


def _on(monkeypatch, stderr) -> None:
    """stderr on the pty (in the test itself: pytest puts its own capture back as a test starts)."""
    monkeypatch.setattr(sys, "stderr", stderr)


def _size(fd: int, cols: int, rows: int) -> None:
    fcntl.ioctl(fd, termios.TIOCSWINSZ, struct.pack("HHHH", rows, cols, 0, 0))


def _shown(master: int) -> list[str]:
    """The bar's redraws written so far (each after a carriage return), without the padding."""
    os.set_blocking(master, False)
    data = b""
    while True:
        try:
            chunk = os.read(master, 65536)
        except BlockingIOError:
            break
        if not chunk:
            break
        data += chunk
    return [part.rstrip("\n") for part in data.decode().replace("\r\n", "\n").split("\r") if part.strip()]


def test_a_bar_on_a_terminal_of_no_size_is_drawn_80_columns_wide(terminal, monkeypatch):
    master, stderr = terminal
    _on(monkeypatch, stderr)
    assert tuple(os.get_terminal_size(stderr.fileno())) == (0, 0)
    with progress_bar(True, desc="sweep", total=10, unit="point") as bar:
        for _ in range(3):
            bar.update(1)
            bar.refresh()
    shown = _shown(master)
    assert any("3/10" in line for line in shown), shown
    assert {len(line.rstrip()) for line in shown if "/10" in line} == {79}, shown  # (a full line would wrap)


def test_a_bar_takes_columns_from_the_environment_and_follows_a_resize(terminal, monkeypatch):
    master, stderr = terminal
    _on(monkeypatch, stderr)
    monkeypatch.setenv("COLUMNS", "100")
    bar = progress_bar(True, desc="sweep", total=10, unit="point")
    bar.update(1)
    bar.refresh()
    assert [len(line) for line in _shown(master) if "1/10" in line][-1:] == [99]
    _size(stderr.fileno(), 120, 40)  # the terminal gets a size: it wins over $COLUMNS
    bar.update(1)
    bar.refresh()
    assert [len(line) for line in _shown(master) if "2/10" in line][-1:] == [119]
    bar.close()
    with open(os.devnull, "w") as nothing:  # no terminal: tqdm's own width
        assert progress.terminal_shape(nothing) == (None, None)


def test_a_sweep_bar_shows_no_time_left_until_a_tenth_of_its_points_is_done(terminal, monkeypatch):
    master, stderr = terminal
    _on(monkeypatch, stderr)
    _size(stderr.fileno(), 100, 24)
    clock = [1000.0]
    # 20 points done before: 80 to run, so the time left shows from the 8th on
    bar = progress_bar(True, eta_after=progress.SWEEP_ETA_AFTER, desc="sweep", total=100, initial=20, unit="point")
    bar._time = lambda: clock[0]
    bar.start_t = bar.last_print_t = clock[0]

    def at(t: float, points: int) -> str:
        for i in range(points):  # (the points at even steps up to t)
            clock[0] = 1000.0 + t - (points - 1 - i) * 0.5
            bar.update(1)
        return str(bar)

    assert "21/100 [00:40<?, " in at(40, 1)  # a slow first point (it renders the frame)
    assert "27/100 [00:47<?, " in at(47, 6)
    # 8 points done: the time left is the points left at the rate of the last half of the time
    # (25 s): the 40 s first point counts for the 15 s of it in that half, so 7.375 points in
    # 25 s: 72 / 0.295 = 244 s
    assert "28/100 [00:50<04:04, " in at(50, 1)
    # 20 points in the last 50 s: 52 / 0.4 = 130 s (the mean since the start, 28 in 100 s, would
    # give 185 s; tqdm's moving average of the last points, 0.5 s apart, 26 s)
    assert "48/100 [01:40<02:10,  2.50s/point]" in at(100, 20), str(bar)
    clock[0] = 1300.0  # none done in the last half (150 s): no time left shown
    assert "48/100 [05:00<?, " in str(bar)
    bar.close()
    shown = _shown(master)
    assert any("<?, " in line for line in shown) and any("<04:04, " in line for line in shown), shown
