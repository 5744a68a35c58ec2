"""A scene's PMap composite under several settings, against its cached Mitsuba truth (issue 24).

Each variant is the scene's config (as ``bench_oracle.py`` reads it) with a few sections
overridden, given as a JSON list of mappings; each is rendered once and printed with its
render seconds, its relative MSE (away from the lights, as ``bench_oracle.py`` measures)
and its mean FLIP against the truth. The truth must be cached: run ``bench_oracle.py
--scenes SCENE`` first (it computes and caches it). What final gathering, the caustic
budget or a radius buys, side by side:

    PYTHONPATH=. python benchmarks/bench_settings.py cornell \\
        '[{"estimate": {"final_gather": 0}}, {"estimate": {"final_gather": 16}}]'
"""

from __future__ import annotations

import argparse
import json
import sys

from bench_oracle import CONFIGS, config, timed_render

from tlm.experiments.reference import image_error
from tlm.oracle import mitsuba as om
from tlm.render.passes import diffuse_pixels, sees_a_light


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", choices=sorted(CONFIGS))
    ap.add_argument("variants", help='JSON list of section overrides, e.g. \'[{"estimate": {"final_gather": 0}}]\'')
    ap.add_argument("--truth-spp", type=int, default=4096)
    ap.add_argument("--large-truth-spp", type=int, default=256)
    args = ap.parse_args()
    variants = json.loads(args.variants)
    if not isinstance(variants, list) or not all(isinstance(v, dict) for v in variants):
        sys.exit("bench_settings: variants must be a JSON list of mappings")
    om.require()
    truth = keep = None
    for v in variants:
        res, secs = timed_render(config(args.scene, "pmap", None, extra=v))
        h, w = res.scene.camera.height, res.scene.camera.width
        if truth is None:
            spp = args.large_truth_spp if res.scene.n_triangles > 100_000 else args.truth_spp
            diffuse = diffuse_pixels(res.frame, res.gbuffer).reshape(h, w)
            found = om.composite_truth(res.scene, diffuse, spp=spp, compute=False,
                                       light_tracing=om.needs_light_tracing(res.scene) and args.scene == "ring")
            if found is None:
                sys.exit(f"bench_settings: no cached truth of {args.scene} at {spp} spp: run "
                         f"'python benchmarks/bench_oracle.py --scenes {args.scene}' first")
            truth = found[0]
            keep = om.away_from_lights(sees_a_light(res.frame, res.gbuffer).reshape(h, w))
        img = res.composite
        print(f"{json.dumps(v)}: {secs:.1f} s, rel MSE {image_error(img[keep], truth[keep])['rel_mse']:.4f}, "
              f"FLIP {om.flip(img, truth):.3f}", flush=True)


if __name__ == "__main__":
    main()
