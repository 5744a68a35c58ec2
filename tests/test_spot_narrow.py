"""A spot light's caustic photons are drawn from where its outer cone and the aim cones meet
(:func:`tlm.kernels.emission.lens_sectors`, :func:`~tlm.kernels.emission.spot_aimed`), so a
narrow spot far from the specular objects costs what a wide one does and wastes no photon:
each lands inside the outer cone and an aim cone and carries power, the caustic group's power
is the spot's over the aimed directions (its flux where the cone lies wholly inside them), in
expectation and cell by cell, and the numbers are the same on any threads and either engine."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tlm.kernels import emission as em
from tlm.kernels import shade, threads
from tlm.kernels.emission import bounding_cone, box_cones, emit, photon_key
from tlm.scenes.model import Light, spot_falloff

SCENE = (np.array([-2.0, 0.0, -2.0]), np.array([2.0, 2.0, 2.0]))
# two boxes on the floor beside a spot 1.5 above it, straight down: a 4-degree cone meets the
# floor at r = 0.1, where the boxes' cones (34 and 24 degrees) just reach
BOXES = np.array([[[0.02, 0.0, -0.5], [1.02, 0.5, 0.5]], [[-0.6, 0.0, 0.02], [0.2, 0.3, 0.8]]])
BEHIND = np.array([[[-0.5, 1.8, -0.5], [0.5, 2.0, 0.5]]])  # (above the spot: its cone misses every cone)
AIMS = {"parts": {"caustic_boxes": np.concatenate([BOXES, BEHIND])},
        "box": {"specular_box": (BOXES[:, 0].min(axis=0), BOXES[:, 1].max(axis=0))}}


def _spot(outer: float, direction=(0.0, -1.0, 0.0)) -> Light:
    return Light("spot", (30.0, 30.0, 30.0), position=(0.0, 1.5, 0.0), direction=direction,
                 inner_angle=outer / 3.0, outer_angle=outer)


def _cones(spot: Light, aim: str) -> tuple[np.ndarray, np.ndarray]:
    pos = np.asarray(spot.position)
    if aim == "box":
        a, c = bounding_cone(pos, *AIMS["box"]["specular_box"])
        return a[None, :], np.array([c])
    boxes = AIMS["parts"]["caustic_boxes"]
    return tuple(x[0] for x in box_cones(pos[None, :], boxes[:, 0], boxes[:, 1]))


def _grid(spot: Light, n: int = 500):
    """Directions on a fine (theta, phi) grid of the spot's outer cone, their polar angle and
    azimuth about its axis, and each one's solid angle."""
    outer = math.radians(spot.outer_angle)
    th = (np.arange(n) + 0.5) / n * outer
    ph = (np.arange(2 * n) + 0.5) / (2 * n) * 2.0 * math.pi
    t, p = np.meshgrid(th, ph, indexing="ij")
    w = spot.axis
    u, v = em._frame(w[None, :])
    d = (np.sin(t)[..., None] * (np.cos(p)[..., None] * u[0] + np.sin(p)[..., None] * v[0])
         + np.cos(t)[..., None] * w).reshape(-1, 3)
    return d, t.ravel(), p.ravel(), (np.sin(t) * (th[1] - th[0]) * (ph[1] - ph[0])).ravel()


