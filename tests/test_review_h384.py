"""Review of 1e4fe5d, a light's ``name:`` (h384).

* ``tlm scene export`` wrote its YAML with PyYAML's YAML 1.1 resolvers, which write a string such as ``1e3``
  bare; tlm reads YAML 1.2 floats (:func:`tlm.config_words.parse_yaml`), so the exported file read it back as
  1000.0: a light's name ``1e3`` made the export fail to load (and the scene's name alike; a material named so
  came back as ``1000.0``, unused). Such strings are now written quoted.
* A light's ``name:`` that YAML reads as a date said ``'2020-01-01' is not a string``, the value quoted as a
  string: now ``2020-01-01 is not text``, with the hint the scene's ``name:`` gives (quote it).
"""

from __future__ import annotations

import pytest
import yaml

from tlm.api_scenes import export_scene, load_scene
from tlm.errors import InputError

HEAD = ("camera: {eye: [0, 0, 6], target: [0, 0, 0], vfov: 40}\nresolution: [8, 8]\n"
        "geometry: {shape: box, params: {min: [-1, -1, -1], max: [1, 1, 1]}}\n")
POINT = "{type: point, position: [0, 3, 0], power: [1, 2, 3]"


@pytest.mark.parametrize("word", ["1e3", "-2E-5", "1.0e3", "+1e+3"])
def test_a_name_that_reads_as_a_number_exports_quoted(tmp_path, word):
    (tmp_path / "s.yaml").write_text(
        f"name: '{word}'\nmaterials: {{'{word}': {{type: lambertian, albedo: [0.6, 0.6, 0.6]}}}}\n"
        f"default_material: '{word}'\n{HEAD}lights: [{POINT}, name: '{word}'}}, {POINT}, name: {word} lamp}}]\n")
    scene = load_scene(tmp_path / "s.yaml")
    out = tmp_path / "out.yaml"
    export_scene(scene, out)
    text = out.read_text()
    assert f"name: {word} lamp\n" in text, text  # (only what tlm would read otherwise is quoted)
    doc = yaml.safe_load(text)
    assert (doc["name"], list(doc["materials"]), doc["lights"][0]["name"]) == (word, [word], word)
    again = load_scene(out)  # (it raised: name: 1000.0 is not text)
    assert again.name == word
    assert [m.name for m in again.materials] == [word]
    assert again.lights == scene.lights and [lt.name for lt in again.lights] == [word, f"{word} lamp"]


@pytest.mark.parametrize("value, said", [("2020-01-01", "2020-01-01"), ("yes", "true"), ("1e3", "1000.0")])
def test_a_light_name_yaml_reads_otherwise_says_to_quote_it(tmp_path, value, said):
    path = tmp_path / "s.yaml"
    path.write_text(f"materials: {{grey: {{type: lambertian, albedo: [0.6, 0.6, 0.6]}}}}\ndefault_material: grey\n"
                    f"{HEAD}lights: [{POINT}, name: {value}}}]\n")
    with pytest.raises(InputError) as e:
        load_scene(path)
    assert str(e.value) == f"{path}: lights[0].name: {said} is not text (the light's name: quote it, name: \"...\")"
