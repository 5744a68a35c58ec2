"""The YAML tlm writes reads back the same by tlm's own reader (h406).

tlm reads YAML with YAML 1.2 floats (:func:`tlm.config_words.parse_yaml`: ``1e3`` is 1000.0), but
``yaml.safe_dump`` (YAML 1.1, which has no such float) wrote the string ``'1e3'`` bare: a run's
``config.resolved.yaml`` holding a plug-in estimator named ``1e3`` failed to run again, a sweep's
``sweep.yaml`` read its description ``1e3``, or a point's hash ``8e91000000000000``, as a number. One
dumper (:class:`tlm.config_words.Dumper`, :func:`~tlm.config_words.dump_yaml`, its libyaml variant
:class:`~tlm.config_words.CDumper` and the one-line :func:`~tlm.config_words.flow_text`) writes them all.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import tlm.api as api
from tlm.config import config_from_dict, load_config, to_dict
from tlm.config_words import CDumper, Dumper, dump_yaml, flow_text, parse_yaml
from tlm.experiments import sweep_point
from tlm.experiments.sweep_file import Point, Sweep
from tlm.registry import ESTIMATORS
from tlm.render.estimators import MVoxel

TRICKY = ["1e3", ".5", "0x10", "2026-12-02", "true", "null", "~", "-1", "+1.0e-3", "yes", "1_000", "1E3", "-2e-5",
          ".5e+3", "1.0e6", "+.inf", "-.Inf", ".NaN", "1.", "0o17", "1:20", "=", "<<", "", " a", "no", "Off"]


@pytest.mark.parametrize("text", TRICKY)
def test_the_dumper_writes_a_string_that_reads_back_as_that_string(text):
    for doc in (text, [text], {text: text}, {"a": {"b": [text, 1, 2.5, None]}}):
        said = dump_yaml(doc, sort_keys=False)
        assert parse_yaml(said) == doc and yaml.safe_load(said) == doc, said
    assert parse_yaml(flow_text(text)) == text and "\n" not in flow_text(text)
    assert parse_yaml(flow_text([text, {text: text}])) == [text, {text: text}]


def test_the_dumper_writes_anything_else_as_safe_dump_did():
    doc = {"scene": "cornell", "mode": "rcast", "seed": 0, "resolution": [16, 16], "x": 1e20, "y": 0.5, "z": None,
           "t": True, "s": "a b: c", "u": "é", "long": "word " * 40, "n": "two\nlines", "inf": float("inf")}
    assert dump_yaml(doc, sort_keys=False) == yaml.safe_dump(doc, sort_keys=False)
    assert issubclass(Dumper, yaml.SafeDumper)


def test_flow_text_is_one_line_and_the_writers_share_it():
    from tlm.cli_tables import yaml_text

    assert [flow_text(v) for v in ("1e3", "cornell", [16, 16], {"spp": 2}, None, True, "a\nb")] == [
        "'1e3'", "cornell", "[16, 16]", "{spp: 2}", "null", "true", '"a\\nb"']
    assert yaml_text("1e3") == "'1e3'" and yaml_text(6e8) == "6.0e+08"


@pytest.fixture
def plugin_1e3(monkeypatch):
    """A plug-in radiance estimator named ``1e3`` (as an installed package's entry point registers one):
    a name that YAML 1.1 writes bare and tlm's reader takes for 1000.0."""
    ESTIMATORS.names()  # (the built-in ones loaded first)
    cls = type("Plugin1e3", (MVoxel,), {"name": "1e3"})
    monkeypatch.setitem(ESTIMATORS._classes, "1e3", cls)
    return cls


BASE = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "estimate": {"filter": "1e3"},
        "arch": {"trace": False}}


