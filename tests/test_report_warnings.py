"""The warnings the runs recorded appear at the top of the report (tlm/report/warnings.py):
each once, with the runs that recorded it; none, no block."""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from tlm.cli import main

REPO = Path(__file__).resolve().parents[1]
SMALL = ["--set", "resolution=[8,8]", "--set", "render.spp=1", "--set", "render.light_samples=1", "--no-progress"]


def _html(folder: Path) -> str:
    return (folder / "report" / "report.html").read_text()


def test_a_run_s_warnings_head_its_report(tmp_path, cache):
    out = tmp_path / "short"
    assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--out", str(out), "--set", "arch.frames=2",
                 "--outputs", "images", *SMALL]) == 0
    (line,) = json.loads((out / "results.json").read_text())["warnings"]
    page = _html(out)
    assert "<strong>Warnings.</strong> The run recorded 1 warning" in page
    assert line.replace("'", "&#x27;") in page and page.index("Warnings.</strong>") < page.index("<nav>")
    calm = tmp_path / "calm"
    assert main(["run", str(REPO / "configs" / "cornell.yaml"), "--out", str(calm), "--outputs", "images",
                 *SMALL]) == 0
    assert json.loads((calm / "results.json").read_text())["warnings"] == []
    assert 'class="warnings"' not in _html(calm)


def test_a_sweep_s_points_warnings_are_listed_once(tmp_path, cache):
    """A warning every point recorded is one line saying so; one some recorded names them."""
    sweep = tmp_path / "s.yaml"
    sweep.write_text(yaml.safe_dump({"base": {"scene": "cornell", "mode": "rcast", "resolution": [8, 8],
                                              "render": {"light_samples": 1, "spp": 1},
                                              "arch": {"trace": False}},
                                     "grid": {"arch.frames": [2, 5], "arch.page_miss_cycles": [0, 12]}}))
    out = tmp_path / "sw"
    assert main(["sweep", str(sweep), "--out", str(out), "--jobs", "1", "--no-progress"]) == 0
    page = _html(out)
    assert "<strong>Warnings.</strong> 2 of the 4 runs recorded 1 warning" in page
    assert page.count("arch.frames=2 is too short") == 1 and "(2 of 4 runs: " in page


def test_a_sweep_point_s_warnings_are_its_own(tmp_path, cache):
    """Points that share one render (they differ in arch only) each get their own unused-setting
    and stream warnings, not those of the point that rendered the frame."""
    sweep = tmp_path / "s.yaml"
    sweep.write_text(yaml.safe_dump({"base": {"scene": "cornell", "mode": "rcast", "resolution": [8, 8],
                                              "render": {"light_samples": 1, "spp": 1},
                                              "arch": {"trace": False, "tiles_per_pipeline": 3}},
                                     "grid": {"arch.scheduler": ["dynamic", "static"], "arch.frames": [5, 2]}}))
    out = tmp_path / "sw"
    assert main(["sweep", str(sweep), "--out", str(out), "--jobs", "1", "--no-progress", "--no-report"]) == 0
    rows = [json.loads(line) for line in (out / "sweep.jsonl").read_text().splitlines()]
    got = {}
    for row in rows:
        results = json.loads((out / "points" / row["hash"] / "results.json").read_text())
        got[(row["arch.scheduler"], row["arch.frames"])] = [w.split(" ", 1)[0] for w in results["warnings"]]
    # (a dynamic stream of two images runs on past arch.frames until it settles: 2 frames asked is not too short)
    assert got == {("dynamic", 5): [], ("dynamic", 2): [], ("static", 5): ["arch.tiles_per_pipeline"],
                   ("static", 2): ["arch.tiles_per_pipeline", "arch.frames=2"]}


