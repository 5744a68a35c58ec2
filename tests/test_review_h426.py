"""h426, review of 7085725 (h424: keys that change nothing say so) and 060f3e0 (h423: --set of a file's own keys).

Under the k-nearest filter (``knn``, which declares it uses no radius) every radius key is named inert, and
``results.json`` records no radius; but the render still made each map's density radius (``radius_photons``,
``caustic_radius_photons``, ``final_gather_photons``: a k-nearest search over a sample of the map) before
its batches and in the photon-map pass, and an error-vs-cost row of ``knn`` timed it in its ``trace_seconds``
(``density_requests(..., gathered_only=True)``: "each one its gathers use"). None is made now
(:func:`tlm.render.pmap.density_wanted` asks for none; the pass hands the estimator ``inf``), the images and
work as before.

``--set arch.trace=true`` dropped by the outputs named ``tlm run --outputs`` and ``--outputs images,trace``
to a caller of ``tlm.api.run`` whose overrides were a mapping (``the overrides``), which has no flags: it
names ``outputs`` now.
"""

from __future__ import annotations

import pytest

from tlm.config import config_from_dict
from tlm.experiments import run as runs
from tlm.experiments.loading import load_frame
from tlm.experiments.run_warnings import trace_dropped
from tlm.kernels import photons as photon_kernels
from tlm.render import pmap

BASE = {"scene": "cornell", "mode": "pmap", "seed": 0, "resolution": [12, 12], "render": {"spp": 1},
        "photons": {"count": 1500}, "reference": {"auto": False}}


def _cfg(**estimate):
    return config_from_dict({**BASE, "estimate": estimate})


@pytest.mark.parametrize("final_gather", [0, 4])
def test_knn_asks_for_no_density_radius(tmp_path, final_gather):
    frame = load_frame(_cfg(filter="knn", final_gather=final_gather), tmp_path, "test")
    assert pmap.density_wanted(frame) == []
    photons = pmap.trace_photon_map(frame).photons
    assert pmap.density_requests(frame, photons) == []
    assert pmap.density_requests(frame, photons, gathered_only=True) == []  # (an error-vs-cost row times none)
    # (a filter with a radius still asks, as before)
    disk = load_frame(_cfg(filter="disk", final_gather=final_gather), tmp_path, "test")
    assert pmap.density_wanted(disk)


@pytest.mark.parametrize("final_gather", [0, 4])
def test_a_knn_render_makes_no_density_radius_and_records_none(monkeypatch, cache, final_gather):
    made: list[int] = []
    real = photon_kernels.density_radius

    def counted(position, k, *args, **kwargs):
        made.append(k)
        return real(position, k, *args, **kwargs)

    monkeypatch.setattr(photon_kernels, "density_radius", counted)  # (the trace's and PhotonMap.density_radius)
    res = runs.render(_cfg(filter="knn", final_gather=final_gather, radius_photons=20), None, "test")
    assert made == [], made
    ph = runs.results_dict(res, 0.0, "test")["photons"]
    assert ph["radius"] is None and ph["caustic_radius"] is None and ph.get("global_radius") is None, ph
    assert sum(g["photons_tested"] for g in ph["gather"].values()) > 0  # (the k nearest were gathered)
    made.clear()
    runs.render(_cfg(filter="disk", final_gather=final_gather), None, "test")
    assert made  # (the density rule of a fixed-radius filter: made, as before)


def test_a_dropped_trace_names_the_api_s_outputs_to_an_api_caller():
    cfg = config_from_dict({"arch": {"trace": False}})
    (line,) = trace_dropped(cfg, ["arch.trace=true"], "the overrides")
    assert line == ("arch.trace=true (in the overrides) is not kept: no trace.json is written, because the run's "
                    "outputs (tlm.api.run's outputs) do not name trace; add it (outputs=\"images,trace\") to write one")
    (line,) = trace_dropped(cfg, ["arch.trace=true"])  # (the command line's, as h424 wrote it)
    assert "(tlm run --outputs)" in line and "(--outputs images,trace)" in line