def test_a_runs_resolved_config_runs_again_to_the_same_config(plugin_1e3, tmp_path):
    api.run(BASE, tmp_path / "a", reference=False)
    text = (tmp_path / "a" / "config.resolved.yaml").read_text(encoding="utf-8")
    assert "filter: '1e3'" in text
    assert parse_yaml(text)["estimate"]["filter"] == "1e3"
    assert to_dict(load_config(tmp_path / "a" / "config.resolved.yaml")[0]) == to_dict(config_from_dict(BASE))
    api.run(tmp_path / "a" / "config.resolved.yaml", tmp_path / "b", reference=False)  # (as tlm run takes it)
    assert (tmp_path / "b" / "config.resolved.yaml").read_text(encoding="utf-8") == text


def test_a_sweeps_files_read_back_the_same(plugin_1e3, tmp_path, monkeypatch):
    (tmp_path / "s.yaml").write_text(
        "description: '1e3'\n"
        "base: {scene: cornell, mode: rcast, resolution: [8, 8], arch: {trace: false}}\n"
        "grid:\n  estimate.filter: ['1e3']\n", encoding="utf-8")

    def no_python_emitter(*a, **k):
        raise AssertionError("a point's config.resolved.yaml went through PyYAML's own emitter")

    if CDumper is not None:  # (libyaml's emitter still writes a plain point's config: the fast path kept)
        monkeypatch.setattr(sweep_point, "dump_yaml", no_python_emitter)
    table = api.sweep(tmp_path / "s.yaml", tmp_path / "out", jobs=1)
    assert list(table["status"]) == ["ok"], table.to_dict()
    spec = parse_yaml((tmp_path / "out" / "sweep.yaml").read_text(encoding="utf-8"))
    assert spec["description"] == "1e3" and spec["grid"] == {"estimate.filter": ["1e3"]}
    assert [p["factors"] for p in spec["points"]] == [{"estimate.filter": "1e3"}]
    (folder,) = (tmp_path / "out" / "points").iterdir()
    resolved = folder / "config.resolved.yaml"
    assert parse_yaml(resolved.read_text(encoding="utf-8"))["estimate"]["filter"] == "1e3"
    again = to_dict(load_config(resolved)[0])
    assert again["estimate"]["filter"] == "1e3"
    api.run(resolved, tmp_path / "b", reference=False)
    assert to_dict(load_config(tmp_path / "b" / "config.resolved.yaml")[0]) == again


def test_a_point_hash_that_reads_as_a_float_is_quoted_in_sweep_yaml():
    """A hash is 16 hex digits: about one point in 1,300 has only digits and one ``e`` (``8e91000000000000``),
    a float to tlm's reader (inf) that YAML 1.1 writes bare; sweep.yaml's lines put together point by point
    (:meth:`Sweep.marker`) quote it as the dump does."""
    hashes = ["8e91000000000000", "1e10000000000000", "0123456789abcdef", "1234567890123456"]
    points = [Point(i, {"scene": s}, {}, h) for i, (h, s) in enumerate(zip(hashes, ["1e3", "cornell", "2e5", "x"]))]
    sw = Sweep(Path("/x/s.yaml"), "1e3", {"scene": "cornell"}, None, {}, {"scene": ["1e3", "cornell", "2e5", "x"]},
               {}, Path("/x"), points)
    text = sw.marker()
    assert text == dump_yaml(sw.to_dict(), sort_keys=False)
    back = parse_yaml(text)
    assert [p["hash"] for p in back["points"]] == hashes and back["description"] == "1e3"
    assert [p["factors"]["scene"] for p in back["points"]] == ["1e3", "cornell", "2e5", "x"]


def test_a_point_config_takes_libyamls_emitter_and_quotes_as_pythons(monkeypatch):
    """:func:`~tlm.experiments.sweep_point.config_text`'s fast path (:class:`~tlm.config_words.CDumper`) writes
    what :func:`~tlm.config_words.dump_yaml` writes, each string read back as itself."""
    config = {"scene": "/x/1e3.yaml", "estimate": {"filter": "1e3"}, "tricky": TRICKY, "n": [1e3, 2, None]}
    want = dump_yaml(config, sort_keys=False)
    if CDumper is not None:
        monkeypatch.setattr(sweep_point, "dump_yaml", lambda *a, **k: pytest.fail("the Python emitter was used"))
    text = sweep_point.config_text(config)
    assert text == want and parse_yaml(text) == config