def test_warnings_are_grouped_counted_and_escaped():
    from tlm.report.collect import Inputs, Run
    from tlm.report.warnings import SHOWN_RUNS, recorded, warnings_html

    def run(i: int, warnings: list[str]) -> Run:
        return Run(Path(f"r{i}"), f"r{i}", "run", {"warnings": warnings}, {})

    many = [run(i, ["a <b> & c", "frames too short"] if i % 2 else ["frames too short"]) for i in range(10)]
    inputs = Inputs([Path(".")], runs=many)
    assert recorded(inputs) == [("frames too short", [f"r{i}" for i in range(10)]),
                                ("a <b> & c", [f"r{i}" for i in range(1, 10, 2)])]
    page = warnings_html(inputs)
    assert ("10 of the 10 runs recorded 2 different warnings (results.json <code>warnings</code>; 15 in all)"
            in page) and "a &lt;b&gt; &amp; c" in page
    assert "frames too short<span class=\"note\"> (every run)</span>" in page
    assert f"(5 of 10 runs: {', '.join(f'r{i}' for i in range(1, 2 * SHOWN_RUNS, 2))} and r9)" in page  # (h413)
    assert warnings_html(Inputs([Path(".")], runs=[run(0, [])])) == ""


def test_an_empty_report_title_is_refused(tmp_path, capsys):
    """--title '' was silently the default title."""
    assert main(["report", str(tmp_path), "--title", " "]) == 2
    assert capsys.readouterr().err.strip() == ("tlm: error: tlm report: argument --title: an empty title: give one, "
                                               "or leave --title out for the default")


def test_many_warnings_keep_the_first_screens_and_drop_none():
    """The committed report's 26 warnings (one coarse-packet line per frame's figures) took the page
    past its screens: the box lists the first SHOWN_WARNINGS, the rest one click below, none dropped."""
    from types import SimpleNamespace

    from tlm.report import warnings as box

    words = [f"warning {'abcdefghijk'[i]}" for i in range(11)]  # (no numbers: lines that differ in numbers fold)
    runs = [SimpleNamespace(label=f"run {i}", results={"warnings": [words[i]]}) for i in range(11)]
    page = box.warnings_html(SimpleNamespace(runs=runs, damaged=[]))
    shown, _, hidden = page.partition("<details>")
    assert [f"{words[i]}<" in shown for i in range(11)] == [i < box.SHOWN_WARNINGS for i in range(11)]
    assert all(f"{words[i]}<" in hidden for i in range(box.SHOWN_WARNINGS, 11))
    assert "<summary>3 more warnings</summary>" in hidden and "recorded 11 warnings (" in shown
    few = box.warnings_html(SimpleNamespace(runs=runs[:box.SHOWN_WARNINGS], damaged=[]))
    assert "<details>" not in few and all(f"{words[i]}<" in few for i in range(box.SHOWN_WARNINGS))


def test_warnings_that_differ_only_in_numbers_are_one_item_with_the_others_below():
    """A sweep's points each said arch.fifo_depth's line with their own figures: six long lines that differ only
    in numbers took the committed report past its first screens (stop 67). The box says such lines once, in the
    wording first met, with how many wordings and which runs, and the other wordings one click below it; none is
    dropped, and lines of other kinds keep their own items."""
    from types import SimpleNamespace

    from tlm.report import warnings as box

    depth = "arch.fifo_depth = {} changes no simulated cycle: the {} puts that waited"
    said = [[depth.format(16, 3065), "BSP stopped at 11 of 12 levels"], [depth.format(16, 2985)],
            [depth.format(256, 3065), "cache.pairs = 2 has no effect"], [depth.format(256, 3065)], []]
    runs = [SimpleNamespace(label=f"p{i}", results={"warnings": lines}) for i, lines in enumerate(said)]
    page = box.warnings_html(SimpleNamespace(runs=runs, damaged=[]))
    head, _, items = page.partition("<ul>")
    assert ("4 of the 5 runs recorded 5 different warnings (results.json <code>warnings</code>; 6 in all) of 3 "
            "kinds (lines that "
            "differ only in their numbers are one kind, listed once);") in head
    first, _, rest = items.partition("<details>")
    assert first.startswith(f"<li>{depth.format(16, 3065)}<span class=\"note\"> (in 3 wordings that differ only "
                            "in their numbers, the first met shown; 4 of 5 runs: p0, p1, p2 and p3; this one by "
                            "1 of 5 runs: p0)</span>")
    others, _, after = rest.partition("</details>")
    assert others == (f"<summary>its 2 other wordings</summary><ul><li>{depth.format(16, 2985)}<span class=\"note\">"
                      f" (1 of 5 runs: p1)</span></li><li>{depth.format(256, 3065)}<span class=\"note\"> (2 of 5 runs: "
                      "p2 and p3)</span></li></ul>")
    assert after.startswith("</li><li>BSP stopped at 11 of 12 levels<span class=\"note\"> (1 of 5 runs: p0)</span>")
    assert "cache.pairs = 2 has no effect" in after and page.count("<li>") == 5  # (each wording once)


