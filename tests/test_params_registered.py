"""`tlm params` names what a registry's keys can select now, a plug-in's too (h525's probe: estimate.filter said "a
registered estimator (tlm.registry)" and named none; the patch of h543, applied to tlm.api.params)."""

from __future__ import annotations

import tlm
from tlm.registry import ESTIMATORS
from tlm.render.estimators import Estimator


def _text(key: str) -> str:
    return next(text for k, _, text in tlm.params() if k == key)


def test_params_names_the_registered_values_a_plugin_among_them():
    assert _text("estimate.filter").endswith("; registered now: disk, mvoxel, kvoxel, knn")
    assert _text("arch.scheduler").endswith("; registered now: static, dynamic")

    @ESTIMATORS.register("gauss_h543")
    class Gauss(Estimator):
        pass

    try:
        assert _text("estimate.filter").endswith("; registered now: disk, mvoxel, kvoxel, knn, gauss_h543")
    finally:
        ESTIMATORS._classes.pop("gauss_h543")
    assert "gauss_h543" not in _text("estimate.filter")
    assert "registered now" not in _text("render.spp")  # (a key no registry selects: as it was)
