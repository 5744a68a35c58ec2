"""A ``shape:`` item's whole number too large to become a float (hundreds of digits; a YAML
hexadecimal one of thousands, more than Python prints), in any of its keys or its
transform's: ``tlm scene show FILE`` says one line naming the key and exits 2. It crashed
with an internal OverflowError (exit 1): the GiB of ``shapes.check_triangle_count`` and the
float checks of a coordinate, a size or a radius."""

from __future__ import annotations

import pytest

from tlm.cli import main
from tlm.scenes import shapes, validate

HEAD = """materials: {grey: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}
default_material: grey
lights: [{type: point, position: [0.0, 3.0, 0.0], power: [10.0, 10.0, 10.0]}]
camera: {eye: [0.0, 1.0, -4.0], target: [0.0, 0.0, 0.0], vfov: 40.0}
resolution: [8, 8]
"""
HUGE = "1" + "0" * 400  # (a 401-digit whole number: no float holds it)
HEX = "0x" + "f" * 5000  # (a YAML whole number of 6021 digits, more than Python prints)
BEYOND = "is beyond +-1e+30, the bound that keeps products of the scene's numbers finite in float64"
QUAD = "corner: [0, 0, 0], edge_u: [1, 0, 0], edge_v: [0, 1, 0]"


def show(tmp_path, item: str, capsys) -> tuple[int, str]:
    scene = tmp_path / "s.yaml"
    scene.write_text(HEAD + f"geometry: [{item}]\n")
    code = main(["scene", "show", str(scene)])
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1, err
    prefix = f"tlm: error: {scene}: "
    assert lines[0].startswith(prefix), err
    return code, lines[0].removeprefix(prefix)


