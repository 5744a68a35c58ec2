"""Passes and the pass planner: the functional frames of an image (no timing).

:mod:`~tlm.render.passes` holds the passes, :mod:`~tlm.render.planner` decides which a
config runs, and :mod:`~tlm.render.batches` renders every planned pass of a frame over
the whole image in batches (radiance, work, the primary AOVs, the photon trace and the
gather tallies).
"""
