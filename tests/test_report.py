"""``tlm report``: the page and its figures from small runs, sweeps and studies in tmp_path.

The sections' own content is tested in test_report_tables.py and test_report_cycles.py;
here: the report builds from every kind of folder, every figure exists and is not
blank, the page references only files that exist (and nothing on the network), the
commands write it unless ``--no-report``, bad input gets one line and exit status 2,
and (when Chromium is installed) the page loads in a browser with every image decoded.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
import yaml
from matplotlib.image import imread

from tests.browser import chromium
from tests.test_report_layout import check_layout
from tlm.cli import main
from tlm.report import build_report
from tlm.report.collect import read

TINY = ["--set", "resolution=[32,32]", "--set", "arch.frames=1", "--set", "render.light_samples=1"]
SECTIONS = ("summary", "tables", "images", "scaling", "sweeps", "cycles", "tradeoff", "peers", "extreme", "provenance")


class Refs(HTMLParser):
    """Every href and src of a page, and its section ids."""

    def __init__(self):
        super().__init__()
        self.refs: list[str] = []
        self.ids: list[str] = []

    def handle_starttag(self, tag, attrs):
        for k, v in attrs:
            if k in ("href", "src") and v is not None:
                self.refs.append(v)
            if tag == "section" and k == "id":
                self.ids.append(v)


def parse(page: Path) -> Refs:
    p = Refs()
    p.feed(page.read_text(encoding="utf-8"))
    return p


def nonblank(png: Path) -> float:
    """The pixel standard deviation of a PNG (0 for a blank image)."""
    return float(np.asarray(imread(png), dtype=float)[..., :3].std())


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A run (pmap, with its automatic report), a 2-point sweep over pipelines and a granularity study."""
    root = tmp_path_factory.mktemp("report")
    assert main(["run", "configs/cornell_pmap.yaml", "--out", str(root / "run"), *TINY,
                 "--set", "photons.count=1500", "--no-reference"]) == 0
    sweep = root / "sweep.yaml"
    sweep.write_text(yaml.safe_dump({
        "base": {"scene": "ring", "mode": "rcast", "resolution": [32, 32], "render": {"light_samples": 1},
                 "arch": {"frames": 1}},
        "grid": {"arch.pipelines": [1, 2], "arch.scheduler": ["static", "dynamic"]}}))
    assert main(["sweep", str(sweep), "--out", str(root / "sweep"), "--jobs", "1", "--no-progress",
                 "--no-report"]) == 0
    gran = root / "gran.yaml"
    gran.write_text(yaml.safe_dump({
        "base": {"scene": "ring", "mode": "rcast", "resolution": [32, 32], "render": {"light_samples": 1},
                 "arch": {"frames": 1}},
        "packet_sizes": [1, 64, 1024]}))
    assert main(["granularity", str(gran), "--out", str(root / "gran"), "--no-report"]) == 0
    return root


@pytest.fixture(scope="module")
def combined(folders):
    out = folders / "combined"
    assert main(["report", str(folders / "run"), str(folders / "sweep"), str(folders / "gran"),
                 "--out", str(out), "--title", "all of it"]) == 0
    return out / "report.html"


@pytest.mark.slow
def test_run_writes_its_report(folders):
    page = folders / "run" / "report" / "report.html"
    assert page.is_file()
    refs = parse(page)
    assert refs.ids == list(SECTIONS)
    pngs = sorted((folders / "run" / "report").glob("*.png"))
    assert pngs, "a pmap run's report has figures (tables, images, cycles, peers)"
    linked = {r for r in refs.refs if r.endswith(".png")}
    assert linked == {p.name for p in pngs}, "every PNG is on the page and every linked PNG exists"


@pytest.mark.slow
def test_every_figure_is_drawn(combined):
    pngs = sorted(combined.parent.glob("*.png"))
    assert len(pngs) >= 8
    for p in pngs:
        assert p.stat().st_size > 5000, p.name
        assert nonblank(p) > 0.02, f"{p.name} is blank"


@pytest.mark.slow
def test_page_references_only_files_that_exist(combined):
    refs = parse(combined)
    assert refs.ids == list(SECTIONS)
    local = [r for r in refs.refs if not r.startswith(("data:", "#"))]
    assert local, "figures link to their PNG files"
    for r in local:
        assert not re.match(r"^[a-z]+://", r), f"the page reaches out to {r}"
        assert (combined.parent / r.partition("#")[0]).is_file(), r  # (a link into a page: its file)
    for r in refs.refs:
        if r.startswith("#"):
            assert r[1:] in refs.ids, r
    text = combined.read_text(encoding="utf-8")
    assert "<script" not in text and "http://" not in text and "https://" not in text
    assert text.count("data:image/png;base64,") == len(list(combined.parent.glob("*.png")))


@pytest.mark.slow
def test_sections_say_why_they_are_empty(combined):
    text = combined.read_text(encoding="utf-8")
    # no error-vs-cost study among the inputs: section 6 has the granularity curve and says so for (a)
    assert "<h2>1. " in text and "<h2>9. " in text
    extreme = text[text.index('id="extreme"'):text.index('id="provenance"')]
    assert "Nothing to show: no &#x27;tlm extreme&#x27; folder" in extreme
    tradeoff = text[text.index('id="tradeoff"'):text.index('id="peers"')]
    assert "error-vs-cost" in tradeoff


