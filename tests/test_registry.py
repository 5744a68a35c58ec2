"""Registries (a new estimator or scheduler is one class and one YAML value), the one code
fingerprint (an edit anywhere in the package changes it) and the one atomic writer."""

from __future__ import annotations

import csv
import dataclasses
import importlib
import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from tlm.config import config_from_dict
from tlm.errors import InputError
from tlm.fingerprint import fingerprint, package_files
from tlm.kernels import estimate
from tlm.registry import ESTIMATORS, SCHEDULERS, Registry
from tlm.render.estimators import Estimator, Gather
from tlm.storage import write_atomic, write_file, write_rows

BASE = {"scene": "cornell", "resolution": [16, 12], "mode": "pmap", "photons": {"count": 2000},
        "render": {"spp": 1}}


def test_the_built_in_names_are_registered_in_order():
    assert ESTIMATORS.names() == ("disk", "mvoxel", "kvoxel", "knn")
    assert SCHEDULERS.names() == ("static", "dynamic")
    assert "disk" in ESTIMATORS and "nope" not in ESTIMATORS


def test_an_unknown_name_is_one_line_naming_the_key_and_the_near_miss():
    with pytest.raises(InputError, match=r"x.yaml: estimate.filter: mvoxl is not one of disk, mvoxel, "
                                         r"kvoxel, knn.*did you mean 'mvoxel'"):
        config_from_dict({**BASE, "estimate": {"filter": "mvoxl"}}, "x.yaml")
    with pytest.raises(InputError, match=r"arch.scheduler: dynamik is not one of.*did you mean 'dynamic'"):
        config_from_dict({**BASE, "arch": {"scheduler": "dynamik"}}, "x.yaml")
    with pytest.raises(InputError, match="unknown radiance estimator 'zzz'"):
        ESTIMATORS["zzz"]


def test_a_name_taken_by_another_class_is_refused():
    reg = Registry("thing", (), "tlm.test-nothing")

    @reg.register("a")
    class A:
        pass

    with pytest.raises(ValueError, match="registered twice"):
        @reg.register("a")
        class B:
            pass
    assert reg["a"] is A and A.name == "a"


@pytest.fixture
def halved():
    """An estimator of one class: the disk estimate at half the power, as ``estimate.filter: halved``."""

    @ESTIMATORS.register("halved")
    class Halved(Estimator):
        def __call__(self, g: Gather):
            e = estimate.disk_estimate(g.position, g.power, g.incoming, g.tree, g.points, g.normals,
                                       g.radius, streams=g.streams, stream=g.stream)
            return dataclasses.replace(e, density=e.density / 2)

    yield Halved
    ESTIMATORS._classes.pop("halved")


def test_a_new_estimator_is_one_class_and_one_yaml_value(halved, tmp_path, monkeypatch):
    from tlm.experiments.run import render

    monkeypatch.setenv("TLM_CACHE", str(tmp_path))
    mine = render(config_from_dict({**BASE, "estimate": {"filter": "halved"}}, "x.yaml"))
    disk = render(config_from_dict({**BASE, "estimate": {"filter": "disk"}}, "x.yaml"))
    a, b = mine.radiance["pmap"], disk.radiance["pmap"]
    assert a.shape == b.shape and np.abs(b).sum() > 0
    np.testing.assert_allclose(a, b / 2, rtol=1e-12, atol=1e-15)  # the pmap pass alone is the estimate
    assert {k: v.sum() for k, v in mine.work["pmap"].items()} == {k: v.sum() for k, v in disk.work["pmap"].items()}


