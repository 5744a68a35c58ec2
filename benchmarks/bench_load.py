"""Loading a large published scene: the LBNL conference room, file to ``Scene``.

The conference room (``scenes/meshes/conference.obj.xz``: 27 MB of OBJ compressed to
1.6 MB, 331,179 triangles after fan triangulation, 35 MTL materials, no ``vn``) is
loaded by ``tlm.scenes.loader.load_scene`` from a temporary scene file naming the
mesh: decompression, tlm's vectorized OBJ reader, the MTL's materials and the crease
normals (the file has no normals), everything a render starts from, parsed (the scene
cache, :mod:`tlm.scenes.cache`, off). Beside it, in the same run: the first load with
the cache on (it parses and writes the entries), every later load (it reads them back),
the parse through the uncompressed OBJ, tlm's mesh parse alone, the crease normals
alone, and trimesh's load of the uncompressed OBJ with the options tlm used before it
read OBJ itself (``process=False``, groups split, materials skipped), which also leaves
the materials and the normals to do. Bar (issue: loading large scenes): file to
``Scene``, parsed, in at most 3 s. Timings are the best of ``--repeat`` runs (trimesh:
``--trimesh-repeat``); the cache is a temporary folder of this run's.

    python benchmarks/bench_load.py [--repeat 3] [--trimesh-repeat 1] [--mesh PATH]
"""

from __future__ import annotations

import argparse
import lzma
import os
import shutil
import tempfile
from pathlib import Path

from timing import best_of, exit_status, verdict

ROOT = Path(__file__).resolve().parents[1]

BAR_S = 3.0
SCENE = """name: conference-bench
geometry: {{mesh: {mesh}}}
materials:
  grey: {{type: lambertian, albedo: [0.5, 0.5, 0.5]}}
default_material: grey
lights:
  - {{type: point, position: [0.0, 500.0, 0.0], power: [1.0e6, 1.0e6, 1.0e6]}}
camera: {{eye: [-800.0, 350.0, 400.0], target: [500.0, 200.0, -300.0], up: [0.0, 1.0, 0.0], vfov: 60.0}}
resolution: [64, 48]
photons: 1000
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--trimesh-repeat", type=int, default=1)
    ap.add_argument("--mesh", type=Path, default=ROOT / "scenes" / "meshes" / "conference.obj.xz")
    args = ap.parse_args()

    import trimesh

    from tlm.scenes import cache, meshes
    from tlm.scenes.loader import load_scene
    from tlm.scenes.meshes import load_mesh
    from tlm.scenes.normals import crease_normals

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        os.environ["TLM_CACHE"] = str(tmp / "cache")
        packed = args.mesh.resolve()
        plain = tmp / packed.name.removesuffix(".xz")
        if packed.suffix == ".xz":
            plain.write_bytes(lzma.decompress(packed.read_bytes()))
            mtl = packed.parent / (plain.stem + ".mtl")
            if mtl.is_file():
                (tmp / mtl.name).write_bytes(mtl.read_bytes())
        else:
            plain = packed
        scenes = {}
        for label, mesh in (("compressed", packed), ("plain", plain)):
            scenes[label] = tmp / f"{label}.yaml"
            scenes[label].write_text(SCENE.format(mesh=str(mesh)))

        def first_load() -> None:
            shutil.rmtree(cache.cache_dir(), ignore_errors=True)
            load_scene(str(scenes["compressed"]))

        scene = load_scene(str(scenes["compressed"]))  # warms the imports up
        n = scene.n_triangles
        file_mats = len(load_mesh(packed).materials)
        t_first = best_of(first_load, args.repeat)
        t_cached = best_of(lambda: load_scene(str(scenes["compressed"])), args.repeat)
        # the cache off (an empty folder, nothing kept): parsed every time
        keep, cache.MIN_TRIANGLES = cache.MIN_TRIANGLES, 1 << 62
        os.environ["TLM_CACHE"] = str(tmp / "empty")
        try:
            t_scene = best_of(lambda: load_scene(str(scenes["compressed"])), args.repeat)
            t_scene_plain = best_of(lambda: load_scene(str(scenes["plain"])), args.repeat)
            assert not (tmp / "empty").exists()
        finally:
            cache.MIN_TRIANGLES = keep
        t_mesh = best_of(lambda: meshes._parse(plain), args.repeat)
        geom = meshes._parse(plain)[0]
        t_normals = best_of(lambda: crease_normals(geom.triangles, geom.part), args.repeat)

        def old() -> None:
            trimesh.load(str(plain), force=None, process=False, group_material=False, maintain_order=True,
                         skip_materials=True, split_groups=True)

        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t_trimesh = best_of(old, args.trimesh_repeat)

    rows = [
        (f"file -> Scene (load_scene, {packed.name}), parsed", t_scene),
        (f"file -> Scene (load_scene, {plain.name}), parsed", t_scene_plain),
        (f"file -> Scene ({packed.name}), first load: parsed and cached", t_first),
        (f"file -> Scene ({packed.name}), later loads: from the cache", t_cached),
        (f"tlm mesh parse ({plain.name}, with materials)", t_mesh),
        ("crease normals", t_normals),
        (f"trimesh.load ({plain.name}, no materials)", t_trimesh),
    ]
    width = max(len(label) for label, _ in rows)
    print(f"{packed.name}: {n:,} triangles, {file_mats} materials from the file, "
          f"normals: {scene.extra.get('normals')}")
    for label, t in rows:
        print(f"  {label:<{width}}  {t:7.3f} s")
    print(f"  trimesh / tlm mesh parse: {t_trimesh / t_mesh:.1f}x")
    print(f"  parsed / from the cache: {t_scene / t_cached:.1f}x")
    verdict(t_scene <= BAR_S, f"file -> Scene, parsed, in {t_scene:.2f} s (bar: at most {BAR_S:.0f} s)")
    exit_status()


if __name__ == "__main__":
    main()
