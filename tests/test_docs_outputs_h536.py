"""h536: the run folder's file table and ``results.json``'s key table (docs/usage.md) and README's
``--no-reference`` against the files of real runs (a user probe, h523, read a run folder with its own scripts
and found keys, dtypes and behaviours the docs left out or said otherwise), and two messages: an unknown dotted
key that is another section's (``--set render.resolution=...``: the top-level ``resolution``), and
``--outputs`` naming its bad part rather than the whole list."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from tlm.cli import main
from tlm.config import config_from_dict
from tlm.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
QUIET = ["--no-report", "--no-progress"]
SMALL = ["--set", "resolution=[16,16]"]
# a photon-map frame and its reference, small: the reference in seconds (not converged, which is no matter here)
PMAP = [*SMALL, "--set", "photons.count=2000", "--set", "reference.photons=2000", "--set", "reference.min_rounds=2",
        "--set", "reference.max_rounds=2", "--set", "reference.spp=2"]


def _row(doc: str, first_cell: str) -> str:
    """The table row of ``doc`` (a file under the project) whose first cell starts with ``first_cell``."""
    rows = [line for line in (ROOT / doc).read_text(encoding="utf-8").splitlines()
            if line.startswith(f"| {first_cell}")]
    assert len(rows) == 1, (first_cell, len(rows))
    return rows[0]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Three runs in a cache of their own: the photon map's at 16 x 16 on two pipelines with ``--no-reference``
    and its reference cached before; Cornell's ``--mode rcast`` and its default mode (refract) on one."""
    tmp = tmp_path_factory.mktemp("h536")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TLM_CACHE", str(tmp / "cache"))
        assert main(["reference", "cornell_pmap", *PMAP, "--no-progress"]) in (0, 1)  # (1: not converged)
        assert main(["run", "cornell_pmap", *PMAP, "--set", "arch.pipelines=2", "--no-reference",
                     "--out", str(tmp / "pmap"), *QUIET]) == 0
        assert main(["run", "cornell", *SMALL, "--mode", "rcast", "--out", str(tmp / "rcast"), *QUIET]) == 0
        assert main(["run", "cornell", *SMALL, "--out", str(tmp / "refract"), *QUIET]) == 0
    return {name: tmp / name for name in ("pmap", "rcast", "refract")}


def _results(folder: Path) -> dict:
    return json.loads((folder / "results.json").read_text(encoding="utf-8"))


def test_every_key_of_scene_bsp_is_documented(runs):
    row = _row("docs/usage.md", "`scene` |")
    bsp = _results(runs["pmap"])["scene"]["bsp"]
    assert {"requested_levels", "slots_reserved", "empty_leaves"} <= set(bsp)
    assert [k for k in bsp if f"`{k}`" not in row] == []
    assert bsp["slots_reserved"] == 20 * bsp["elements"] and "`bsp.memory_factor` x `elements`" in row


