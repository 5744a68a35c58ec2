"""Independent oracles for our images: Mitsuba 3 renders of the same scenes.

:mod:`tlm.oracle.mitsuba` turns a :class:`~tlm.scenes.model.Scene` into a Mitsuba 3
scene, renders ground-truth images (cached under ``$TLM_CACHE/oracle``) and measures
image error (FLIP, the per-pixel relative MSE ``rel_mse_per_pixel``, relative RMSE). Mitsuba is an optional dependency:
nothing here imports it until a render is asked for.
"""
