"""The caustic group aimed at the specular parts (``photons.aim: parts``, Jensen's
projection maps) and its photon budget of its own (``photons.caustic_count``).

* the mixture of cones stays unbiased: the caustic map's power, in all and cell by cell,
  agrees with ``aim: box``'s within Monte Carlo noise (a point light, a quad light and a
  mesh light);
* it wastes fewer photons: on the ring scenes a caustic-group photon is stored several
  times as often;
* ``caustic_count`` gives the caustic group that many photons beside ``count``'s;
* ``aim: box`` without ``caustic_count`` emits exactly what it did before either existed.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest

from tlm.kernels.emission import aim_boxes, bounding_cone, box_cones, emit, photon_key, split_photons
from tlm.kernels.photons import trace_photons
from tlm.kernels.traverse import build_accel
from tlm.scenes.loader import load_scene
from tlm.scenes.model import KIND, Light

THESIS_RING = "scenes/thesis/ring.yaml"  # the gold ring and the glass ball apart: one box spans both


def _scene(name: str):
    scene = load_scene(name)
    return scene, build_accel(scene.triangles)


def _boxes(scene, aim_triangles: int = 64) -> np.ndarray:
    return aim_boxes(scene.triangles, scene.material_table()["kind"], scene.part, aim_triangles)


# ---------------------------------------------------------------- the aiming boxes and cones


def test_aim_boxes_cut_each_specular_part_into_small_boxes():
    scene = load_scene(THESIS_RING)  # ring 384 triangles, glass ball 256, floor 6
    kind = scene.material_table()["kind"]
    spec = kind != KIND["lambertian"]
    for cap, count in ((64, 8 + 4), (1000, 2), (1, int(spec.sum()))):
        boxes = _boxes(scene, cap)
        assert boxes.shape == (count, 2, 3)
        assert np.all(boxes[:, 0] <= boxes[:, 1])
    # every specular triangle lies in a box of its part; no box reaches the floor alone
    boxes = _boxes(scene, 64)
    tri = scene.triangles[spec]
    inside = np.all((tri.min(axis=1)[:, None] >= boxes[None, :, 0]) & (tri.max(axis=1)[:, None] <= boxes[None, :, 1]),
                    axis=2)
    assert inside.any(axis=1).all()
    ring, glass = (scene.triangles[spec & (scene.part == p)].reshape(-1, 3) for p in np.unique(scene.part[spec]))
    assert np.all(boxes[:8, 0] >= ring.min(axis=0)) and np.all(boxes[8:, 0] >= glass.min(axis=0))
    with pytest.raises(ValueError, match="aim_triangles"):
        _boxes(scene, 0)
    # no specular triangle: no box
    assert aim_boxes(scene.triangles, np.zeros_like(kind), scene.part, 64).shape == (0, 2, 3)


def test_box_cones_are_bounding_cone_box_by_box():
    rng = np.random.default_rng(3)
    lo = rng.uniform(-2, 1, (7, 3))
    hi = lo + rng.uniform(0.0, 2.0, (7, 3))
    hi[0, 1] = lo[0, 1]  # a flat box (a mirror quad)
    p = rng.uniform(-4, 4, (50, 3))
    p[0] = 0.5 * (lo[2] + hi[2])  # inside a box, at its centre
    p[1] = lo[3]  # on a corner
    axes, cos = box_cones(p, lo, hi)
    for i in range(p.shape[0]):
        for k in range(lo.shape[0]):
            a, c = bounding_cone(p[i], lo[k], hi[k])
            assert cos[i, k] == pytest.approx(c, abs=1e-12)
            if c > -1.0:
                np.testing.assert_allclose(axes[i, k], a, atol=1e-12)
    assert cos[0, 2] == -1.0 and cos[1, 3] == -1.0


def test_overlapping_cones_count_a_direction_once():
    """Two copies of one box: each direction lies in both cones, so the mixture's density
    is the one cone's and the power that of aiming at the box alone."""
    pos = np.array([0.0, 10.0, 0.0])
    lo, hi = np.array([-1.0, 0.0, -1.0]), np.array([1.0, 1.0, 1.0])
    light = Light("point", (1.0, 2.0, 3.0), position=tuple(pos))
    axis, cos_max = bounding_cone(pos, lo, hi)
    _, d, power, group = emit((light,), 4000, photon_key(0), (lo, hi), caustic_fraction=0.5,
                              caustic_boxes=np.array([[lo, hi], [lo, hi]]))
    assert group.sum() == 2000
    assert np.all(d[group] @ axis >= cos_max - 1e-12)
    np.testing.assert_allclose(power[group], np.tile([1.0, 2.0, 3.0], (2000, 1)) * (1.0 - cos_max) / 2.0 / 2000)
    # a light inside a box: that cone is the whole sphere (4 pi), the other one's directions
    # lie in both, so the density is 2 / (4 pi + Omega) there and 1 / (4 pi + Omega) elsewhere
    _, d, power, group = emit((light,), 4000, photon_key(0), (lo, hi), caustic_fraction=0.5,
                              caustic_boxes=np.array([[lo, hi], [pos - 1.0, pos + 1.0]]))
    omega = 2.0 * np.pi * (1.0 - cos_max)
    both = d[group] @ axis >= cos_max
    assert 0 < both.sum() < 2000
    want = (4.0 * np.pi + omega) / (4.0 * np.pi * np.where(both, 2.0, 1.0)) / 2000
    np.testing.assert_allclose(power[group], want[:, None] * [1.0, 2.0, 3.0])
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)


