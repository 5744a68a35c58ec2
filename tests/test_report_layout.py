"""The report's layout, measured in a real browser (Chromium through Playwright).

A researcher opens ``plots/report.html`` and should read what the model found on the
first screen and the whole page, before opening any ``<details>``, in at most
:data:`MAX_SCREENS` screens of 1280 x 900 pixels. These tests run in CI (the browser is
installed from Debian's packages where missing: ``tests/browser.py``); they are never
skipped.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.browser import VIEWPORT, open_page

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = ROOT / "plots" / "report.html"
MAX_SCREENS = 8

MEASURE = """() => {
  const boxes = [...document.images].map(i => {
    const r = i.getBoundingClientRect();
    return {x: r.left + scrollX, y: r.top + scrollY, w: r.width, h: r.height,
            ok: i.complete && i.naturalWidth > 0,
            shown: r.width > 0 && r.height > 0 && !i.closest('details:not([open])')};
  });
  const summary = document.querySelector('#summary');
  return {height: document.documentElement.scrollHeight, width: document.documentElement.scrollWidth,
          boxes: boxes, details: document.querySelectorAll('details').length,
          open: document.querySelectorAll('details[open]').length,
          summaryTop: summary ? summary.getBoundingClientRect().top + scrollY : null,
          summaryText: summary ? summary.innerText : ''};
}"""


def measure(page_path: Path) -> dict:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser, page = open_page(p, page_path.as_uri())
        try:
            closed = page.evaluate(MEASURE)
            page.evaluate("() => document.querySelectorAll('details').forEach(d => d.open = true)")
            closed["height_all_open"] = page.evaluate("document.documentElement.scrollHeight")
        finally:
            browser.close()
    return closed


def overlaps(boxes: list[dict]) -> list[tuple[int, int]]:
    shown = [b for b in boxes if b["shown"]]
    bad = []
    for i, a in enumerate(shown):
        for j, b in enumerate(shown[i + 1:], i + 1):
            if (a["x"] < b["x"] + b["w"] - 1 and b["x"] < a["x"] + a["w"] - 1
                    and a["y"] < b["y"] + b["h"] - 1 and b["y"] < a["y"] + a["h"] - 1):
                bad.append((i, j))
    return bad


def check_layout(page_path: Path, max_screens: int = MAX_SCREENS) -> dict:
    m = measure(page_path)
    screens = m["height"] / VIEWPORT["height"]
    assert screens <= max_screens, f"{page_path}: {m['height']} px = {screens:.1f} screens before any <details>"
    assert m["width"] <= VIEWPORT["width"], f"{page_path}: {m['width']} px wide: scrolls sideways"
    assert m["open"] == 0 and m["details"] > 0  # the long parts are there, collapsed
    assert m["height_all_open"] > m["height"]
    assert all(b["ok"] for b in m["boxes"]), "a figure did not decode"
    assert overlaps(m["boxes"]) == []
    assert m["summaryTop"] is not None and m["summaryTop"] < VIEWPORT["height"] / 3  # the summary comes first
    return m


@pytest.mark.slow
@pytest.mark.skipif(not COMMITTED.is_file(), reason="plots/report.html is not committed (tlm plots writes it)")
def test_the_committed_report_reads_in_a_few_screens():
    m = check_layout(COMMITTED)
    for question in ("How fast", "What limits it", "Does it scale", "What quality costs"):
        assert question in m["summaryText"], question  # every question answered from the committed runs


@pytest.mark.slow
def test_the_check_fails_on_a_long_page(tmp_path):
    page = tmp_path / "long.html"
    page.write_text('<!DOCTYPE html><html><body><section id="summary">x</section><details>y</details>'
                    + '<p style="height:1000px">z</p>' * 9 + "</body></html>")
    with pytest.raises(AssertionError, match="screens before any <details>"):
        check_layout(page)


def test_the_check_finds_overlapping_figures():
    a = {"x": 0, "y": 0, "w": 100, "h": 100, "ok": True, "shown": True}
    assert overlaps([a, {**a, "x": 50, "y": 50}]) == [(0, 1)]
    assert overlaps([a, {**a, "x": 100}]) == []


if __name__ == "__main__":  # python -m tests.test_report_layout [PAGE]: the page's height in screens
    import sys

    path = Path(sys.argv[1] if len(sys.argv) > 1 else COMMITTED).resolve()
    m = measure(path)
    print(f"{path}: {m['height']} px = {m['height'] / VIEWPORT['height']:.1f} screens of "
          f"{VIEWPORT['width']}x{VIEWPORT['height']} before any <details>; {m['height_all_open']} px all open")
