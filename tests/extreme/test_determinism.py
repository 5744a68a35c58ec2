"""Determinism: one config and one seed give the same bytes and the same numbers.

* reruns (in this process, and in a fresh interpreter with another hash seed): every
  file of the run folder byte-identical, ``results.json`` identical but for the host
  fields below, the photon-map reference too;
* packet size, pipelines N and scheduler: the images and every functional section of
  ``results.json`` identical (only the timing sections may differ);
* executors: one sweep in this process, in a process pool and on Dask gives the same
  point folders and the same ``sweep.csv`` but for its host-seconds columns and who ran
  each point (its worker, host and process);
* a different seed changes the images (so the comparisons above can fail).

Each run gets its own functional and reference cache (``TLM_CACHE``), so a rerun
really renders and never reads what the previous one wrote.
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from tlm.cli import main
from tlm.config import config_from_dict
from tlm.experiments.run import run
from tlm.experiments.sweep import run_sweep

REPO = Path(__file__).resolve().parents[2]

# ``results.json`` fields that differ between two runs of one config on one machine by
# nature, and nothing else:
HOST_FIELDS = (
    "host_seconds",  # wall seconds per stage of this host, this moment
    "versions",  # Python, platform and package versions of the interpreter that ran
    "git_revision",  # HEAD of the checkout: others commit to it while the suite runs
    "git_modified",  # whether the checkout differs from HEAD: others edit it while the suite runs
    "code_fingerprint",  # the package's content: the same edits
    "ran",  # who ran it: its Dask worker (a sweep point's; None for a tlm run), host and process id
)
# a sweep point's results.json has one more, inside its "functional" section:
POINT_HOST_FIELDS = ("functional.render_host_seconds",)  # the render's seconds per stage
# (its "key" and "cached" are compared: the key hashes the config, the scene and the
# functional layer's source, and the first point of each key renders, the rest read it)
# the reference's meta.json: how long the rounds took
REFERENCE_HOST_FIELDS = ("host_seconds", "meta_sha256")  # (and its seal, a digest over them: h528)
# sweep.csv / sweep.jsonl columns copied from the points' host_seconds
SWEEP_HOST_COLUMNS = ("seconds.functional", "seconds.simulate", "seconds.one_off", "seconds.write",
                      "worker", "host", "pid")  # (and who ran the point: its results.json "ran")

# results.json sections of the functional layer (the render): independent of the
# architecture, so equal across packet sizes, N and schedulers ...
FUNCTIONAL_FIELDS = ("tlm", "config", "config_file", "plugins", "overrides", "seed", "mode", "scene", "plan",
                     "primary", "work", "work_keys", "photons", "image", "error", "warnings",
                     "scene_digest")  # (h339: the scene inputs as read: the same for every arch)
# ... and those of the timing model, which the architecture changes by design
TIMING_FIELDS = ("cycles", "fps", "timing")


def _functional(warnings: list[str]) -> list[str]:
    """A run's warnings less the timing model's (coarse packets, empty tiles, arch and cache
    settings that change nothing here: each starts with its key)."""
    return [w for w in warnings if not w.startswith(("arch.", "cache."))]

TINY = {
    "scene": "cornell",
    "seed": 0,
    "resolution": [24, 24],
    "photons": {"count": 1500},
    # a two-round reference: cheap, but the photon-map frame's error then has numbers
    "reference": {"photons": 1500, "k_nearest": 20, "min_rounds": 2, "max_rounds": 2},
    # two pipelines and the dynamic scheduler: the timing model's shared queue reruns too
    "arch": {"frames": 2, "pipelines": 2, "scheduler": "dynamic", "packet_size": 16, "trace": True},
}
MODES = ("refract", "pmap")  # ray traced only, and with the seeded photon map


def config_file(tmp_path: Path, mode: str, **over) -> Path:
    path = tmp_path / f"{mode}.yaml"
    path.write_text(yaml.safe_dump({**TINY, "mode": mode, **over}, sort_keys=False))
    return path


def use_cache(monkeypatch, folder: Path) -> Path:
    monkeypatch.setenv("TLM_CACHE", str(folder))
    return folder


def cli_run(config: Path, out: Path, *args: str) -> dict:
    assert main(["run", str(config), "--out", str(out), "--no-report", *args]) == 0
    return json.loads((out / "results.json").read_text())


def files(folder: Path) -> dict[str, Path]:
    return {str(p.relative_to(folder)): p for p in sorted(folder.rglob("*")) if p.is_file()}


def without(d: dict, dotted: tuple[str, ...]) -> dict:
    """A deep copy of ``d`` without the dotted keys, each of which must be present (a
    renamed host field must not silently turn into a compared or a missing one)."""
    d = json.loads(json.dumps(d))
    for key in dotted:
        *path, last = key.split(".")
        inner = d
        for p in path:
            inner = inner[p]
        assert last in inner, f"host field {key!r} is gone: update the exclusions"
        del inner[last]
    return d


def npz(path: Path) -> dict[str, tuple[str, tuple, bytes]]:
    with np.load(path) as z:
        return {k: (str(z[k].dtype), z[k].shape, z[k].tobytes()) for k in z.files}


def assert_same_folder(a: Path, b: Path, host: tuple[str, ...] = HOST_FIELDS) -> None:
    """Every file of ``a`` and ``b`` equal: bytes, except ``results.json`` (JSON without
    the host fields), ``.npz`` archives (their arrays bitwise: a zip member carries
    the time it was written) and ``.tlm-written`` (its paths alone)."""
    fa, fb = files(a), files(b)
    assert list(fa) == list(fb)
    for name, pa in fa.items():
        pb = fb[name]
        if pa.name == "results.json":
            ra, rb = json.loads(pa.read_text()), json.loads(pb.read_text())
            assert without(ra, host) == without(rb, host), name
        elif pa.suffix == ".npz":
            assert npz(pa) == npz(pb), name
        elif pa.name == ".tlm-written":  # (each file's size and time, h464: its paths compared; the files are)
            assert _paths(pa) == _paths(pb), name
        else:
            assert pa.read_bytes() == pb.read_bytes(), name


def _paths(listing: Path) -> list[str]:
    """The paths a run's ``.tlm-written`` lists (less each file's size and time: results.json's host fields)."""
    return [line.split("\t")[0] for line in listing.read_text().splitlines()]