@pytest.mark.slow
def test_provenance_names_every_run(combined, folders):
    text = combined.read_text(encoding="utf-8")
    prov = text[text.index('id="provenance"'):]
    inputs = read([folders / "run", folders / "sweep", folders / "gran"])
    assert len(inputs.runs) == 5  # the run and the four sweep points
    for run in inputs.runs:
        assert str(run.path) in prov
        assert run.results["git_revision"] is None or run.results["git_revision"][:12] in prov
    assert prov.count("resolved config") >= 5
    gran = json.loads((folders / "gran" / "provenance.json").read_text())
    assert gran["versions"]["numpy"] in prov


@pytest.mark.slow
def test_scaling_section_fits_the_sweep(combined):
    text = combined.read_text(encoding="utf-8")
    scaling = text[text.index('id="scaling"'):text.index('id="sweeps"')]
    assert "Nothing to show" not in scaling
    assert (combined.parent / "scaling_sweep_ring.png").is_file()


def test_no_report_flag(tmp_path):
    assert main(["run", "configs/ring.yaml", "--out", str(tmp_path / "r"), *TINY, "--no-report"]) == 0
    assert (tmp_path / "r" / "results.json").is_file()
    assert not (tmp_path / "r" / "report").exists()


@pytest.mark.slow
def test_report_again_replaces_the_report(folders, tmp_path):
    out = tmp_path / "rep"
    first = build_report([folders / "gran"], out)
    (out / "stale.png").write_bytes(b"x")
    second = build_report([folders / "gran"], out)
    assert first == second and second.is_file()
    assert not (out / "stale.png").exists()


@pytest.mark.slow
def test_folder_of_folders(folders, tmp_path):
    """``tlm report runs/`` reads every tlm folder one level down."""
    build_report([folders], tmp_path / "all")
    (tmp_path / "all" / "oracle").mkdir()  # bench_oracle's images: kept when the report is rewritten
    (tmp_path / "all" / "oracle" / "x.png").write_bytes(b"png")
    (tmp_path / "all" / "stale.png").write_bytes(b"old")  # anything else of an earlier report goes
    page = build_report([folders], tmp_path / "all")
    assert (tmp_path / "all" / "oracle" / "x.png").read_bytes() == b"png"
    assert not (tmp_path / "all" / "stale.png").exists()
    inputs = read([folders])
    assert {s.kind for s in inputs.studies} == {"granularity"}
    assert len(inputs.sweeps) == 1
    assert page.is_file()


@pytest.mark.slow
@pytest.mark.parametrize("argv, words", [
    (["report", "{tmp}/nothing"], "not found"),
    (["report", "{tmp}"], "holds no tlm output"),
    (["report", "{run}", "{gran}"], "--out"),
    (["report", "{gran}", "--out", "{tmp}/occupied"], "not an earlier tlm output"),
])
def test_bad_input(argv, words, folders, tmp_path, capsys):
    (tmp_path / "occupied").mkdir()
    (tmp_path / "occupied" / "keep.txt").write_text("mine")
    argv = [a.format(tmp=tmp_path, run=folders / "run", gran=folders / "gran") for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("tlm: error:") and words in err and len(err.splitlines()) == 1
    assert (tmp_path / "occupied" / "keep.txt").read_text() == "mine"
    assert not list(tmp_path.glob(".*tmp*"))


def test_unreadable_results_file(tmp_path, capsys):
    bad = tmp_path / "run"
    bad.mkdir()
    (bad / "results.json").write_text("{not json")
    assert main(["report", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "results.json" in err and "cannot read" in err
    assert not (bad / "report").exists()


CHECK = """<script>
window.addEventListener('load', () => {
  const imgs = [...document.images];
  const ok = imgs.filter(i => i.complete && i.naturalWidth > 0).length;
  document.title = 'IMAGES ' + ok + '/' + imgs.length;
});
</script>"""


@pytest.mark.slow
def test_page_loads_in_headless_chromium(combined, tmp_path):
    """Chromium opens the page without a failed load, and decodes every embedded figure."""
    page = tmp_path / "check.html"
    page.write_text(combined.read_text(encoding="utf-8").replace("</body>", CHECK + "</body>"), encoding="utf-8")
    for png in combined.parent.glob("*.png"):
        shutil.copy(png, tmp_path / png.name)
    cmd = [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={tmp_path / 'profile'}", "--enable-logging=stderr", "--v=0",
           "--virtual-time-budget=10000", "--dump-dom", page.as_uri()]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    n = len(list(combined.parent.glob("*.png")))
    assert f"<title>IMAGES {n}/{n}</title>" in done.stdout, done.stdout[:500]
    for bad in ("Failed to load resource", "net::ERR_", "Uncaught"):
        assert bad not in done.stderr, done.stderr[-2000:]


@pytest.mark.slow
def test_the_combined_report_reads_in_a_few_screens(combined):
    """Runs, sweeps and studies together: the summary first, the page within the screen budget."""
    check_layout(combined)