# ---------------------------------------------------------------- unbiased


def _cells(position: np.ndarray, lo: np.ndarray, hi: np.ndarray, g: int) -> np.ndarray:
    f = np.clip(((position - lo) / np.maximum(hi - lo, 1e-12) * g).astype(np.int64), 0, g - 1)
    return (f[:, 0] * g + f[:, 1]) * g + f[:, 2]


def _power_by_cell(tr, n_group: int, lo, hi, g: int) -> tuple[np.ndarray, np.ndarray]:
    """The caustic map's power per cell (and in all, last) and its variance: a caustic-group
    photon stores at most once, so a cell's power is a sum of ``n_group`` independent
    terms x_i (zero for most), whose variance is estimated as sum x^2 - (sum x)^2 / n."""
    cm = tr.photons.maps[0]
    x = cm.power.sum(axis=1)
    cell = _cells(cm.position, lo, hi, g)
    s = np.append(np.bincount(cell, x, g**3), x.sum())
    s2 = np.append(np.bincount(cell, x * x, g**3), (x * x).sum())
    counts = np.append(np.bincount(cell, minlength=g**3), x.shape[0])
    return s, s2 - s * s / n_group, counts


@pytest.mark.slow
@pytest.mark.parametrize("name, n_group", [("ring", 60000), (THESIS_RING, 60000), ("cornell", 40000),
                                           ("cornell-sphere", 30000)])
def test_parts_and_box_agree_within_the_noise(name, n_group):
    """The caustic map's power in all and over a coarse grid of cells agrees between the
    one cone (``box``) and the mixture (``parts``): every cell's difference within 4.5
    standard errors, the cells' chi-square within 4 of its own standard deviations of
    its mean (independent runs: another seed each)."""
    scene, accel = _scene(name)
    flat = scene.triangles.reshape(-1, 3)
    lo, hi, g = flat.min(axis=0), flat.max(axis=0), 4
    runs = {aim: _power_by_cell(trace_photons(scene, accel, 100, seed=seed, aim=aim, caustic_count=n_group),
                                n_group, lo, hi, g)
            for aim, seed in (("box", 11), ("parts", 12))}
    (sa, va, ca), (sb, vb, cb) = runs["box"], runs["parts"]
    assert cb[-1] > ca[-1]  # aimed better: more photons stored
    used = (ca >= 30) & (cb >= 30)  # cells with enough photons for the normal approximation
    used[-1] = True
    z = (sa - sb)[used] / np.sqrt(va + vb)[used]
    assert abs(z[-1]) < 4.0, (sa[-1], sb[-1], z[-1])
    cells = z[:-1]
    dof = cells.shape[0]
    assert dof >= 3
    assert np.abs(cells).max() < 4.5, cells
    assert (cells**2).sum() < dof + 4.0 * math.sqrt(2.0 * dof), (cells, dof)


# ---------------------------------------------------------------- efficient


