"""A real browser for the report's tests: Debian's Chromium, driven by Playwright.

:func:`chromium` finds a Chromium binary; where none is installed and the machine has
Debian's ``apt-get`` and root (CI does), it installs the ``chromium`` package from
Debian's registry once, so the browser tests run in CI instead of being skipped. Where
neither is possible the tests fail and say how to install it. ``TLM_CHROMIUM`` names
a binary to use instead.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from functools import cache

NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
VIEWPORT = {"width": 1280, "height": 900}  # one "screen" of the report's budget


def _find() -> str | None:
    named = os.environ.get("TLM_CHROMIUM")
    if named:
        return named
    return next((shutil.which(n) for n in NAMES if shutil.which(n)), None)


@cache
def chromium() -> str:
    """The path of a Chromium binary (installed from Debian's packages if missing and possible)."""
    found = _find()
    if found:
        return found
    if shutil.which("apt-get") and os.geteuid() == 0:
        env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
        install = ["apt-get", "install", "-y", "-q", "--no-install-recommends", "chromium"]
        done = subprocess.run(install, capture_output=True, text=True, env=env, timeout=900)
        if done.returncode != 0:  # a fresh image has no package lists yet
            subprocess.run(["apt-get", "update", "-q"], capture_output=True, env=env, timeout=600)
            done = subprocess.run(install, capture_output=True, text=True, env=env, timeout=900)
        found = _find()
        if found:
            return found
        raise RuntimeError(f"apt-get install chromium failed: {done.stderr[-500:]}")
    raise RuntimeError("no Chromium: install Debian's package (apt-get install chromium) or set TLM_CHROMIUM")


def open_page(playwright, url: str):
    """A headless Chromium page at the report's screen size, loaded with ``url``."""
    browser = playwright.chromium.launch(executable_path=chromium(), args=["--no-sandbox", "--disable-gpu"])
    page = browser.new_page(viewport=VIEWPORT)
    page.goto(url)
    page.wait_for_load_state("load")
    return browser, page
