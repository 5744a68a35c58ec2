"""A render whose batches run at once puts in leaf order (:meth:`PhotonMap.prepared`) only
the photon maps its frame gathers (:func:`tlm.render.pmap.gathered_maps`): with final
gathering not the indirect map, without it not the global map. Nothing else reads a
map's leaf order, so the other map's would be made for nothing."""

from __future__ import annotations

import pytest

from tlm.config import config_from_dict
from tlm.kernels import threads
from tlm.kernels.photons import PhotonMap
from tlm.kernels.traverse import build_accel
from tlm.render import batches
from tlm.render.batches import render_batches
from tlm.render.frame import Frame
from tlm.render.pmap import gathered_maps, trace_photon_map
from tlm.scenes.loader import load_scene

NAMES = ("caustic", "indirect", "global")


@pytest.fixture(scope="module")
def cornell():
    scene = load_scene("cornell", resolution=[16, 16])
    return scene, build_accel(scene.triangles)


@pytest.fixture
def made(monkeypatch):
    """The maps whose leaf order is made (not only looked up), in order."""
    real = PhotonMap.prepared
    out: list[PhotonMap] = []

    def recording(self):
        if "leaf_order" not in self._memo:
            out.append(self)
        return real(self)

    monkeypatch.setattr(PhotonMap, "prepared", recording)
    return out


def _frame(cornell, final_gather: int) -> Frame:
    scene, accel = cornell
    # 16x16 at 8 samples a pixel: 2,048 eye rays, two batches on two threads (they run at once)
    return Frame.create(scene, accel, config_from_dict(
        {"scene": "cornell", "mode": "pmap", "resolution": [16, 16], "render": {"spp": 8, "threads": 2},
         "photons": {"count": 1500}, "estimate": {"final_gather": final_gather}}))


def _names(photons, maps: list[PhotonMap]) -> list[str]:
    """The names of ``maps`` (by identity: a map's ``==`` compares arrays)."""
    return [name for name in NAMES for m in maps if m is getattr(photons, f"{name}_map")]


def test_a_render_with_final_gathering_does_not_prepare_the_indirect_map(cornell, made):
    frame = _frame(cornell, 4)
    assert len(batches.batches_for(16 * 16, 8, frame.cfg.render.batch_rays, 2)) > 1  # (the warm path)
    done = render_batches(frame, ["pmap"])
    photons = done.photons.photons
    assert photons.global_map is not None and min(photons.indirect_map.n, photons.caustic_map.n) > 0
    assert sorted(done.gather_maps) == ["caustic", "global"]  # (what the pass gathered)
    assert sorted(_names(photons, made)) == ["caustic", "global"]
    assert "leaf_order" not in photons.indirect_map._memo


def test_a_frame_without_final_gathering_does_not_prepare_the_global_map(cornell, made):
    """``_warm`` (before the batches run at once) on a trace with a global map for a frame
    that does not gather it: the caustic and indirect maps, not the global one."""
    traced = trace_photon_map(_frame(cornell, 4))  # (a cold trace: nothing in leaf order yet)
    photons = traced.photons
    assert made == [] and photons.global_map is not None and photons.global_map.n > 0
    frame = _frame(cornell, 0)
    with threads.using(2):
        batches._warm(frame, traced)
    assert sorted(_names(photons, made)) == ["caustic", "indirect"]
    assert sorted(_names(photons, made)) == sorted(gathered_maps(frame, photons))
    assert "leaf_order" not in photons.global_map._memo


def test_a_warm_trace_with_a_global_map_prepares_the_maps_the_pipeline_keeps(cornell, made):
    """``trace_photon_map(warm=True)`` with final gathering puts in leaf order, with the
    trees, the caustic and global maps (:attr:`PhotonMaps.gathered`, the maps the pipeline
    keeps), which are the ones the frame gathers: ``_warm`` then makes none."""
    frame = _frame(cornell, 4)
    with threads.using(2):
        traced = trace_photon_map(frame, warm=True)
        photons = traced.photons
        assert sorted(_names(photons, made)) == ["caustic", "global"]
        assert _names(photons, list(photons.gathered)) == _names(photons, list(gathered_maps(frame, photons).values()))
        made.clear()
        batches._warm(frame, traced)
    assert made == []