def test_every_key_of_error_with_a_cached_reference_is_documented_and_no_reference_uses_it(runs):
    error = _results(runs["pmap"])["error"]
    assert error["available"] and "skipped" not in error  # (--no-reference computed none, but used the cached one)
    assert (runs["pmap"] / "images" / "pmap_error.png").is_file()
    assert error["reference_resolution"] == [16, 16] and error["reference_photons"] == 2000
    row = _row("docs/usage.md", "`error` |")
    assert [k for k in error if f"`{k}`" not in row] == []
    assert "`--no-reference` computes none, but a reference already cached is used" in row
    assert _row("docs/usage.md", "`images/pmap_error.png` |")  # (the file table names it)
    readme = [line for line in (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
              if "`--no-reference` (or `reference.auto: false`)" in line]
    assert len(readme) == 1 and "skips it" not in readme[0] and "uses one already cached" in readme[0]


def test_tiles_are_half_open_rectangles_as_documented(runs):
    tiling = _results(runs["pmap"])["timing"]["tiling"]
    assert (tiling["rows"], tiling["cols"]) == (1, 2) and tiling["tiles"] == [[0, 0, 8, 16], [8, 0, 16, 16]]
    covered = np.zeros((16, 16), dtype=int)
    for x0, y0, x1, y1 in tiling["tiles"]:
        covered[y0:y1, x0:x1] += 1
    assert (covered == 1).all()  # (x1, y1 exclusive: each pixel in one tile)
    row = _row("docs/usage.md", "`timing.clock_hz`")
    assert "`[x0, y0, x1, y1]`" in row and "`x0` and `y0` included, `x1` and `y1` not" in row


def test_compose_and_the_vertex_pm_by_pipeline_as_documented(runs):
    two, one = _results(runs["pmap"])["timing"], _results(runs["rcast"])["timing"]
    assert "compose" in two["units"] and "compose" not in one["units"]
    assert "pipe0.vertex" in two["units"] and "pipe1.vertex" not in two["units"]
    assert two["pipelines"][0]["vertex"] > 0 and two["pipelines"][1]["vertex"] == 0
    assert "`compose` only with more than one pipeline" in _row("docs/usage.md", "`timing.units` |")
    assert "`vertex` 0 but in the first" in _row("docs/usage.md", "`timing.pipelines` |")


def test_every_work_count_is_named_in_work_keys_or_the_work_row(runs):
    results = _results(runs["pmap"])
    row = _row("docs/usage.md", "`work`, `work_keys` |")
    keys = set(results["work_keys"])
    assert "photons_tested" in results["work"]["pmap"] and "photons_tested" not in keys
    unnamed = {k for counts in results["work"].values() for k in counts if k not in keys and f"`{k}`" not in row}
    with np.load(runs["pmap"] / "aov" / "work.npz") as work:
        unnamed |= {k.split(".", 1)[1] for k in work.files if k.split(".", 1)[1] not in keys
                    and f"`{k.split('.', 1)[1]}`" not in row}
    assert unnamed == set()
    assert "the counts named in `work_keys`" not in row


def test_primary_npz_dtypes_and_misses_as_documented(runs):
    row = _row("docs/usage.md", "`aov/primary.npz` |")
    with np.load(runs["rcast"] / "aov" / "primary.npz") as npz:
        arrays = {k: npz[k] for k in npz.files}
    miss = arrays["triangle"] < 0
    assert miss.any() and (~miss).any()
    assert np.isinf(arrays["t"][miss]).all() and np.isfinite(arrays["t"][~miss]).all()
    assert (arrays["normal"][miss] == 0).all()
    for name, array in arrays.items():
        cell = row.split(f"`{name}`", 1)[1].split(")", 1)[0]  # (its parenthesis: shape, dtype, miss)
        assert array.dtype.name in cell, (name, array.dtype, cell)
    assert "0 on a miss" in row.split("`normal`", 1)[1]


def test_config_resolved_keeps_a_builtin_scene_by_name(runs):
    resolved = yaml.safe_load((runs["rcast"] / "config.resolved.yaml").read_text(encoding="utf-8"))
    assert resolved["scene"] == "cornell"
    assert "a built-in scene as its name" in _row("docs/usage.md", "`config.resolved.yaml` |")


def test_a_pass_png_follows_the_composites_exposure_and_carries_no_colour_chunk(runs):
    rcast, refract = runs["rcast"], runs["refract"]
    assert np.array_equal(np.load(rcast / "radiance" / "rcast.npy"), np.load(refract / "radiance" / "rcast.npy"))
    assert _results(rcast)["image"]["exposure"] != _results(refract)["image"]["exposure"]
    png = (rcast / "images" / "rcast.png").read_bytes()
    assert png != (refract / "images" / "rcast.png").read_bytes()
    assert not any(chunk in png for chunk in (b"sRGB", b"gAMA", b"iCCP", b"cHRM"))
    row = _row("docs/usage.md", "`images/<pass>.png`")
    assert "one chosen from the composite" in row and "differs between modes" in row and "`gAMA`" in row


@pytest.mark.parametrize(("key", "hint"), [
    ("render.resolution", "(did you mean 'resolution'?)"),
    ("render.seed", "(did you mean 'seed'?)"),
    ("arch.spp", "(did you mean 'render.spp' or 'reference.spp'?)"),
    ("spp", "(did you mean 'render.spp' or 'reference.spp'?)"),  # (not 'bsp', as it was)
])
def test_an_unknown_key_of_another_section_is_named(key, hint):
    section, _, name = key.rpartition(".")
    raw = {section: {name: 2}} if section else {name: 2}
    with pytest.raises(InputError) as info:
        config_from_dict(raw)
    assert hint in str(info.value) and "\n" not in str(info.value)


def test_set_of_an_unknown_key_of_another_section_is_one_line_with_the_key(tmp_path, capsys):
    assert main(["run", "cornell", "--set", "render.resolution=[48,48]", "--out", str(tmp_path / "x"), *QUIET]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.endswith("render.resolution: unknown key (did you mean 'resolution'?)")
    with pytest.raises(InputError, match=r"resolutoin: unknown key \(did you mean 'resolution'\?\)"):
        config_from_dict({"resolutoin": [48, 48]})  # (a typo: its hint as before)


@pytest.mark.parametrize(("given", "named"), [("aov,bogus", "'bogus' is none of them"),
                                              ("trac,aov,x", "'trac', 'x' are none of them (did you mean 'trace'?)")])
def test_outputs_names_its_bad_part(tmp_path, capsys, given, named):
    assert main(["run", "cornell", "--outputs", given, "--out", str(tmp_path / "x"), *QUIET]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.endswith(f"--outputs: {given!r}: expected a comma-separated list of images, aov, radiance, trace; "
                        + named)
