"""h511, a review of h505 (photons.cut_share) and h506 (the inside-out glass check).

* ``photons.cut_share`` summed the power in flight of both photon groups, while the caustic group's photons, aimed
  at the specular objects, estimate a part of the light the global group's already carry: a box of mirrors said
  132% of its lights' power at caustic_fraction 0.5 (66% at 0), more than the lights gave. Now the global group's
  alone: the same share whatever the caustic group.
* the glass check judged a part's dielectric triangles as one surface: a hollow body whose cavity is a part of its
  own (an OBJ object) named the cavity, and an inside-out body split over two parts, or sitting in one part beside
  a body wound right, was not named. Now bodies (triangles joined by their corners, over parts too), a cavity
  (inside another closed glass body) not named.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.test_glass_winding_h506 import _reversed, _scene
from tlm.config import config_from_dict
from tlm.experiments.loading import load_frame
from tlm.kernels import threads
from tlm.kernels.photons import trace_photons
from tlm.render import checks
from tlm.scenes.loader import load_scene
from tlm.scenes.shapes import aabox

MIRROR_BOX = """name: mbox
geometry:
  - shape: box
    name: room
    params: {min: [0.0, 0.0, 0.0], max: [1.0, 1.0, 1.0]}
  - shape: quad
    name: patch
    params: {corner: [0.45, 0.01, 0.45], edge_u: [0.0, 0.0, 0.1], edge_v: [0.1, 0.0, 0.0]}
materials:
  mir: {type: mirror, reflectance: [0.95, 0.95, 0.95]}
  white: {type: lambertian, albedo: [0.8, 0.8, 0.8]}
parts: {room: mir, patch: white}
lights:
  - {type: quad, corner: [0.4, 0.999, 0.4], edge_u: [0.2, 0.0, 0.0], edge_v: [0.0, 0.0, 0.2], power: [3.0, 3.0, 3.0]}
camera: {eye: [0.5, 0.5, 0.05], target: [0.5, 0.5, 1.0], up: [0.0, 1.0, 0.0], vfov: 100.0}
resolution: [8, 8]
photons: 4000
"""
SAID = "a closed surface that faces inwards"


@pytest.fixture
def mirror_box(tmp_path):
    path = tmp_path / "mbox.yaml"
    path.write_text(MIRROR_BOX)
    frame = load_frame(config_from_dict({"scene": str(path), "mode": "pmap"}))
    return frame.scene, frame.accel


def test_the_cut_share_is_the_lights_power_in_flight_whatever_the_caustic_group(mirror_box):
    # (most paths stay on the mirrors: about 0.95^8 of the light still travels after 8 hits, some 66%)
    alone = trace_photons(*mirror_box, 6000, seed=1, caustic_fraction=0.0).photons
    both = trace_photons(*mirror_box, 6000, seed=1, caustic_fraction=0.5).photons
    assert 0.5 < alone.cut_share < 0.8
    assert both.cut_share == pytest.approx(alone.cut_share, rel=0.1)  # (132% before: both groups summed)
    assert both.cut_power == pytest.approx(tuple(3.0 * both.cut_share for _ in range(3)), rel=1e-9)


def test_the_cut_power_with_a_caustic_group_is_the_same_bits_on_any_threads(mirror_box):
    with threads.using(1):
        one = trace_photons(*mirror_box, 9000, seed=2, caustic_fraction=0.5).photons
    with threads.using(3):
        three = trace_photons(*mirror_box, 9000, seed=2, caustic_fraction=0.5, batch_rays=1).photons
    assert one.cut_power == three.cut_power and one.cut_share == three.cut_share < 1.0


def _said(tmp_path, name, parts, glass):
    scene = load_scene(str(_scene(tmp_path, name, parts, glass)))
    return [w for w in checks.file_warnings(scene) if SAID in w]


def test_a_cavity_given_as_a_part_of_its_own_is_not_named(tmp_path):
    outer = aabox((-0.2, 0.0, -0.2), (0.2, 0.4, 0.2))
    cavity = _reversed(aabox((-0.1, 0.1, -0.1), (0.1, 0.3, 0.1)))  # (faces into the cavity: right)
    assert _said(tmp_path, "hollow", {"outer": outer, "cavity": cavity}, ["outer", "cavity"]) == []
    # (a ball inside that cavity wound inwards too is wrong again, and named)
    ball = _reversed(aabox((-0.05, 0.15, -0.05), (0.05, 0.25, 0.05)))
    [line] = _said(tmp_path, "nested", {"outer": outer, "cavity": cavity, "ball": ball}, ["outer", "cavity", "ball"])
    assert line.startswith("part 'ball' (glass: material 'g') is " + SAID + ": its 12 triangles")


def test_an_inside_out_body_over_two_parts_or_beside_a_right_one_is_named(tmp_path):
    box = _reversed(aabox((-0.2, 0.0, -0.2), (0.2, 0.4, 0.2)))
    [line] = _said(tmp_path, "split", {"half_a": box[:6], "half_b": box[6:]}, ["half_a", "half_b"])
    assert line.startswith("parts 'half_a' and 'half_b' (glass: material 'g') are " + SAID + ": their 12 triangles "
                           "enclose a volume of -0.064")
    right = aabox((-0.4, 0.0, -0.4), (0.4, 0.8, 0.4)) + np.array([2.0, 0.0, 0.0])
    [line] = _said(tmp_path, "pair", {"pair": np.concatenate([right, box])}, ["pair"])
    assert line.startswith("part 'pair' (glass: material 'g') is " + SAID + ": 12 of its triangles enclose a volume "
                           "of -0.064")
