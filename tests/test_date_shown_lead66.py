"""A scene file's value that YAML reads as a date is named as written in an error line (stop 66, after h390):
``name: 2020-01-01`` said ``datetime.date(2020, 1, 1) is not text``."""

import pytest

from tlm.errors import InputError
from tlm.scenes.loader import load_scene


@pytest.mark.parametrize("key", ["name", "description"])
def test_a_date_for_a_scene_words_key_is_named_as_written(tmp_path, key):
    (tmp_path / "t.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "s.yaml").write_text(
        f"{key}: 2020-01-01\ngeometry: {{mesh: t.obj}}\ndefault_material: m\n"
        "materials: {m: {type: lambertian, albedo: [0.5, 0.5, 0.5]}}\n"
        "lights: [{type: point, position: [0.3, 0.3, 1], power: [10, 10, 10]}]\n"
        "camera: {eye: [0.5, 0.5, 3], target: [0.5, 0.5, 0], vfov: 40}\nresolution: [8, 8]\n")
    with pytest.raises(InputError) as e:
        load_scene(tmp_path / "s.yaml")
    assert f"{key}: 2020-01-01 is not text" in str(e.value), str(e.value)
    assert "datetime" not in str(e.value)