@pytest.mark.slow
@pytest.mark.parametrize("name, least", [(THESIS_RING, 2.5), ("ring", 1.8)])
def test_parts_store_more_of_the_caustic_group(name, least):
    """Share of the caustic group stored in the caustic map (20,000 photons, seed 0):
    thesis ring box 0.117, parts 0.398 (3.4x); ring box 0.360, parts 0.761 (2.1x: the
    ring alone, whose box is tight already; a quarter of what hits it is reflected away
    from the floor)."""
    scene, accel = _scene(name)
    share = {aim: trace_photons(scene, accel, 100, seed=0, aim=aim, caustic_count=20000).photons.maps[0].n / 20000
             for aim in ("box", "parts")}
    assert share["parts"] >= least * share["box"], share


# ---------------------------------------------------------------- caustic_count


@pytest.mark.slow
def test_caustic_count_is_a_budget_of_its_own():
    scene, accel = _scene("room")  # a quad light and a point light
    flat = scene.triangles.reshape(-1, 3)
    box = (flat.min(axis=0), flat.max(axis=0))
    boxes = _boxes(scene)
    for kw in ({"caustic_boxes": boxes}, {"specular_box": box}):
        _, d, _, group, _ = emit(scene.lights, 3000, photon_key(1), box, caustic_fraction=0.5,
                                 with_source=True, caustic_count=1234, **kw)
        assert group.sum() == 1234 and (~group).sum() == 3000
        assert np.unique(d, axis=0).shape[0] == 4234  # every photon its own random numbers
        # light by light: the global group then the caustic group, each its share of its budget
        glob, caus = split_photons(scene.lights, 3000), split_photons(scene.lights, 1234)
        runs = np.diff(np.flatnonzero(np.diff(np.concatenate([[-1], group.astype(int), [-1]])) != 0))
        assert runs.tolist() == [x for pair in zip(glob, caus, strict=True) for x in pair if x]
    tr = trace_photons(scene, accel, 3000, seed=2, caustic_count=1234, caustic_fraction=0.0)
    assert tr.photons.emitted == 4234 and tr.work["photons_emitted"].sum() == 4234
    assert all(m.emitted == 4234 for m in tr.photons.maps)
    assert tr.photons.maps[0].n > 0
    # no specular surface: no caustic group, count photons only
    box_scene, box_accel = _scene("cornell-box")
    assert trace_photons(box_scene, box_accel, 500, caustic_count=300).photons.emitted == 500
    # caustic_count 0: no caustic group, the global group stores caustics too
    none = trace_photons(scene, accel, 3000, seed=2, caustic_count=0)
    assert none.photons.emitted == 3000 and none.photons.maps[0].n > 0


@pytest.mark.parametrize("bad", [{"caustic_count": -1}, {"aim": "cone"}, {"aim_triangles": 0}])
def test_bad_aim_arguments(bad):
    scene, accel = _scene("ring")
    with pytest.raises(ValueError, match=next(iter(bad))):
        trace_photons(scene, accel, 10, **bad)


# ---------------------------------------------------------------- box: as before


def _digest(arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str(a.dtype).encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()[:16]


# emit(lights, 3001, photon_key(7), scene box, specular box, 0.5, with_source=True), computed
# before photons.aim and photons.caustic_count existed
BEFORE = {"ring": "48c821d3193c9da0", THESIS_RING: "32cf811553b52a90", "cornell": "d5b401ffe990767b",
          "cornell-sphere": "e1eb28c4f97d75e1", "room": "a2dae29df1263133"}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(BEFORE))
def test_box_emits_as_before(name, monkeypatch):
    scene = load_scene(name)
    kind = scene.material_table()["kind"]
    flat = scene.triangles.reshape(-1, 3)
    spec = scene.triangles[kind != KIND["lambertian"]].reshape(-1, 3)
    args = (scene.lights, 3001, photon_key(7), (flat.min(axis=0), flat.max(axis=0)),
            (spec.min(axis=0), spec.max(axis=0)), 0.5)
    assert _digest(emit(*args, with_source=True)) == BEFORE[name]
    assert _digest(emit(*args, with_source=True, caustic_boxes=None, caustic_count=None)) == BEFORE[name]
    # and trace_photons emits that with aim box (photons.caustic_fraction 0.5, no caustic_count)
    from tlm.kernels import photons as module

    seen = []
    real = module.emit

    def spy(*a, **kw):
        out = real(*a, **kw)
        seen.append(_digest(out))
        return out

    monkeypatch.setattr(module, "emit", spy)
    trace_photons(scene, build_accel(scene.triangles), 3001, seed=7, aim="box", caustic_fraction=0.5, max_bounces=1)
    assert seen == [BEFORE[name]]
