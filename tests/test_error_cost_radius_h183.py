"""``tlm error-vs-cost``'s radius columns are the radii its photon-map pass gathered with.

Under final gathering (``estimate.final_gather`` > 0, the default) the pass gathers the caustic map
at the gather points and the global map where the final-gather rays land; the indirect map is built
but not gathered. The old ``radius`` column was the indirect map's radius all the same (sized by
``estimate.radius_photons``, which is inert there), so a researcher trading radius against error read
the radius of a map that was not used (a 16x16 Cornell study, 3,000 photons: 161.4 on both rows,
where the final-gathering row's global map was gathered within 52.1), and the study computed that
radius (a density radius over the indirect map) for the column only, inside the row's timed
``trace_seconds``. Now ``radius`` is the indirect light's (the global map's under final gathering),
``caustic_radius`` the caustic map's, and the indirect map's is not computed there."""

from __future__ import annotations

import csv
import json

import numpy as np

import tlm.render.pmap as pmap
from tlm.config import apply_overrides, config_from_dict
from tlm.experiments.error_cost import COLUMNS, Truth, run_error_vs_cost
from tlm.experiments.loading import cast_image, load_frame
from tlm.kernels.photons import PhotonMap
from tlm.render.frame import Frame

K_INDIRECT = 37  # estimate.radius_photons: the indirect map's density k, told apart from the others' (8, 16)
BASE = {"scene": "cornell", "seed": 0, "resolution": [8, 8], "render": {"spp": 1}, "photons": {"count": 600},
        "estimate": {"radius_photons": K_INDIRECT},
        "reference": {"photons": 500, "k_nearest": 20, "tolerance": 1e-6, "min_rounds": 2, "max_rounds": 2,
                      "spp": 1}}
POINTS = [{"estimate.final_gather": [4, 0]},  # (the density rule: the final-gathering row first)
          {"estimate.final_gather": [4], "estimate.radius_fraction": [0.03]},  # (a fraction given: both maps')
          {"estimate.filter": ["knn"], "estimate.final_gather": [0]},  # (k nearest: no radius)
          {"photons.count": [0]}]  # (no map gathered)


def _gathered_with(frame: Frame, photons, monkeypatch) -> dict[str, set[float]]:
    """The radii the photon-map pass gathers each of ``photons``' maps with (its ``_estimate`` calls),
    by the names of :func:`tlm.render.pmap.gathered_maps`."""
    names = {id(m): name for name, m in pmap.gathered_maps(frame, photons).items()}
    seen: dict[str, set[float]] = {}
    real = pmap._estimate

    def spy(frame_, ph, radius, *args, **kwargs):
        seen.setdefault(names[id(ph)], set()).add(float(radius))
        return real(frame_, ph, radius, *args, **kwargs)

    with monkeypatch.context() as m:
        m.setattr(pmap, "_estimate", spy)
        pmap.pmap_pass(frame, cast_image(frame), photons)
    return seen


def test_the_radius_columns_are_the_radii_gathered_with(tmp_path, cache, monkeypatch):
    exp = tmp_path / "evc.yaml"
    exp.write_text(json.dumps({"base": BASE, "points": POINTS}))
    asked: list = []  # (k, map) of every density radius made, and ("row", i) after each row
    real = PhotonMap.density_radius

    def density_radius(self, k):
        if k not in self._memo:
            asked.append((k, self))
        return real(self, k)

    monkeypatch.setattr(PhotonMap, "density_radius", density_radius)
    rows = run_error_vs_cost(exp, tmp_path / "out", progress=lambda i, n, row: asked.append(("row", i)),
                             truth=Truth(spp=0))
    monkeypatch.setattr(PhotonMap, "density_radius", real)
    assert [r["final_gather"] for r in rows] == [4, 0, 4, 0, 16]
    for row, point in zip(rows, [{"estimate.final_gather": 4}, {"estimate.final_gather": 0},
                                 {"estimate.final_gather": 4, "estimate.radius_fraction": 0.03},
                                 {"estimate.filter": "knn", "estimate.final_gather": 0},
                                 {"photons.count": 0}], strict=True):
        cfg = config_from_dict({**apply_overrides(BASE, [f"{k}={json.dumps(v)}" for k, v in point.items()]),
                                "mode": "pmap"})
        frame = load_frame(cfg, tmp_path, str(exp))
        photons = pmap.trace_photon_map(frame).photons
        used = _gathered_with(frame, photons, monkeypatch)
        indirect = used.get("global", used.get("indirect"))
        if cfg.estimate.filter == "knn" or cfg.photons.count == 0:  # (no radius: none taken, none gathered)
            assert row["radius"] is None and row["caustic_radius"] is None, (point, row)
            continue
        assert indirect is not None and len(indirect) == 1 and set(used) >= {"caustic"}, (point, used)
        assert row["radius"] == indirect.pop(), (point, row["radius"], used)  # (the old code: the indirect map's)
        assert {row["caustic_radius"]} == used["caustic"], (point, row, used)
    fg, thesis, fraction = rows[0], rows[1], rows[2]
    assert fg["radius"] != thesis["radius"]  # (the global map's, ~16 photons, against the indirect map's, ~37)
    assert fraction["radius"] == 0.03 * load_frame(config_from_dict(BASE), tmp_path, str(exp)).accel.scale
    # the indirect map's density radius (k = radius_photons) is made for the row that gathers it alone
    per_row: list[list[int]] = [[]]
    for a in asked:
        per_row.append([]) if a[0] == "row" else per_row[-1].append(a[0])
    assert K_INDIRECT not in per_row[0], per_row[0]  # (the old code: made for the column, in trace_seconds)
    assert K_INDIRECT in per_row[1], per_row[1]  # (its warm-up's small map's and its own)
    with open(tmp_path / "out" / "rows.csv", newline="") as fh:
        cells = list(csv.DictReader(fh))
    assert list(cells[0]) == list(COLUMNS) and "caustic_radius" in COLUMNS
    assert float(cells[0]["radius"]) == fg["radius"] and cells[3]["radius"] == cells[3]["caustic_radius"] == ""


def test_gathered_radii_and_density_requests_leave_the_indirect_map_out_under_final_gathering(tmp_path):
    cfg = config_from_dict({**BASE, "mode": "pmap", "photons": {"count": 400}})
    frame = load_frame(cfg, tmp_path, "test")
    photons = pmap.trace_photon_map(frame).photons
    assert pmap.final_gathering(frame, photons)
    asked = {k for _, k in pmap.density_requests(frame, photons, gathered_only=True)}
    assert asked == {cfg.estimate.final_gather_photons, cfg.estimate.caustic_radius_photons}
    assert K_INDIRECT in {k for _, k in pmap.density_requests(frame, photons)}  # (what radii() records: all)
    radii = pmap.gathered_radii(frame, photons)
    assert set(radii) == {"caustic", "global"}
    assert radii["global"] == pmap.global_radius(frame, photons) != pmap.search_radius(frame, photons)
    assert radii["caustic"] == pmap.caustic_radius(frame, photons)
    thesis = Frame.create(frame.scene, frame.accel, config_from_dict({**BASE, "mode": "pmap",
                                                                      "estimate": {"final_gather": 0}}))
    traced = pmap.trace_photon_map(thesis).photons
    assert set(pmap.gathered_radii(thesis, traced)) == {"caustic", "indirect"}
    assert np.isclose(pmap.gathered_radii(thesis, traced)["indirect"], pmap.search_radius(thesis, traced))
