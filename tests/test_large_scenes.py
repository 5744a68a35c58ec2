"""Large scenes in bounded memory: batched renders, ``tlm run --outputs``, progress bars.

A run renders its image in batches of ``render.batch_rays`` eye rays, every pass of a
batch before the next, the cache pairs carried over: the images, work counts and AOVs
must be those of one whole-image batch, bit for bit. The folder's optional outputs are
chosen with ``--outputs``; progress bars go to stderr only when it is a terminal.
"""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
import yaml

from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments.reference import compute_reference
from tlm.experiments.reference_cache import ReferenceSettings
from tlm.experiments.run import parse_outputs, render, write_run
from tlm.experiments.thesis import run_thesis
from tlm.render.batches import Primary
from tlm.render.frame import GBuffer, ImageGBuffer, cast, pixel_batches

SMALL = {"scene": "cornell", "resolution": [23, 17], "photons": {"count": 1500},
         "arch": {"frames": 2, "packet_size": 32, "trace": False}}


def _render(mode: str, batch_rays: int, **extra):
    # (one thread: several would cut the image into more batches, tests/test_threads.py)
    return render(config_from_dict({**SMALL, "mode": mode, **extra,
                                    "render": {**extra.get("render", {}), "batch_rays": batch_rays, "threads": 1}}))


def _assert_same(a, b) -> None:
    assert list(a.radiance) == list(b.radiance) and list(a.work) == list(b.work)
    for name in a.radiance:
        assert a.radiance[name].dtype == b.radiance[name].dtype
        np.testing.assert_array_equal(a.radiance[name], b.radiance[name], err_msg=name)
    for name in a.work:
        assert list(a.work[name]) == list(b.work[name])
        for k, v in a.work[name].items():
            assert v.dtype == b.work[name][k].dtype == np.int32
            np.testing.assert_array_equal(v, b.work[name][k], err_msg=f"{name}.{k}")
    for f in ("origin", "direction", "t", "triangle", "normal", "sees_light"):
        np.testing.assert_array_equal(getattr(a.primary, f), getattr(b.primary, f), err_msg=f)
    assert (a.primary.rays, a.primary.hits) == (b.primary.rays, b.primary.hits)


@pytest.mark.slow
@pytest.mark.parametrize(("mode", "extra"), [
    ("refract", {}),  # four jittered eye rays per pixel, Fresnel-split glass, shadow rays
    ("pmap", {"estimate": {"filter": "kvoxel"}, "render": {"spp": 1}}),  # both photon maps' gathers
])
def test_batches_give_the_whole_image_bit_for_bit(mode, extra):
    whole = _render(mode, 1 << 20, **extra)
    spp = whole.cfg.render.spp
    batched = _render(mode, 37 * spp, **extra)  # 11 batches, the last one short, rows cut anywhere
    assert len(pixel_batches(23 * 17, spp, 37 * spp)) == 11
    assert isinstance(whole.gbuffer, GBuffer) and isinstance(batched.gbuffer, ImageGBuffer)
    _assert_same(batched, whole)
    # misses depend on every access before them: the carried pairs give the whole image's
    assert batched.work["rcast"]["trav_misses"].sum() == whole.work["rcast"]["trav_misses"].sum() > 0
    if mode == "pmap":
        for k, v in whole.photons.work.items():
            np.testing.assert_array_equal(batched.photons.work[k], v)
    # the batched render's G-buffer is cast again on demand: the same rays and hits
    np.testing.assert_array_equal(batched.gbuffer.triangle, whole.gbuffer.triangle)
    np.testing.assert_array_equal(batched.gbuffer.hits.t, whole.gbuffer.hits.t)
    assert batched.gbuffer.pixels.shape == whole.gbuffer.pixels.shape


