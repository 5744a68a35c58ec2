"""The run warning on photon paths that ``photons.max_bounces`` cut with power still travelling (h505), out of
:mod:`tlm.experiments.run_warnings` (whose :func:`~tlm.experiments.run_warnings.reference_warnings` gives it, so a
cached frame says it as its error, measured when the frame is read, has it).

The photon trace records the power its photons still carried when the cap ended their paths
(:attr:`tlm.kernels.photons.PhotonMaps.cut_power`, ``results.json`` ``photons.cut_power``) and its luminance's share
of the lights' power (``photons.cut_share``). That light never reaches the maps: the frame's photon-map term
(the indirect light and caustics) is darker by about that share (more where its light is of many bounces). With
final gathering the frame also goes one diffuse bounce past its reference
(:mod:`tlm.experiments.reference`: the k nearest photons of the indirect map at the eye's point, no gather, the
same ``photons.max_bounces``), which gets a bounce less of the light the cap spares, so the error against it
measures part of that share as well as the run's noise.
"""

from __future__ import annotations

from tlm.config import RunConfig

# the share of the lights' power past which the line is said: 5%, past twice the relative standard error of its mean
# that a reference may keep (reference.tolerance 0.02), so the loss (the photon-map term darker by about the share or
# more: room's 2.8% for 2.35%) cannot pass for the reference's noise; configs/cornell-water.yaml raised its
# photons.max_bounces to 16 for the 5.84% its scene keeps at 8 ("8 hits lose ~7 %"). The shares at the defaults
# (h505, the global group's alone since h511; 8 bounces): ring 0% (configs/ring.yaml's 300000 photons 0.0007%),
# thesis/ring 0.007%, conference 0.44%, cornell-box 0.44%, cornell-sphere 0.90%, cornell 1.05% (configs/cornell.yaml,
# cornell_pmap.yaml: its pmap term 1.1% darker than at 30 bounces, its composite 0.27%), thesis/room 2.01%
# (configs/thesis.yaml), room 2.35% (configs/room.yaml: its composite 0.8% darker, h500), cornell-water 5.84%
# (configs/cornell-water.yaml at 400,000 of its 2,000,000 photons: 1.09%). So
# the built-in scenes and the committed configs say nothing (tests/test_warnings.py: no line on the built-in
# scenes) but the cornell-water scene at 8 bounces; a closed box of albedo 0.8 keeps 0.8^8 = 16.8% (h500's cube08:
# its frame 0.877 of a path tracer's), of albedo 1 all of it
CUT_SHARE = 0.05


def cut_warnings(photons: dict | int | None, cfg: RunConfig, error: dict | None = None) -> list[str]:
    """A line when the run's photons (``results.json`` ``photons``, or what
    :func:`~tlm.experiments.run_warnings.emitted_photons` gives of it) still carried more than :data:`CUT_SHARE` of
    the lights' power when ``photons.max_bounces`` ended their paths (``cut_share``): the frame misses the light
    of the later bounces; with final gathering and an error measured (``error`` ``available``), that the run
    gathers one bounce past its reference, so its error carries part of that share. None where the record holds
    no share (a count alone, a record from before the key)."""
    share = photons.get("cut_share") if isinstance(photons, dict) else None
    if isinstance(share, bool) or not isinstance(share, int | float) or not share > CUT_SHARE:
        return []
    bounces = cfg.photons.max_bounces
    line = (f"photons.max_bounces {bounces} ends photon paths that still carry {share:.1%} of the lights' power "
            f"(results.json photons.cut_share): the photon-map frame misses the light of their later bounces and "
            f"is darker for it; raise photons.max_bounces")
    if error and error.get("available") and cfg.estimate.final_gather > 0:
        line += (f"; with final gathering (estimate.final_gather {cfg.estimate.final_gather}) this run gathers one "
                 f"bounce past its reference {error.get('reference')}, which reads the indirect map at the eye's "
                 "point, so the pmap error against it (error.rmse, error.rel_mse) carries part of that share")
    return [line]
