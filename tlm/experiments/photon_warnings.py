"""The run warning on photon paths that ``photons.max_bounces`` cut with power still travelling (h505), out of
:mod:`tlm.experiments.run_warnings` (whose :func:`~tlm.experiments.run_warnings.reference_warnings` gives it, so a
cached frame says it as its error, measured when the frame is read, has it), and ``tlm error-vs-cost``'s, once for
the study, naming its points past the share (:func:`study_cut_line`: a row's ``cut_share``; h529).

The photon trace records the power its photons still carried when the cap ended their paths
(:attr:`tlm.kernels.photons.PhotonMaps.cut_power`, ``results.json`` ``photons.cut_power``) and its luminance's share
of the lights' power that reached the scene (``photons.cut_share``; not what left an open scene at once, most of a
directional light's disc: :func:`tlm.kernels.photons.reached`). That light never reaches the maps: the frame's
photon-map term (the indirect light and caustics) is darker by about that share (more where its light is of many
bounces). With final gathering the frame also goes one diffuse bounce past its reference
(:mod:`tlm.experiments.reference`: the k nearest photons of the indirect map at the eye's point, no gather, the
same ``photons.max_bounces``), which gets a bounce less of the light the cap spares, so the error against it
measures part of that share as well as the run's noise.
"""

from __future__ import annotations

from tlm.config import RunConfig
from tlm.config_words import listing

# the share of the lights' power past which the line is said: 5%, past twice the relative standard error of its mean
# that a reference may keep (reference.tolerance 0.02), so the loss (the photon-map term darker by about the share or
# more: room's 2.8% for 2.35%) cannot pass for the reference's noise; configs/cornell-water.yaml raised its
# photons.max_bounces to 16 for the 6.86% its scene keeps at 8 ("8 hits lose ~7 %"). The shares at the defaults
# (8 bounces; the global group's alone since h511, of the power that reached the scene since h529: an open scene's
# share of all the lights emit was lower by what left at once, cornell's 1.05%, thesis/ring's 0.007%): ring 0%
# (configs/ring.yaml's 300000 photons 0.004%), thesis/ring 0.05%, conference 0.44%, cornell-box 0.54%, cornell-sphere
# 1.08%, cornell 1.28% (configs/cornell.yaml, cornell_pmap.yaml: its pmap term 1.1% darker than at 30 bounces, its
# composite 0.27%), thesis/room 2.01% (configs/thesis.yaml), room 2.35% (configs/room.yaml: its composite 0.8%
# darker, h500), cornell-water 6.86% (configs/cornell-water.yaml at 400,000 of its 2,000,000 photons: 1.28%). So
# the built-in scenes and the committed configs say nothing (tests/test_warnings.py: no line on the built-in
# scenes) but the cornell-water scene at 8 bounces; a closed box of albedo 0.8 keeps 0.8^8 = 16.8% (h500's cube08:
# its frame 0.877 of a path tracer's), of albedo 1 all of it; an open well of albedo 0.8 (1 x 2 x 1, lit from
# straight above by a directional light whose disc the well's opening takes a fifth of) 10.7%, which as a share of
# the whole disc's power was 2.2% (tests/test_cut_and_words_h529.py)
CUT_SHARE = 0.05
# the points the study's line names (the report's way, :func:`~tlm.config_words.listing`): of more, the first ones and
# how many more (configs/error_vs_cost.yaml's 66 points at a low photons.max_bounces: every one past the share)
NAMED_POINTS = 7


def cut_warnings(photons: dict | int | None, cfg: RunConfig, error: dict | None = None) -> list[str]:
    """A line when the run's photons (``results.json`` ``photons``, or what
    :func:`~tlm.experiments.run_warnings.emitted_photons` gives of it) still carried more than :data:`CUT_SHARE` of
    the lights' power that reached the scene when ``photons.max_bounces`` ended their paths (``cut_share``): the
    frame misses the light of the later bounces; with final gathering and an error measured (``error``
    ``available``), that the run gathers one bounce past its reference, so its error carries part of that share.
    None where the record holds no share (a count alone, a record from before the key)."""
    share = photons.get("cut_share") if isinstance(photons, dict) else None
    if isinstance(share, bool) or not isinstance(share, int | float) or not share > CUT_SHARE:
        return []
    bounces = cfg.photons.max_bounces
    line = (f"photons.max_bounces {bounces} ends photon paths that still carry {share:.1%} of the lights' power "
            f"that reached the scene (results.json photons.cut_share): the photon-map frame misses the light of their "
            f"later bounces and is darker for it; raise photons.max_bounces")
    if error and error.get("available") and cfg.estimate.final_gather > 0:
        line += (f"; with final gathering (estimate.final_gather {cfg.estimate.final_gather}) this run gathers one "
                 f"bounce past its reference {error.get('reference')}, which reads the indirect map at the eye's "
                 "point, so the pmap error against it (error.rmse, error.rel_mse) carries part of that share")
    return [line]


def study_cut_line(rows: list[dict], cfg: RunConfig, key: str, measured: bool = True) -> str | None:
    """``tlm error-vs-cost``'s line, once for the study (h529), on its points whose photons still carried more than
    :data:`CUT_SHARE` of the lights' power that reached the scene when ``photons.max_bounces`` (the base's: every
    point shares it with the reference ``key``) ended their paths: how many, each named (``point``; of more than
    :data:`NAMED_POINTS` + 1, the first and how many more, :func:`~tlm.config_words.listing`), the most of
    them with its ``factors``, and, for those with final gathering, that they gather one bounce past the reference,
    so their rmse and rel_mse carry part of that share (not where ``measured`` is False, a black reference: no
    rel_mse, and the rmse each point's own radiance, as the study's line on it says; h535). ``rows``: the study's
    (their ``cut_share``; a row without one, of an older study, is not weighed). None where no point passes the
    share."""
    weighed = [r for r in rows if isinstance(r.get("cut_share"), int | float) and not isinstance(r["cut_share"], bool)]
    past = [r for r in weighed if r["cut_share"] > CUT_SHARE]
    if not past:
        return None
    worst = max(past, key=lambda r: r["cut_share"])
    named = listing((r["point"] for r in past), NAMED_POINTS)  # (of many, the first and how many more: h535)
    count = len(past)
    line = (f"error-vs-cost: {count} of the {len(weighed)} points {'is' if count == 1 else 'are'} traced with photon "
            f"paths that photons.max_bounces {cfg.photons.max_bounces} ends still carrying more than {CUT_SHARE:.0%} "
            f"of the lights' power that reached the scene (rows' cut_share), point{'s' if count > 1 else ''} "
            f"{named}; the most, point {worst['point']} ({worst['factors']}): {worst['cut_share']:.1%}; "
            f"{'their' if count > 1 else 'its'} photon-map frames miss the light of the later bounces and are darker "
            f"for it; raise the base's photons.max_bounces")
    gathered = [str(r["point"]) for r in past if (r.get("final_gather") or 0) > 0]
    if gathered and measured:
        line += (f"; with final gathering (point{'s' if len(gathered) > 1 else ''} {listing(gathered, NAMED_POINTS)}) "
                 f"a point gathers one bounce past its reference {key}, which reads the indirect map at the eye's "
                 "point, so its rmse and rel_mse carry part of that share")
    return line


def study_cut_said(say, rows: list[dict], cfg: RunConfig, key: str, measured: bool = True) -> list[dict]:
    """``rows``, as they are, once ``say`` got :func:`study_cut_line` (where there is one): the study's ``finish``."""
    line = study_cut_line(rows, cfg, key, measured)
    if line is not None:
        say(line)
    return rows