@pytest.mark.slow
def test_batches_of_one_pixel_and_the_written_aovs(tmp_path):
    whole = _render("reflect", 1 << 20, render={"spp": 1})
    single = _render("reflect", 1, render={"spp": 1})  # one pixel a batch (fewer rays than spp: still one)
    _assert_same(single, whole)
    for res, out in ((whole, tmp_path / "whole"), (single, tmp_path / "single")):
        write_run(res, out)
    for name in ("primary", "work"):
        a, b = np.load(tmp_path / "whole" / "aov" / f"{name}.npz"), np.load(tmp_path / "single" / "aov" / f"{name}.npz")
        assert a.files == b.files
        for k in a.files:
            assert a[k].dtype == b[k].dtype
            np.testing.assert_array_equal(a[k], b[k], err_msg=f"{name}.{k}")
    # the AOVs of the G-buffer itself, as before batching
    g = whole.gbuffer
    assert np.array_equal(np.load(tmp_path / "single" / "aov" / "primary.npz")["triangle"].reshape(-1),
                          g.first(g.triangle))


def test_pixel_batches_cover_the_image_in_order():
    for n, spp, rays in ((0, 4, 8), (10, 1, 3), (10, 4, 3), (10, 4, 8), (7, 1, 100)):
        got = pixel_batches(n, spp, rays)
        ids = np.concatenate([np.arange(s.start, s.stop) for s in got]) if got else np.zeros(0, int)
        np.testing.assert_array_equal(ids, np.arange(n))
        assert all(s.stop - s.start == max(1, rays // spp) for s in got[:-1])
    with pytest.raises(ValueError, match="batch_rays"):
        pixel_batches(10, 1, 0)


def test_primary_of_a_gbuffer_equals_its_first_samples():
    res = _render("rcast", 1 << 20)
    g = res.gbuffer
    p = Primary.empty(g.pixels.shape[0])
    p.add(res.frame, cast(res.frame, g.pixels), slice(0, g.pixels.shape[0]))
    np.testing.assert_array_equal(p.direction, g.first(g.direction))
    np.testing.assert_array_equal(p.normal, g.first(g.normal(res.frame)))
    assert p.rays == g.origin.shape[0] == 4 * 23 * 17 and p.hits == int((g.triangle >= 0).sum())


# ---------------------------------------------------------------------------- --outputs


@pytest.fixture
def config(tmp_path):
    path = tmp_path / "cfg.yaml"
    path.write_text(yaml.safe_dump({**SMALL, "mode": "reflect", "render": {"spp": 1},
                                    "arch": {"frames": 5, "packet_size": 64}}))
    return str(path)


def _files(out) -> set[str]:
    return {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}


def test_default_outputs_are_everything(tmp_path, config, capsys):
    out = tmp_path / "run"
    assert main(["run", config, "--out", str(out), "--no-report"]) == 0
    files = _files(out)
    assert {"trace.json", "aov/primary.npz", "aov/work.npz", "radiance/composite.npy", "images/composite.png",
            "results.json", "config.resolved.yaml"} <= files


@pytest.mark.slow
@pytest.mark.parametrize(("names", "present", "absent"), [
    ("aov,trace", {"aov/primary.npz", "aov/work.npz", "trace.json"}, {"radiance"}),
    ("radiance", {"radiance/composite.npy", "radiance/reflect.npy"}, {"aov", "trace.json"}),
    ("images", set(), {"aov", "radiance", "trace.json"}),
    (" trace , images ", {"trace.json"}, {"aov", "radiance"}),
])
def test_outputs_choose_what_a_run_writes(tmp_path, config, capsys, names, present, absent):
    out = tmp_path / "run"
    assert main(["run", config, "--out", str(out), "--outputs", names, "--no-report"]) == 0
    files = _files(out)
    assert {"images/composite.png", "images/rcast.png", "images/reflect.png", "results.json",
            "config.resolved.yaml", *present} <= files
    for name in absent:
        assert not (out / name).exists(), name
    resolved = yaml.safe_load((out / "config.resolved.yaml").read_text())
    assert resolved["arch"]["trace"] is ("trace.json" in present)  # no trace kept when none is written
    assert json.loads((out / "results.json").read_text())["cycles"]["throughput"] > 0


def test_a_trace_asked_for_by_name_is_written_though_the_config_turns_it_off(tmp_path, config, capsys):
    """``--outputs trace`` against ``arch.trace: false`` (configs/sweep_fifo.yaml sets it):
    the trace asked for is written, and the run records the change as an override; without
    ``--outputs`` the config's false holds."""
    out = tmp_path / "run"
    assert main(["run", config, "--out", str(out), "--outputs", "trace", "--set", "arch.trace=false",
                 "--no-report"]) == 0
    assert (out / "trace.json").is_file()
    assert yaml.safe_load((out / "config.resolved.yaml").read_text())["arch"]["trace"] is True
    assert json.loads((out / "results.json").read_text())["overrides"][-1] == "arch.trace=true"
    off = tmp_path / "off"
    assert main(["run", config, "--out", str(off), "--set", "arch.trace=false", "--no-report"]) == 0
    assert not (off / "trace.json").exists() and (off / "aov" / "primary.npz").is_file()


@pytest.mark.parametrize("bad", ["aov,foo", "aovs", ",", "all"])
def test_an_unknown_output_is_exit_2_in_one_line(tmp_path, config, capsys, bad):
    out = tmp_path / "run"
    assert main(["run", config, "--out", str(out), "--outputs", bad]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tlm: error:")
    assert "--outputs" in err[0] and repr(bad) in err[0]
    assert not out.exists()


def test_parse_outputs_orders_and_checks():
    assert parse_outputs("trace,aov") == ("aov", "trace")
    assert parse_outputs("images") == ()
    with pytest.raises(Exception, match="did you mean 'trace'"):
        parse_outputs("trac")


# ---------------------------------------------------------------------------- progress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_no_bars_when_stderr_is_not_a_terminal(tmp_path, config, capsys):
    assert main(["run", config, "--out", str(tmp_path / "run"), "--no-report"]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.slow
def test_bars_on_a_terminal_unless_no_progress(tmp_path, config, monkeypatch):
    term = _Terminal()
    monkeypatch.setattr("sys.stderr", term)
    assert main(["run", config, "--out", str(tmp_path / "a"), "--no-report"]) == 0
    drawn = term.getvalue()
    assert "render" in drawn and "simulate" in drawn and "batch 1/1" in drawn
    term.seek(0)
    term.truncate()
    assert main(["run", config, "--out", str(tmp_path / "b"), "--no-report", "--no-progress"]) == 0
    assert term.getvalue() == ""


@pytest.mark.slow
def test_reference_and_thesis_bars_follow_the_terminal(tmp_path, monkeypatch, capsys):
    cfg = config_from_dict({**SMALL, "mode": "pmap", "resolution": [8, 6], "render": {"spp": 1}})
    res = render(cfg)
    settings = ReferenceSettings(photons=600, k_nearest=10, tolerance=1e-9, min_rounds=2, max_rounds=3)
    compute_reference(res.frame, res.gbuffer, settings, bar=True)  # stderr is pytest's: not a terminal
    assert capsys.readouterr().err == ""
    term = _Terminal()
    monkeypatch.setattr("sys.stderr", term)
    compute_reference(res.frame, res.gbuffer, settings, bar=True)
    assert "reference" in term.getvalue() and "round" in term.getvalue()
    study = tmp_path / "study.yaml"
    base = {k: v for k, v in SMALL.items() if k != "scene"}
    study.write_text(yaml.safe_dump({"base": {**base, "resolution": [8, 6]}, "scenes": ["ring"],
                                     "modes": ["rcast", "reflect"]}))
    term.seek(0)
    term.truncate()
    run_thesis(study, tmp_path / "thesis", bar=True)
    assert "thesis" in term.getvalue() and "2/2" in term.getvalue()
    term.seek(0)
    term.truncate()
    run_thesis(study, tmp_path / "thesis2")  # bars are off by default for library callers
    assert term.getvalue() == ""