def _polar(spot: Light, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    w = spot.axis
    u, v = em._frame(w[None, :])
    return np.arccos(np.clip(d @ w, -1.0, 1.0)), np.mod(np.arctan2(d @ v[0], d @ u[0]), 2.0 * math.pi)


def _caustic(spot: Light, aim: str, n: int = 40_000, seed: int = 11):
    _, d, power, caustic = emit((spot,), n, photon_key(seed), SCENE, caustic_fraction=1.0, **AIMS[aim])
    assert caustic.all()
    return d, power[:, 0]


@pytest.mark.parametrize(("outer", "aim"), [(4.0, "parts"), (4.0, "box"), (30.0, "parts")])
def test_every_caustic_photon_is_aimed_and_carries_power_cell_by_cell_unbiased(aim, outer, monkeypatch):
    """Each caustic photon of a 4- or 30-degree spot is inside the outer cone and an aim cone
    and carries power (of a million photons aimed at the two boxes alone, the 4-degree one
    left 54% (parts) and 80% (box) with nothing after 32 draws from the aim cones) and none
    at the box behind the spot (where draws from the aim cones went, to be drawn again); the
    power in
    each of 3 x 4 cells of the cone (rings by polar angle, quarters by azimuth) is the spot's
    power over 4 pi times its falloff integrated over the aimed directions of the cell (on a
    grid), within 5 standard errors. The photons, more than two chunks of them, are the same
    bits on 1 and 3 threads and with TLM_KERNELS=numpy."""
    spot = _spot(outer)
    axes, coss = _cones(spot, aim)
    d, power = _caustic(spot, aim)
    with threads.using(3):
        np.testing.assert_array_equal(_caustic(spot, aim)[0], d)
    monkeypatch.setenv("TLM_KERNELS", "numpy")
    again, same = _caustic(spot, aim)
    np.testing.assert_array_equal(again, d)
    np.testing.assert_array_equal(same, power)
    co = spot.cone_cosines[1]
    aimed = (d @ axes.T >= coss[None, :]).any(axis=1)
    assert (d @ spot.axis > co).all() and aimed.all()
    assert (power > 0).all() and np.isfinite(power).all()
    if aim == "parts":  # (the box behind: none aimed there)
        assert not (d @ axes[2] >= coss[2]).any()
    grid, th, ph, dw = _grid(spot)
    exact_w = 30.0 / (4.0 * math.pi) * spot_falloff(grid @ spot.axis, *spot.cone_cosines) * dw
    exact_w *= (grid @ axes.T >= coss[None, :]).any(axis=1)
    t, p = _polar(spot, d)
    edges = np.radians(spot.outer_angle) * np.array([0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0 + 1e-12])
    n = power.shape[0]
    checked = 0
    for i in range(3):
        for q in range(4):
            in_grid = (th >= edges[i]) & (th < edges[i + 1]) & (ph >= q * math.pi / 2) & (ph < (q + 1) * math.pi / 2)
            exact = exact_w[in_grid].sum()
            cell = (t >= edges[i]) & (t < edges[i + 1]) & (p >= q * math.pi / 2) & (p < (q + 1) * math.pi / 2)
            x = np.where(cell, power, 0.0)
            got, error = x.sum(), x.std() * math.sqrt(n)
            if exact == 0.0:
                assert got == 0.0, (i, q, got)
                continue
            assert abs(got - exact) <= 5.0 * error + 1e-9 * exact, (i, q, got, exact, error)
            checked += 1
    assert checked >= 4
    total, exact = power.sum(), exact_w.sum()
    assert abs(total - exact) <= 5.0 * power.std() * math.sqrt(n) and power.std() * math.sqrt(n) < 0.05 * exact


@pytest.mark.parametrize("aim", ["parts", "box"])
def test_a_narrow_spot_inside_the_aim_cones_emits_its_flux(aim):
    """A 4-degree spot turned towards the first box, its outer cone wholly inside that box's
    cone: the caustic group's power is the spot's flux, in expectation (within 5 standard
    errors, and its standard error under 1%), as the global group's is exactly."""
    target = 0.5 * (BOXES[0, 0] + BOXES[0, 1]) - np.array([0.0, 1.5, 0.0])
    spot = _spot(4.0, direction=tuple(target))
    axes, coss = _cones(spot, aim)
    assert (axes @ spot.axis >= np.cos(np.arccos(coss) - math.radians(4.0))).any()  # (the cone inside one)
    d, power = _caustic(spot, aim, n=40_000)
    assert (power > 0).all() and (d @ spot.axis > spot.cone_cosines[1]).all()
    error = power.std() * math.sqrt(power.shape[0])
    assert abs(power.sum() - spot.flux[0]) <= 5.0 * error and error < 0.01 * spot.flux[0]
    _, _, every, group = emit((spot,), 40_000, photon_key(3), SCENE)
    assert not group.any() and every[:, 0].sum() == pytest.approx(spot.flux[0], rel=1e-12)


def test_a_cone_that_grazes_the_spot_is_drawn_from_a_sector_about_its_sliver():
    """A box whose cone from a 4-degree spot just cuts the spot's cone (the lens 3% of it):
    every caustic photon carries power and lands in the box's cone, the group's power is
    unbiased, and a draw falls in the lens with the chance lens_sectors says (L / sector, more
    than a third: the sector is not the whole cone)."""
    spot = _spot(4.0)
    pos = np.asarray(spot.position)
    outer = math.radians(4.0)
    g = math.radians(30.0)  # (the box's cone, 26.6 degrees about this, reaches 3.4 degrees from the spot's axis)
    far = pos + 3.0 * np.array([math.sin(g), -math.cos(g), 0.0])
    half = 0.8
    box = np.array([[far - half, far + half]])
    axes, coss = (x[0] for x in box_cones(pos[None, :], box[:, 0], box[:, 1]))
    _, d, power, _ = emit((spot,), 40_000, photon_key(2), SCENE, caustic_fraction=1.0, caustic_boxes=box)
    p = power[:, 0]
    assert (p > 0).all() and (d @ axes[0] >= coss[0]).all()
    grid, _, _, dw = _grid(spot)
    exact = (30.0 / (4.0 * math.pi) * spot_falloff(grid @ spot.axis, *spot.cone_cosines) * dw
             * (grid @ axes[0] >= coss[0])).sum()
    assert abs(p.sum() - exact) <= 5.0 * p.std() * math.sqrt(p.shape[0])

    from tlm.kernels.emission import lens_sectors

    lens, s, psi, v_lo, v_hi, phi, sector = lens_sectors(spot.axis, spot.cone_cosines[1], axes, coss)
    rate = lens[0] / sector[0]
    assert 0.0 < lens[0] < 0.05 * 2.0 * math.pi * (1.0 - math.cos(outer)) and rate > 1.0 / 3.0
    rng = np.random.default_rng(5)
    n = 200_000
    v = v_lo[0] + rng.random(n) * (v_hi[0] - v_lo[0])
    dd = em._around(np.tile(s[0], (n, 1)), 1.0 - v, psi[0] + (2.0 * rng.random(n) - 1.0) * phi[0])
    hit = (dd @ spot.axis > spot.cone_cosines[1]) & (dd @ axes[0] >= coss[0])
    assert abs(hit.mean() - rate) <= 5.0 * math.sqrt(rate * (1.0 - rate) / n)


@pytest.mark.parametrize("aim", ["parts", "box"])
def test_a_narrow_spot_draws_about_as_many_numbers_as_a_wide_one(aim, monkeypatch):
    """The cost of a spot's caustic group: the random numbers it draws a photon, for a
    4-degree spot at most 1.5 times a 30-degree one's (now 5.0 against 6.0 (parts) and 5.0
    (box); it was 90 against 20, and 88 against 10: most of the narrow spot's photons drew
    32 times from the aim cones)."""
    counted = []
    real = shade.hash_uniform

    def counting(seed, *keys):
        out = real(seed, *keys)
        counted.append(out.size)
        return out

    monkeypatch.setattr(em, "hash_uniform", counting)
    used = {}
    for outer in (30.0, 4.0):
        counted.clear()
        _caustic(_spot(outer), aim, n=20_000)
        used[outer] = sum(counted) / 20_000
    assert used[4.0] <= 1.5 * used[30.0], used