def test_the_fingerprint_changes_when_any_source_file_changes(tmp_path):
    """Every .py and .yaml of the package is in it: a kernel, the timing seam, the run, the report."""
    root = Path(__file__).resolve().parents[1] / "tlm"
    copy = tmp_path / "tlm"
    shutil.copytree(root, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = fingerprint(copy)
    assert before == fingerprint(root)
    names = {f.relative_to(copy).as_posix() for f in package_files(copy)}
    for rel in ("arch/functional.py", "experiments/run.py", "kernels/traverse.py", "report/html.py", "cli.py",
                "arch/programs.yaml"):
        assert rel in names
        f = copy / rel
        text = f.read_text()
        f.write_text(text + "\n# an edit\n")
        assert fingerprint(copy) != before, rel
        f.write_text(text)
        assert fingerprint(copy) == before
    (copy / "kernels" / "new.py").write_text("X = 1\n")  # a new module counts too
    assert fingerprint(copy) != before


def test_an_atomic_write_that_fails_leaves_the_old_file_and_no_litter(tmp_path):
    path = tmp_path / "a.json"
    write_file(path, "old")
    with pytest.raises(RuntimeError), write_atomic(path) as fh:
        fh.write("half")
        raise RuntimeError("killed")
    assert path.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["a.json"]
    write_file(path, b"\x00new")
    assert path.read_bytes() == b"\x00new"


def test_rows_are_written_once_as_csv_and_jsonl(tmp_path):
    rows = [{"point": 1, "b": 2.5}, {"point": 0, "c": [1, 2]}]
    write_rows(tmp_path, "r", rows, ["point", "a"])
    with open(tmp_path / "r.csv") as fh:
        got = list(csv.DictReader(fh))
    assert list(got[0]) == ["point", "a", "b", "c"]
    assert got[1]["c"] == "[1, 2]" and got[0]["a"] == ""
    assert [json.loads(x) for x in (tmp_path / "r.jsonl").read_text().splitlines()] == rows


@pytest.mark.slow
def test_the_registries_load_their_providers_lazily():
    """The base layer names its providers by module path; asking for the names imports them."""
    import subprocess

    code = ("import sys; from tlm.config import config_from_dict; "
            "assert 'tlm.render.estimators' not in sys.modules; "
            "from tlm.registry import ESTIMATORS; print(ESTIMATORS.names()); "
            "assert 'tlm.render.estimators' in sys.modules")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "mvoxel" in out


def _registry_of(tmp_path, monkeypatch, name: str, provider: str) -> Registry:
    """A registry in module ``<name>_reg`` whose one provider is module ``<name>_mod`` of
    source ``provider`` (``{IMPORT}``: the line that imports the registry as ``THINGS``)."""
    (tmp_path / f"{name}_reg.py").write_text(
        f"from tlm.registry import Registry\nTHINGS = Registry('thing', ('{name}_mod',), 'tlm.no-such-group')\n")
    (tmp_path / f"{name}_mod.py").write_text(provider.replace("{IMPORT}", f"from {name}_reg import THINGS"))
    monkeypatch.syspath_prepend(str(tmp_path))
    return importlib.import_module(f"{name}_reg").THINGS


def test_threads_that_ask_while_the_providers_load_wait_for_them(tmp_path, monkeypatch):
    """Two threads ask a registry at once (a Dask worker running two points): the one that
    comes while the other imports the providers waits and sees every name, where it saw an
    empty registry marked loaded (``arch.scheduler: 'static' is not one of ...``)."""
    import threading
    import time

    things = _registry_of(tmp_path, monkeypatch, "slow_provider",
                          "import time\ntime.sleep(0.5)\n{IMPORT}\n\n\n"
                          "@THINGS.register('slow')\nclass Slow:\n    pass\n")

    seen = {}

    def ask(who):
        seen[who] = things.names()

    first = threading.Thread(target=ask, args=("first",))
    first.start()
    time.sleep(0.1)  # (the first is inside the provider's import)
    ask("second")
    first.join()
    assert seen == {"first": ("slow",), "second": ("slow",)}


def test_a_provider_that_asks_its_own_registry_while_it_loads_gets_what_is_there(tmp_path, monkeypatch):
    """A provider module that asks its registry during its own import gets the names
    registered so far (no deadlock, no second load), and every later question all of them."""
    things = _registry_of(tmp_path, monkeypatch, "self_asking",
                          "{IMPORT}\n\n\n@THINGS.register('a')\nclass A:\n    pass\n\n\n"
                          "SEEN = THINGS.names()\n\n\n@THINGS.register('b')\nclass B:\n    pass\n")
    assert things.names() == ("a", "b")
    import self_asking_mod

    assert self_asking_mod.SEEN == ("a",)
