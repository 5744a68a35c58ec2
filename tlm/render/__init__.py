"""Passes and the pass planner: the functional frames of an image (no timing).

:mod:`~tlm.render.frame` casts a frame's eye rays, :mod:`~tlm.render.passes` holds the ray
cast, reflection and refraction passes (:mod:`~tlm.render.walk` their specular walk),
:mod:`~tlm.render.pmap` the photon-map frame, :mod:`~tlm.render.planner` decides which a
config runs, and :mod:`~tlm.render.batches` renders every planned pass of a frame over
the whole image in batches (radiance, work, the primary AOVs, the photon trace and the
gather tallies).
"""
