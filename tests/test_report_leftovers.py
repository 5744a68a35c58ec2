"""Four report defects a researcher met in the scaling and sweeps sections.

* The idle figures (and the eq. 5.2 figures) of a sweep over ``arch.pipelines`` were titled by the
  sweep folder's name (``[sw]``), where the notes and tables of the same report name the sweep by
  its label (``a/sw`` and ``b/sw`` for two folders named ``sw``). They are titled by the label.
* ``tlm scaling`` wrote one ``scaling_<scene>.png`` for two scenes whose names give one file name
  (``a b`` and ``a_b``): the second overwrote the first. The later gets the report's suffix.
* FPS against a factor of numbers and null (``bsp.levels: [null, 6, 8]``) drew the factor as a
  category, ``None`` a point of its own. The numbers are on an axis of numbers now, and the null
  points are stars at the depth they resolved to (results.json ``scene.bsp.requested_levels``),
  or, where no results folder records it, at a tick ``null`` apart, with a legend entry each.
* The scaling section marked a ``tlm scaling`` folder's figures out of date by the folder's name, so that
  a sweep, or another scaling folder, of the same name was marked too. The marker is the folder's own,
  and a scaling folder is named by the tail of its path that tells it from the section's other folders.

The sweep folders are made by hand (the files and keys the report reads).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import yaml

import tlm.report.sweeps as sweeps
from tlm.cli import main
from tlm.report.collect import read
from tlm.report.common import figure_output
from tlm.report.scaling import scaling_section
from tlm.report.sweeps import sweeps_section
from tlm.scenes.loader import scenes_dir

PMS = ("vertex", "traversal", "intersection", "fragment")
CORNELL = scenes_dir() / "cornell.yaml"


def _results(n: int, source: Path, name: str, work: int = 12000) -> dict:
    """A point's results.json as eq. 5.2 reads it: the work splits over N pipelines."""
    per = {"traversal": 9000 // n, "intersection": work // n, "fragment": 3000 // n}
    return {"scene": {"name": name, "source": str(source)}, "mode": "rcast", "fps": 1e9 / (1000 + work // n),
            "timing": {"pipelines": [per] * n, "throughput_estimate": {"steady": True, "frames": 5}},
            "cycles": {"vertex": 1000, **per, "latency": 2000 + work // n, "throughput": 1000 + work // n}}


def pipelines_sweep(folder: Path, points: list[tuple[int, str, Path, str]]) -> Path:
    """A finished sweep over ``arch.pipelines`` (static scheduler) of the points ``(N, the config's
    scene, the scene file, its name)``, each with a results folder and the rows' idle fractions."""
    (folder / "points").mkdir(parents=True)
    spec = {"sweep": "s.yaml", "grid": {"arch.pipelines": sorted({n for n, *_ in points})}, "points": []}
    rows = []
    for i, (n, scene, source, name) in enumerate(points):
        h = f"{i:016x}"
        res = _results(n, source, name, work=12000 + 1000 * len(name))
        spec["points"].append({"point": i, "hash": h, "factors": {"arch.pipelines": n}})
        rows.append({"point": i, "hash": h, "status": "ok", "error": None, "scene": scene, "mode": "rcast",
                     "arch.pipelines": n, "fps": res["fps"], "cycles.throughput": res["cycles"]["throughput"],
                     **{f"idle.{pm}": round(0.1 * k + 0.02 * n, 6) for k, pm in enumerate(PMS)}})
        (folder / "points" / h).mkdir()
        (folder / "points" / h / "results.json").write_text(json.dumps({**res, "factors": {"arch.pipelines": n}}))
        (folder / "points" / h / "config.resolved.yaml").write_text(yaml.safe_dump(
            {"scene": scene, "mode": "rcast", "seed": 0, "resolution": [16, 16],
             "arch": {"pipelines": n, "scheduler": "static", "frames": 5}}))
    (folder / "sweep.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


def svg_text(out: Path, png: str) -> str:
    return (out / png).with_suffix(".svg").read_text(encoding="utf-8")


# ------------------------------------------------------------ 1. a sweep's scaling figures titled by its label


def test_the_idle_and_eq52_figures_of_two_sweeps_named_alike_are_titled_by_their_labels(tmp_path):
    a = pipelines_sweep(tmp_path / "coll" / "a" / "sw", [(n, "cornell", CORNELL, "cornell") for n in (1, 2, 4)])
    b = pipelines_sweep(tmp_path / "coll" / "b" / "sw", [(n, "cornell", CORNELL, "cornell") for n in (1, 2, 4)])
    c = pipelines_sweep(tmp_path / "coll" / "c" / "sw", [(2, "cornell", CORNELL, "cornell")])  # (one N: a note)
    inputs = read([a, b, c])
    assert [sw.label for sw in inputs.sweeps] == ["a/sw", "b/sw", "c/sw"]
    out = tmp_path / "rep"
    out.mkdir()
    with figure_output("svg"):  # (the SVG keeps each title a text element)
        sec = scaling_section(inputs, out)
    idle = [f for f in sec.figures if f.file.startswith("idle_")]
    assert [f.title for f in idle] == ["cornell: idle fraction per PM against N, from a/sw",
                                       "cornell: idle fraction per PM against N, from b/sw"]
    for fig, label in zip(idle, ("a/sw", "b/sw"), strict=True):
        text = svg_text(out, fig.file)
        assert f"cornell: idle fraction per PM, static [{label}]" in text and "[sw]" not in text, fig.file
    eq52 = [f for f in sec.figures if f.file.startswith("scaling_")]
    assert [f.title for f in eq52] == ["cornell: scaling from a/sw", "cornell: scaling from b/sw"]
    for fig, label in zip(eq52, ("a/sw", "b/sw"), strict=True):
        text = svg_text(out, fig.file)
        assert f"cornell: speed-up [{label}]" in text and "[sw]" not in text, fig.file
    # the file names are as they were (the folder's name and the suffix of a clash)
    assert idle[0].file == "idle_sw_cornell.png" and idle[1].file.startswith("idle_sw_cornell_")
    # the notes name the sweep by its label too
    assert "c/sw: cornell/rcast: no idle figure: one value of N only" in sec.notes, sec.notes


# ------------------------------------------------------------ 2. tlm scaling: one figure per scene, whatever its name


def test_two_scenes_whose_names_give_one_file_name_get_two_scaling_figures(tmp_path):
    """Scene files ``a b.yaml`` and ``a_b.yaml`` (named so by their configs, as the report names
    them): ``scaling_a_b.yaml.png`` was written twice, the second over the first; now the later
    gets the suffix, and the report shows each."""
    files = {}
    for stem, name in (("one", "a b"), ("two", "a_b")):
        files[name] = tmp_path / f"{name}.yaml"
        files[name].write_text(CORNELL.read_text().replace("name: cornell", f"name: {stem}", 1) + f"# {stem}\n")
    sw = pipelines_sweep(tmp_path / "sw", [(n, files[name].name, files[name], name)
                                           for name in ("a b", "a_b") for n in (1, 2, 4)])
    assert main(["scaling", str(sw), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    meta = json.loads((tmp_path / "eq" / "eq52.json").read_text())
    assert {f["scene"] for f in meta["fits"]} == {"a b.yaml", "a_b.yaml"}
    pngs = sorted(p.name for p in (tmp_path / "eq").glob("scaling_*.png"))
    assert len(pngs) == 2, pngs  # (one before: the second figure overwrote the first)
    assert pngs[0] == "scaling_a_b.yaml.png" and pngs[1].startswith("scaling_a_b.yaml_") and len(pngs[1]) == len(
        "scaling_a_b.yaml_01234567.png"), pngs
    assert (tmp_path / "eq" / pngs[0]).read_bytes() != (tmp_path / "eq" / pngs[1]).read_bytes()
    # the same scenes get the same names again
    assert main(["scaling", str(sw), "--out", str(tmp_path / "eq"), "--no-report"]) == 0
    assert sorted(p.name for p in (tmp_path / "eq").glob("scaling_*.png")) == pngs
    # the report links a figure of each scene, each its own file
    out = tmp_path / "rep"
    out.mkdir()
    sec = scaling_section(read([tmp_path / "eq"]), out)
    figs = [f for f in sec.figures if f.file.startswith("scaling_")]
    assert len(figs) == 2 and len({f.file for f in figs}) == 2, [f.file for f in figs]
    assert all((out / f.file).is_file() for f in figs)
    assert sorted(f.title.split(": scaling from")[0] for f in figs) == sorted(
        str(files[n]) for n in ("a b", "a_b"))  # (without its sweeps' runs, the report names such a scene by its file)


# ------------------------------------------------------------ 3. a factor of numbers and null


def levels_sweep(root: Path, resolved: bool = True, fifos=(1, 16), levels=(None, 6, 8)) -> Path:
    """A sweep over ``bsp.levels`` (null, 6, 8) x ``arch.fifo_depth``: null builds the thesis's depth,
    floor(ln 2604) = 7, which each point's results.json records unless not ``resolved`` (an older tlm's)."""
    root.mkdir()
    (root / "sweep.yaml").write_text(yaml.safe_dump({"sweep": "s.yaml", "description": "16x16 RCast",
                                                     "grid": {"bsp.levels": list(levels),
                                                              "arch.fifo_depth": list(fifos)}}))
    rows = []
    for i, (lv, fifo) in enumerate((lv, f) for lv in levels for f in fifos):
        depth = 7 if lv is None else lv
        fps = 20.0 - depth + fifo / 100
        h = f"h{i:03d}"
        rows.append({"point": i, "hash": h, "status": "ok", "scene": "cornell", "mode": "rcast", "bsp.levels": lv,
                     "arch.fifo_depth": fifo, "fps": fps, "cycles.throughput": 6e8 / fps,
                     "cycles.traversal": 1000 + 100 * depth, "cycles.intersection": 900})
        bsp = {"levels": depth, "requested_levels": depth, "truncated": False} if resolved else {}
        results = {"scene": {"name": "cornell", "source": str(CORNELL), "resolution": [16, 16], "triangles": 2604,
                             "bsp": bsp},
                   "mode": "rcast", "fps": fps, "factors": {"bsp.levels": lv, "arch.fifo_depth": fifo},
                   "cycles": {"vertex": 10, "traversal": 1000 + 100 * depth, "intersection": 900, "fragment": 100,
                              "throughput": 6e8 / fps, "latency": 2000},
                   "timing": {"frames": 1, "units": {}}}
        point = root / "points" / h
        point.mkdir(parents=True)
        (point / "results.json").write_text(json.dumps(results))
        (point / "config.resolved.yaml").write_text(yaml.safe_dump(
            {"scene": "cornell", "mode": "rcast", "bsp": {"levels": lv}, "arch": {"fifo_depth": fifo}}))
    (root / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return root


def levels_figure(monkeypatch, folder: Path, out: Path):
    """The FPS-against-bsp.levels figure of the sweeps section (the matplotlib figure), and its record."""
    drawn = {}
    save = sweeps.save

    def keep(fig, where, name, title, caption=""):
        drawn[title] = fig
        return save(fig, where, name, title, caption)

    monkeypatch.setattr(sweeps, "save", keep)
    out.mkdir()
    sec = sweeps_section(read([folder]), out)
    (record,) = [f for f in sec.figures if f.title.endswith("FPS against bsp.levels")]
    assert (out / record.file).is_file()
    return drawn[record.title].axes[0], record


def _stars(ax) -> list:
    return [ln for ln in ax.get_lines() if ln.get_marker() == "*" and len(ln.get_xdata())]


def test_null_among_the_levels_is_drawn_at_the_depth_it_resolved_to_on_a_numeric_axis(tmp_path, monkeypatch):
    ax, record = levels_figure(monkeypatch, levels_sweep(tmp_path / "L"), tmp_path / "rep")
    lines = {ln.get_label(): ln for ln in ax.get_lines() if not ln.get_label().startswith("_")}
    # the numbers on an axis of numbers, joined by lines (before: categories None, 6, 8 at 0, 1, 2)
    assert [float(x) for x in lines["fifo_depth=1"].get_xdata()] == [6.0, 8.0]
    assert [float(x) for x in lines["fifo_depth=16"].get_xdata()] == [6.0, 8.0]
    assert lines["fifo_depth=1"].get_linestyle() != "None"
    assert "None" not in [t.get_text() for t in ax.get_xticklabels()]
    # the null points: stars at level 7, one per combination, of its line's colour, joined to nothing
    stars = _stars(ax)
    assert sorted((float(x), float(y)) for s in stars for x, y in zip(s.get_xdata(), s.get_ydata(), strict=True)) \
        == [(7.0, 13.01), (7.0, 13.16)]
    assert {s.get_markeredgecolor() for s in stars} == {lines["fifo_depth=1"].get_color(),
                                                       lines["fifo_depth=16"].get_color()}
    assert all(s.get_linestyle() == "None" for s in stars)
    legend = [t.get_text().replace("\n", " ") for t in ax.figure.legends[0].get_texts()]
    assert "bsp.levels null (floor(ln n), the thesis's depth), at the depth it resolved to: 7" in legend, legend
    assert "results.json scene.bsp.requested_levels: 7" in record.caption


def test_null_among_the_levels_without_the_depth_recorded_is_a_marked_point_apart(tmp_path, monkeypatch):
    ax, record = levels_figure(monkeypatch, levels_sweep(tmp_path / "U", resolved=False), tmp_path / "rep")
    lines = {ln.get_label(): ln for ln in ax.get_lines() if not ln.get_label().startswith("_")}
    assert [float(x) for x in lines["fifo_depth=1"].get_xdata()] == [6.0, 8.0]
    stars = _stars(ax)
    xs = {float(x) for s in stars for x in s.get_xdata()}
    assert len(xs) == 1 and xs.pop() < 6  # (left of the numbers)
    ticks = {t.get_text(): float(t.get_position()[0]) for t in ax.get_xticklabels()}
    assert ticks["null"] < 6 and {"6", "7", "8"} <= set(ticks), ticks
    assert ticks["null"] == float(stars[0].get_xdata()[0])
    legend = [t.get_text().replace("\n", " ") for t in ax.figure.legends[0].get_texts()]
    assert 'bsp.levels null (floor(ln n), the thesis\'s depth), depth not recorded: at "null"' in legend, legend
    assert "2 points of bsp.levels null" in record.caption


def test_null_among_the_levels_with_a_band_is_a_star_at_its_depth(tmp_path, monkeypatch):
    """More than 8 distinct lines: the median and the min-max band, the null points a star at the
    median of their FPS with a bar over their range."""
    ax, record = levels_figure(monkeypatch, levels_sweep(tmp_path / "M", fifos=tuple(range(1, 12))), tmp_path / "rep")
    assert "the band at each value of bsp.levels" in record.caption
    median = next(ln for ln in ax.get_lines() if ln.get_label() == "median")
    assert [float(x) for x in median.get_xdata()] == [6.0, 8.0]
    (star,) = _stars(ax)
    assert float(star.get_xdata()[0]) == 7.0 and abs(float(star.get_ydata()[0]) - (13 + 0.06)) < 1e-9



# ------------------------------------------------------------ 4. "out of date" is a scaling folder's, not a name's


def _stale_fit(sweep: Path, out: Path) -> Path:
    """A ``tlm scaling`` folder ``out`` fitted from ``sweep`` (N = 1, 2, 4), the sweep then run again into its
    folder with N = 8 too: the fit no longer shows the points its sweep holds (out of date)."""
    pipelines_sweep(sweep, [(n, "cornell", CORNELL, "cornell") for n in (1, 2, 4)])
    assert main(["scaling", str(sweep), "--out", str(out), "--no-report"]) == 0
    shutil.rmtree(sweep)
    pipelines_sweep(sweep, [(n, "cornell", CORNELL, "cornell") for n in (1, 2, 4, 8)])
    return out


def _eq52_titles(sec) -> list[str]:
    """The eq. 5.2 figures' titles, each checked to be marked out of date in its caption as in its title."""
    figs = [f for f in sec.figures if f.file.startswith("scaling_")]
    for f in figs:
        assert f.title.endswith(" (out of date)") == f.caption.startswith("Out of date: "), (f.title, f.caption)
    return [f.title for f in figs]


def test_a_sweep_named_as_a_stale_scaling_folder_is_not_out_of_date(tmp_path):
    """A sweep over N in a folder ``sw`` and a stale ``tlm scaling`` folder also named ``sw``: the marker
    was looked up by the folder's name, so the fit of the sweep as it is now was marked out of date too
    (and both figures were titled "scaling from sw")."""
    fit = _stale_fit(tmp_path / "src" / "sw", tmp_path / "fits" / "sw")
    fresh = pipelines_sweep(tmp_path / "now" / "sw", [(n, "cornell", CORNELL, "cornell") for n in (1, 2, 4)])
    out = tmp_path / "rep"
    out.mkdir()
    sec = scaling_section(read([fit, fresh]), out)
    assert [t.endswith(" (out of date)") for t in _eq52_titles(sec)] == [True, False], _eq52_titles(sec)
    assert _eq52_titles(sec) == ["cornell: scaling from fits/sw (out of date)", "cornell: scaling from sw"]
    (note,) = [n for n in sec.notes if "out of date" in n]
    assert note.startswith("fits/sw: out of date: its sweep "), note


def test_of_two_scaling_folders_named_alike_only_the_stale_one_is_out_of_date(tmp_path):
    stale = _stale_fit(tmp_path / "src" / "sw", tmp_path / "a" / "eq")
    other = pipelines_sweep(tmp_path / "src2" / "sw", [(n, "cornell", CORNELL, "cornell") for n in (1, 2, 4)])
    assert main(["scaling", str(other), "--out", str(tmp_path / "b" / "eq"), "--no-report"]) == 0
    out = tmp_path / "rep"
    out.mkdir()
    sec = scaling_section(read([stale, tmp_path / "b" / "eq"]), out)
    assert [t.endswith(" (out of date)") for t in _eq52_titles(sec)] == [True, False], _eq52_titles(sec)
    # (each folder named by the tail of its path that tells it from the other: "eq" named both)
    assert _eq52_titles(sec) == ["cornell: scaling from a/eq (out of date)", "cornell: scaling from b/eq"]
    (note,) = [n for n in sec.notes if "out of date" in n]
    assert note.startswith("a/eq: out of date: its sweep "), note