def test_a_folded_item_names_the_runs_of_the_wording_it_shows():
    """h436: the item of lines that differ only in their numbers named the runs of its kind after the wording it
    shows, and that wording's own runs nowhere: ``light 0 reaches nothing (...; every run)`` of two runs where one
    said ``light 0`` (each run says its own lights' lines, one run several of them). Each wording is said with its
    own runs: the one shown ``this one by``, the others below it."""
    from types import SimpleNamespace

    from tlm.report import warnings as box

    said = [["light 0 reaches nothing", "light 1 reaches nothing"], ["light 1 reaches nothing"]]
    runs = [SimpleNamespace(label=f"p{i}", results={"warnings": lines}) for i, lines in enumerate(said)]
    page = box.warnings_html(SimpleNamespace(runs=runs, damaged=[]))
    assert ("<li>light 0 reaches nothing<span class=\"note\"> (in 2 wordings that differ only in their numbers, the "
            "first met shown; every run; this one by 1 of 2 runs: p0)</span><details><summary>its 1 other wording"
            "</summary><ul><li>light 1 reaches nothing<span class=\"note\"> (every run)</span></li></ul></details>"
            "</li>") in page
    one = box.warnings_html(SimpleNamespace(runs=runs[:1], damaged=[]))  # (a page of one run names no run)
    assert ("<li>light 0 reaches nothing<span class=\"note\"> (in 2 wordings that differ only in their numbers, the "
            "first met shown)</span>") in one and "The run recorded 2 warnings" in one


def test_a_folded_item_past_the_first_screens_is_counted_by_its_lines_and_nests_its_details():
    """h436: a folded item past SHOWN_WARNINGS was counted as one warning in the "more" summary (``1 more
    warning`` over three lines); it says how many items and how many warnings are one click below, and its
    own <details> sits whole inside theirs (each tag closed in order)."""
    from html.parser import HTMLParser
    from types import SimpleNamespace

    from tlm.report import warnings as box

    words = [f"warning {'abcdefgh'[i]}" for i in range(box.SHOWN_WARNINGS)]
    lines = [*words, "moved by 0.14%", "moved by 0.29%", "moved by 1.5%", "warning z"]
    runs = [SimpleNamespace(label=f"run {i}", results={"warnings": [line]}) for i, line in enumerate(lines)]
    page = box.warnings_html(SimpleNamespace(runs=runs, damaged=[]))
    assert ("12 of the 12 runs recorded 12 warnings (results.json <code>warnings</code>) of 10 kinds (lines that "
            "differ only in their numbers are one kind, listed once);") in page
    shown, _, hidden = page.partition("<details>")
    assert all(f"{w}<" in shown for w in words) and "moved" not in shown
    assert hidden.startswith("<summary>2 more kinds, 4 warnings</summary><ul><li>moved by 0.14%")
    assert all(f"{line}<" in hidden for line in lines[box.SHOWN_WARNINGS:]) and page.count("<li>") == 12

    class Tags(HTMLParser):
        def __init__(self):
            super().__init__()
            self.open, self.bad = [], []

        def handle_starttag(self, tag, attrs):
            self.open.append(tag)

        def handle_endtag(self, tag):
            if not self.open or self.open.pop() != tag:
                self.bad.append(tag)

    tags = Tags()
    tags.feed(page)
    assert tags.open == [] and tags.bad == []