@pytest.mark.parametrize("item,said", [
    # too many triangles: the count in digits (its GiB is beyond a float)
    (f"{{shape: sphere, params: {{segments: {HUGE}}}}}",
     "geometry[0].params: a sphere of segments = a 401-digit number and rings = 16 makes a 402-digit number of "
     "triangles, more than this machine's "),
    (f"{{shape: sphere, params: {{rings: {HUGE}}}}}",
     "geometry[0].params: a sphere of segments = 32 and rings = a 401-digit number makes a 402-digit number of "
     "triangles, more than this machine's "),
    (f"{{shape: cylinder, params: {{segments: {HUGE}}}}}",
     "geometry[0].params: a cylinder of segments = a 401-digit number (4 triangles a segment) makes a 401-digit "
     "number of triangles, more than this machine's "),
    (f"{{shape: box, params: {{divisions: {HUGE}}}}}",
     "geometry[0].params: divisions = a 401-digit number (a side, on each of 6 faces) makes an 802-digit number "
     "of triangles, more than this machine's "),
    (f"{{shape: plane, params: {{divisions: [1, {HUGE}]}}}}",
     "geometry[0].params: divisions = [1, a 401-digit number] makes a 401-digit number of triangles, more than "
     "this machine's "),
    (f"{{shape: quad, params: {{{QUAD}, divisions: [{HUGE}, 2]}}}}",
     "geometry[0].params: divisions = [a 401-digit number, 2] makes a 401-digit number of triangles, more than "
     "this machine's "),
    (f"{{shape: plane, params: {{divisions: [{HEX}, {HEX}]}}}}",
     "geometry[0].params: divisions = [a 6021-digit number, a 6021-digit number] makes a 12042-digit number of "
     "triangles, more than this machine's "),
    # numbers a float cannot hold: beyond the bound, as a float past it is
    (f"{{shape: sphere, params: {{radius: {HUGE}}}}}", f"geometry[0].params.radius: a 401-digit number {BEYOND}"),
    (f"{{shape: sphere, params: {{center: [0, -{HUGE}, 0]}}}}",
     f"geometry[0].params.center: [0, a negative 401-digit number, 0] {BEYOND}"),
    (f"{{shape: cylinder, params: {{height: {HUGE}}}}}", f"geometry[0].params.height: a 401-digit number {BEYOND}"),
    (f"{{shape: cylinder, params: {{radius: -{HUGE}}}}}",
     f"geometry[0].params.radius: a negative 401-digit number {BEYOND}"),
    (f"{{shape: cylinder, params: {{center: [{HUGE}, 0, 0]}}}}",
     f"geometry[0].params.center: [a 401-digit number, 0, 0] {BEYOND}"),
    (f"{{shape: box, params: {{min: [{HEX}, 0, 0]}}}}",
     f"geometry[0].params.min: [a 6021-digit number, 0, 0] {BEYOND}"),
    (f"{{shape: box, params: {{max: [1, 1, {HUGE}]}}}}",
     f"geometry[0].params.max: [1, 1, a 401-digit number] {BEYOND}"),
    (f"{{shape: plane, params: {{size: [{HUGE}, 1]}}}}", f"geometry[0].params.size: [a 401-digit number, 1] {BEYOND}"),
    (f"{{shape: quad, params: {{corner: [0, 0, {HUGE}], edge_u: [1, 0, 0], edge_v: [0, 1, 0]}}}}",
     f"geometry[0].params.corner: [0, 0, a 401-digit number] {BEYOND}"),
    (f"{{shape: quad, params: {{corner: [0, 0, 0], edge_u: [{HUGE}, 0, 0], edge_v: [0, 1, 0]}}}}",
     f"geometry[0].params.edge_u: [a 401-digit number, 0, 0] {BEYOND}"),
    (f"{{shape: quad, params: {{corner: [0, 0, 0], edge_u: [1, 0, 0], edge_v: [0, {HUGE}, 0]}}}}",
     f"geometry[0].params.edge_v: [0, a 401-digit number, 0] {BEYOND}"),
    (f"{{shape: box, transform: {{scale: {HUGE}}}}}", f"geometry[0].transform.scale: a 401-digit number {BEYOND}"),
    (f"{{shape: box, transform: {{rotate: [0, {HEX}, 0]}}}}",
     f"geometry[0].transform.rotate: [0, a 6021-digit number, 0] {BEYOND}"),
    # below their range
    (f"{{shape: box, params: {{divisions: -{HUGE}}}}}",
     "geometry[0].params.divisions: a negative 401-digit number must be a whole number >= 1"),
    (f"{{shape: sphere, params: {{rings: -{HEX}}}}}",
     "geometry[0].params.rings: a negative 6021-digit number must be a whole number >= 2"),
], ids=lambda v: v[:48])
def test_a_shape_s_impossible_number_is_one_line_naming_its_key(tmp_path, cache, capsys, item, said):
    code, line = show(tmp_path, item, capsys)
    assert code == 2, line
    assert line.startswith(said), line
    assert "internal error" not in line and "Overflow" not in line


def test_the_count_in_digits_is_exact():
    assert [validate.digits(n) for n in (0, 1, 9, 10, 99, 100, 10**400 - 1, 10**400, -(10**400))] == \
        [1, 1, 1, 2, 2, 3, 400, 401, 401]
    assert validate.digits(16**5000 - 1) == 6021
    assert [validate.digit_count(n) for n in (10**7, 10**10, 10**17, 10**79, 10**801, 10**1100, 10**8000)] == \
        ["an 8-digit number", "an 11-digit number", "an 18-digit number", "an 80-digit number",
         "an 802-digit number", "a 1101-digit number", "an 8001-digit number"]
    assert validate.digit_count(-(10**400)) == "a negative 401-digit number"
    with pytest.raises(ValueError, match=r"^a sphere of segments = a 401-digit number and rings = 2 makes a "
                                         r"401-digit number of triangles, more than this machine's \d+ GiB can hold$"):
        shapes.uv_sphere((0, 0, 0), 1.0, 10**400, 2)

