"""``tlm scaling`` tells each point's scene by its file (:func:`tlm.experiments.provenance.scene_identity`):
the points of one scene file digest it once per study, not once a point
(:func:`tlm.experiments.provenance.identities_remembered` around the collection, as ``tlm thesis``
and the report do), and the fit is the one it was before."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import yaml

from tlm.experiments import provenance
from tlm.experiments.scaling import analyse

NS = (1, 2, 4)


def fake_sweep(folder: Path, scene: Path, scheduler: str) -> Path:
    """A finished sweep folder over ``arch.pipelines`` in :data:`NS` of one scene file: each
    point's ``results.json`` and resolved config as far as eq. 5.2 reads them (no render)."""
    rows = []
    for n in NS:
        digest = f"p{n}"
        point = folder / "points" / digest
        point.mkdir(parents=True)
        work = 900 // n
        res = {"scene": {"name": "mesh", "source": str(scene)},
               "timing": {"pipelines": [{"traversal": work, "intersection": work // 2, "fragment": work // 3}] * n,
                          "throughput_estimate": {"steady": True, "frames": 5, "min_frames": 3}},
               "cycles": {"vertex": 50, "latency": 100 + 2 * work, "throughput": 60 + work}}
        (point / "results.json").write_text(json.dumps(res))
        cfg = {"scene": str(scene), "mode": "rcast", "seed": 0, "arch": {"scheduler": scheduler, "pipelines": n}}
        (point / "config.resolved.yaml").write_text(yaml.safe_dump(cfg))
        rows.append({"point": len(rows), "hash": digest, "status": "ok", "arch.pipelines": n})
    (folder / "sweep.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    (folder / "sweep.yaml").write_text(yaml.safe_dump({"points": [{"hash": r["hash"]} for r in rows]}))
    return folder


def test_a_scaling_study_digests_each_scene_file_once(tmp_path, monkeypatch):
    scene = tmp_path / "mesh.yaml"
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    scene.write_text("geometry: {mesh: m.obj}\ncamera: {eye: [0, 0, -3], target: [0, 0, 0], vfov: 40}\n")
    sweeps = [fake_sweep(tmp_path / "a", scene, "static"), fake_sweep(tmp_path / "b", scene, "dynamic")]
    before = [analyse([sw], tmp_path / f"eq_{sw.name}")["fits"] for sw in sweeps]  # (each sweep on its own)

    digests: Counter = Counter()
    identity = provenance._identity

    def counted(path, depth):
        if depth == 0:
            digests[str(path)] += 1
        return identity(path, depth)

    monkeypatch.setattr(provenance, "_identity", counted)
    done = analyse(sweeps, tmp_path / "eq")
    assert digests == Counter({str(scene): 1}), digests  # (six points of one scene file)
    assert {f["scene"] for f in done["fits"]} == {scene.name} and len(done["fits"]) == 4  # (2 schedulers x 2 targets)
    assert sorted(done["fits"], key=json.dumps) == sorted(before[0] + before[1], key=json.dumps)
    assert provenance.scene_identity(scene) == provenance.scene_identity(scene)  # (outside: computed each call)
    assert digests[str(scene)] == 3
