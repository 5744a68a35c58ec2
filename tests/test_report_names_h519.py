"""h519 (found by probe h518): a folder's, a scene's or a sweep factor's name with ``$`` (or a tab) is drawn in the
report's figures as written.

Figure text built from names reached matplotlib unescaped: ``tlm run --out 'bad$\\frac$x'`` wrote no report
(``ValueError: \\frac ... ParseSyntaxException``, exit 1), ``m$x^2$`` was drawn as a formula, and a tab printed
matplotlib's ``Glyph 9 missing`` warnings on stderr. Now every text a figure draws from a name is drawn as written
(:func:`tlm.report.common._drawable_texts`), a tab as a space, as a ``tlm:`` line and the page show it; tlm's own
mathtext (a log axis's ``10^{3}``) is still drawn as mathtext.
"""

from __future__ import annotations

import json
import re
import warnings
from pathlib import Path

import pytest
import yaml

from tlm.config import config_from_dict
from tlm.experiments.run import run as run_experiment
from tlm.report import build_report
from tlm.report.common import figure_output, log_ticks, new_figure, write_png
from tlm.scenes.loader import scenes_dir

TINY = {"seed": 0, "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1}, "arch": {"trace": False},
        "mode": "rcast"}
FOLDER = "bad$\\frac$x\tt"  # (a run folder's name)
SCENE = "m$x^2$ frac\tz"  # (a scene file's name, its label)
VALUES = ("a$\\frac$b", "c\td$x$")  # (a sweep factor's values)
SHOWN = ("bad$\\frac$x t", "m$x^2$ frac z", "a$\\frac$b", "c d$x$")  # (as drawn: a tab as a space)


def _svg_texts(folder: Path) -> list[str]:
    """The text of every ``<text>`` element of the SVG files in ``folder`` (the figures keep their text as text)."""
    import html
    return [html.unescape(t) for f in sorted(folder.glob("*.svg"))
            for t in re.findall(r"<text[^>]*>([^<]*)", f.read_text(encoding="utf-8"))]


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """A report of a run (its folder :data:`FOLDER`, its scene file :data:`SCENE`) and a sweep over the scene (rows
    only) of the values :data:`VALUES`, its figures as PNG and SVG; what was printed, and the warnings raised."""
    root = tmp_path_factory.mktemp("h519")
    scene = root / f"{SCENE}.yaml"
    scene.write_text((scenes_dir() / "cornell.yaml").read_text(encoding="utf-8"), encoding="utf-8")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(root / "cache"))
        run_experiment(config_from_dict({**TINY, "scene": str(scene)}, "test"), root / FOLDER)
    sweep = root / "sw"
    sweep.mkdir()
    (sweep / "sweep.yaml").write_text(yaml.safe_dump({"sweep": "s.yaml", "description": "16x16 RCast",
                                                      "grid": {"scene": list(VALUES)}}))
    rows = [{"point": i, "hash": f"h{i}", "status": "ok", "scene": v, "mode": "rcast", "fps": 100.0 + 50 * i,
             "cycles.throughput": 6e6 / (100.0 + 50 * i)} for i, v in enumerate(VALUES)]
    (sweep / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    with warnings.catch_warnings(record=True) as caught, figure_output(("png", "svg")):
        warnings.simplefilter("always")
        page = build_report([root / FOLDER, sweep], root / "report")
    return Path(page), caught


def test_names_with_dollars_a_frac_and_a_tab_are_drawn_as_written(report, capfd):
    page, caught = report
    assert page.is_file()
    texts = _svg_texts(page.parent)
    for shown in SHOWN:
        assert any(shown in t for t in texts), (shown, [t for t in texts if "$" in t])
    assert not any("\t" in t for t in texts)
    assert not [str(w.message) for w in caught if "Glyph" in str(w.message) or "mathtext" in str(w.message).lower()]
    assert "Glyph" not in capfd.readouterr().err


def test_tlms_own_mathtext_on_a_log_axis_is_still_mathtext(tmp_path):
    fig = new_figure(4, 3)
    ax = fig.add_subplot()
    ax.plot([1e5, 1e8], [1, 2], label="m$x^2$")
    ax.set_xscale("log")
    log_ticks(ax)
    ax.set_title("bad$\\frac$x")
    ax.legend()
    with figure_output(("png", "svg")):
        write_png(fig, tmp_path / "f.png")
    texts = _svg_texts(tmp_path)
    assert "bad$\\frac$x" in texts and "m$x^2$" in texts
    ticks = [t for t in ax.xaxis.get_ticklabels() if t.get_text()]
    assert ticks and all(t.get_text().startswith("$\\mathdefault{") and t.get_parse_math() for t in ticks)
    assert not any("mathdefault" in t for t in texts)  # (the powers of ten drawn as mathtext: glyph by glyph)


def test_the_helpers():
    from tlm.report.common import figure_text

    assert figure_text("a\tb\x1bc\nd") == "a b\\x1bc\nd"  # (a line break kept: tlm's own, a wrapped title's)
    assert figure_text("m$x^2$", True) == "m\\$x^2\\$"  # (a tick label's: drawn as mathtext where in $)
