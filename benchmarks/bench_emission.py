"""Photon emission aimed at the specular parts: the compiled cone mixture against numpy, in the same run.

A caustic group aimed with ``photons.aim: parts`` (the default) draws each photon from
a mixture of the cones bounding boxes of at most ``photons.aim_triangles`` specular
triangles, and tests every cone for the density (``tlm.kernels.emission.cone_mixture``):
work of photons x boxes. The numpy code forms those (photon, box) arrays chunk by chunk;
the compiled code (``tlm/kernels/_jit_cones.py``) walks the boxes photon by photon,
with the threads at once. For each scene (default: the built-in ``cornell``, and the
Cornell box with the 69k-triangle glass blob of ``bench_memory.py``, 2,064 boxes), this
bench emits the scene's photons (its own count, the defaults' caustic fraction and
boxes: all of ``emit``, of which the cone mixture is most) with each engine at each
thread count, engines alternated ``--rounds`` times after one untimed emission of each,
and prints the median seconds and the ratio numpy / compiled (paired, per round). It
checks that every engine and thread count gives the bytes of numpy's one-thread
emission (FAIL and exit 1 otherwise).

    python benchmarks/bench_emission.py [--scenes cornell glass] [--threads 1 2] [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_memory import GLASS, write_scene
from timing import exit_status, verdict

from tlm.config import PhotonConfig
from tlm.kernels import threads
from tlm.kernels.bsp import bounds
from tlm.kernels.emission import aim_boxes, emit, photon_key
from tlm.scenes.loader import load_scene


def emission(scene, boxes, fraction: float):
    """What the photon trace emits for ``scene`` (its photon count, aimed at ``boxes``)."""
    return emit(scene.lights, scene.photons, photon_key(0), bounds(scene.triangles.reshape(-1, 3)), None,
                fraction, with_source=True, caustic_boxes=boxes)


def bench_scene(name: str, tmp: Path, defaults: PhotonConfig, counts: list[int], rounds: int) -> None:
    """One scene's table, and the verdict on its bytes."""
    if name == "glass":
        path, _ = write_scene(tmp, "glass", *GLASS)
        scene = load_scene(str(path))
    else:
        scene = load_scene(name)
    boxes = aim_boxes(scene.triangles, scene.material_table()["kind"], scene.part, defaults.aim_triangles)
    print(f"\n{name}: {scene.triangles.shape[0]:,} triangles, {scene.photons:,} photons "
          f"(caustic fraction {defaults.caustic_fraction}), {len(boxes):,} boxes of at most "
          f"{defaults.aim_triangles} specular triangles")
    # the reference, numpy on one thread; then one untimed emission with the compiled code
    # (numba loads its functions on the first call)
    os.environ["TLM_KERNELS"] = "numpy"
    with threads.using(1):
        reference = [x.tobytes() for x in emission(scene, boxes, defaults.caustic_fraction)]
    os.environ["TLM_KERNELS"] = "numba"
    same = [x.tobytes() for x in emission(scene, boxes, defaults.caustic_fraction)] == reference
    print(f"{'threads':>7} {'numpy s':>8} {'compiled s':>10} {'numpy / compiled':>17}")
    for n in counts:
        times: dict[str, list[float]] = {"numpy": [], "numba": []}
        with threads.using(n):
            for _ in range(rounds):
                for engine in ("numpy", "numba"):
                    os.environ["TLM_KERNELS"] = engine
                    t0 = time.perf_counter()
                    got = [x.tobytes() for x in emission(scene, boxes, defaults.caustic_fraction)]
                    times[engine].append(time.perf_counter() - t0)
                    same = same and got == reference
        ratio = np.median(np.array(times["numpy"]) / np.array(times["numba"]))
        print(f"{n:7d} {np.median(times['numpy']):8.3f} {np.median(times['numba']):10.3f} {ratio:16.2f}x")
    verdict(same, f"{name}: both engines emit numpy's one-thread bytes at every thread count")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", choices=["cornell", "glass"], default=["cornell", "glass"])
    ap.add_argument("--threads", nargs="+", type=int, default=sorted({1, threads.available()}))
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    if args.rounds < 1 or min(args.threads) < 1:
        ap.error("--rounds and --threads must be >= 1")
    defaults = PhotonConfig()
    old = os.environ.get("TLM_KERNELS")
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for name in args.scenes:
                bench_scene(name, Path(tmp), defaults, args.threads, args.rounds)
    finally:
        if old is None:
            os.environ.pop("TLM_KERNELS", None)
        else:
            os.environ["TLM_KERNELS"] = old
    exit_status()


if __name__ == "__main__":
    main()