def check_references(caches: list[Path]) -> None:
    """The photon-map references in ``caches`` (one each): one key, the same image bytes,
    the same meta.json but for its host seconds."""
    refs = []
    for cache in caches:
        (folder,) = (cache / "references").iterdir()
        refs.append(folder)
    for r in refs[1:]:
        assert r.name == refs[0].name
        assert (r / "reference.npy").read_bytes() == (refs[0] / "reference.npy").read_bytes()
        assert without(json.loads((r / "meta.json").read_text()), REFERENCE_HOST_FIELDS) == \
            without(json.loads((refs[0] / "meta.json").read_text()), REFERENCE_HOST_FIELDS)


# ---------------------------------------------------------------- reruns


@pytest.mark.slow
@pytest.mark.parametrize("mode", MODES)
def test_rerun_gives_identical_bytes_and_numbers(tmp_path, monkeypatch, mode):
    """Four runs of one config: two in this process and one in a fresh interpreter with
    another hash seed, each with a fresh cache (so each renders, and traces its own
    reference), give identical run folders; the seed changed gives other images."""
    config = config_file(tmp_path, mode)
    outs = {}
    for name in ("first", "second", "other_seed"):
        use_cache(monkeypatch, tmp_path / f"cache_{name}")
        if mode == "pmap":
            assert main(["reference", str(config)]) == 1  # (the tiny frame stops at max_rounds: cached all the same)
        seed = ["--seed", "1"] if name == "other_seed" else []
        outs[name] = tmp_path / name
        cli_run(config, outs[name], *seed)
    # a fresh interpreter: nothing carried over in module state, str hashes salted otherwise
    fresh_cache = use_cache(monkeypatch, tmp_path / "cache_fresh")
    if mode == "pmap":
        assert main(["reference", str(config)]) == 1  # (the tiny frame stops at max_rounds: cached all the same)
    outs["fresh"] = tmp_path / "fresh"
    env = {**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(fresh_cache), "PYTHONHASHSEED": "4242"}
    done = subprocess.run([sys.executable, "-m", "tlm", "run", str(config), "--out", str(outs["fresh"]),
                           "--no-report"], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr

    first = json.loads((outs["first"] / "results.json").read_text())
    assert set(HOST_FIELDS) <= set(first)
    if mode == "pmap":  # the error is compared as numbers, not as a hint to compute a reference
        assert first["error"]["available"] is True and first["error"]["rmse"] > 0
    else:
        assert first["error"] is None and first["photons"] is None
    assert (outs["first"] / "trace.json").is_file() and (outs["first"] / "aov" / "work.npz").is_file()
    for name in ("second", "fresh"):
        assert_same_folder(outs["first"], outs[name])

    if mode == "pmap":  # the references, traced three times from the fixed reference seed
        check_references([tmp_path / f"cache_{n}" for n in ("first", "second", "fresh")])

    # another seed: same eye rays, other light samples (and another photon map)
    other = json.loads((outs["other_seed"] / "results.json").read_text())
    assert other["seed"] == 1 and other["primary"] == first["primary"]
    changed = ["composite", "rcast", *(["pmap"] if mode == "pmap" else [])]
    for name in changed:
        assert (outs["other_seed"] / "images" / f"{name}.png").read_bytes() != \
            (outs["first"] / "images" / f"{name}.png").read_bytes(), name
        assert not np.array_equal(np.load(outs["other_seed"] / "radiance" / f"{name}.npy"),
                                  np.load(outs["first"] / "radiance" / f"{name}.npy")), name
    if mode == "pmap":
        assert other["photons"] != first["photons"]
        assert other["work"]["pmap"] != first["work"]["pmap"]
        assert other["error"]["rmse"] != first["error"]["rmse"]


# ---------------------------------------------------------------- the architecture


ARCHS = [  # packet sizes 1 pixel, a prime, a power of two, the whole 24 x 24 frame
    {"pipelines": 1, "scheduler": "static", "packet_size": 576},
    {"pipelines": 1, "scheduler": "dynamic", "packet_size": 1},
    {"pipelines": 2, "scheduler": "static", "packet_size": 7},
    {"pipelines": 2, "scheduler": "dynamic", "packet_size": 64},
    {"pipelines": 4, "scheduler": "static", "packet_size": 64},
    {"pipelines": 4, "scheduler": "dynamic", "packet_size": 7},
]


@pytest.mark.slow
@pytest.mark.parametrize("mode", MODES)
def test_architecture_changes_timing_only(tmp_path, monkeypatch, mode):
    """Packet size, N and scheduler change the timing sections and nothing else: images,
    radiance, AOVs and the functional sections of results.json are identical."""
    use_cache(monkeypatch, tmp_path / "cache")
    config = config_file(tmp_path, mode)
    if mode == "pmap":  # one reference: the photon-map frame's error is compared as numbers
        assert main(["reference", str(config)]) == 1  # (the tiny frame stops at max_rounds: cached all the same)
    base = {**TINY, "mode": mode, "arch": {"frames": 1, "trace": False}}
    results, outs = [], []
    for i, arch in enumerate(ARCHS):
        cfg = config_from_dict({**base, "arch": {**base["arch"], **arch}})
        outs.append(tmp_path / f"arch{i}")
        results.append(run(cfg, outs[-1]))

    first = results[0]
    assert set(first) == {*FUNCTIONAL_FIELDS, *TIMING_FIELDS, *HOST_FIELDS}  # every section classified
    if mode == "pmap":
        assert first["error"]["available"] is True and first["error"]["rmse"] > 0
    for arch, res, out in zip(ARCHS, results, outs):
        assert set(res) == set(first)
        for key in FUNCTIONAL_FIELDS:
            if key == "warnings":  # (those of the stream and of arch settings are the timing model's: _functional)
                assert _functional(res[key]) == _functional(first[key]), (arch, key)
                continue
            assert res[key] == first[key], (arch, key)
        tm = res["timing"]
        assert (tm["packet_size"], len(tm["pipelines"]), tm["scheduler"]) == \
            (arch["packet_size"], arch["pipelines"], arch["scheduler"])
        for folder in ("images", "radiance"):
            for name, path in files(outs[0] / folder).items():
                assert (out / folder / name).read_bytes() == path.read_bytes(), (arch, folder, name)
        for name in ("primary.npz", "work.npz"):
            assert npz(out / "aov" / name) == npz(outs[0] / "aov" / name), (arch, name)
    # the variants did reach the timing model: the comparisons above are not of one run
    assert len({json.dumps(r["cycles"], sort_keys=True) for r in results}) == len(ARCHS)


# ---------------------------------------------------------------- executors


def read_csv(path: Path) -> tuple[list[str], list[dict]]:
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        return list(reader.fieldnames or []), list(reader)


SWEEP = {
    "base": {**{k: v for k, v in TINY.items() if k != "reference"},
             "arch": {"frames": 2, "packet_size": 16, "trace": True}},
    "grid": {"arch.pipelines": [1, 4], "arch.scheduler": ["static", "dynamic"]},
    "zip": {"mode": ["refract", "pmap"], "seed": [0, 1]},
}
EXECUTORS = {"in_process": {"jobs": 1}, "pool": {"jobs": 2}, "dask": {"jobs": 2, "dask": "local"}}


def sweep_with(root: Path, name: str) -> Path:
    """The sweep of :data:`SWEEP` (one file for all executors) run by ``name`` into a
    folder of its own, with a fresh cache: each executor renders its two frames."""
    sweep = root / "sweep.yaml"
    if not sweep.exists():
        sweep.write_text(yaml.safe_dump(SWEEP, sort_keys=False))
    with pytest.MonkeyPatch.context() as mp:
        use_cache(mp, root / f"cache_{name}")
        done = run_sweep(sweep, root / name, **EXECUTORS[name])
    assert (done.ok, done.failed, done.renders) == (8, 0, 2), name
    return root / name


@pytest.fixture(scope="module")
def in_process(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("executors")
    return sweep_with(root, "in_process")


def strip(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in SWEEP_HOST_COLUMNS} for r in rows]


@pytest.mark.slow
@pytest.mark.parametrize("executor", ["pool", "dask"])
def test_executors_give_identical_points_and_rows(in_process, executor):
    """One sweep in this process (jobs=1) and in a process pool (jobs=2) or on a local
    Dask cluster (2 workers), each with a fresh cache: the same point folders byte for
    byte (results.json but for the host fields), the same sweep.yaml, and the same
    sweep.csv and sweep.jsonl rows but for the seconds columns and who ran each point."""
    if executor == "dask":
        pytest.importorskip("distributed", reason="dask.distributed is not installed: no Dask executor")
    ref = in_process
    out = sweep_with(ref.parent, executor)

    head, rows = read_csv(ref / "sweep.csv")
    assert {r["mode"] for r in rows} == {"refract", "pmap"}
    assert len({r["cycles.throughput"] for r in rows}) >= 4  # the points differ: a mix-up would show
    assert set(SWEEP_HOST_COLUMNS) <= set(head)

    assert (out / "sweep.yaml").read_bytes() == (ref / "sweep.yaml").read_bytes()
    assert_same_folder(ref / "points", out / "points", host=HOST_FIELDS + POINT_HOST_FIELDS)
    head_b, rows_b = read_csv(out / "sweep.csv")
    assert head_b == head
    assert strip(rows_b) == strip(rows)
    jsonl = [strip([json.loads(line) for line in (o / "sweep.jsonl").read_text().splitlines()])
             for o in (ref, out)]
    assert jsonl[0] == jsonl[1]
