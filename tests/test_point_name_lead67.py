"""An error-vs-cost point's name gives its filter's own settings with final gathering on too (h426's finding:
the series name, 'knn + final gather', was tested against 'knn', so a k-NN point with final gathering was named
by a radius it does not use and lost its k)."""

from tlm.report.tradeoff import _point_name, gather_rays


def _row(**kw):
    row = {"filter": "knn", "photons": 20000, "k_nearest": 50, "k": None, "radius_fraction": 0.02,
           "caustic_photons": 0, "factors": "", "final_gather": 16, "gather_rays": 16}
    row.update(kw)
    return row


def test_a_knn_point_with_final_gathering_is_named_by_its_k():
    r = _row()
    assert gather_rays(r), "the row must be one with final gathering for this test to hold"
    name = _point_name(r)
    assert "k=50" in name and "r=" not in name


def test_a_kvoxel_point_with_final_gathering_keeps_its_k():
    r = _row(filter="kvoxel", k=8, k_nearest=None)
    assert "k=8, r=0.02" in _point_name(r)
