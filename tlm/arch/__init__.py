"""The timing layer: the thesis GPU's units as SimPy processes, in integer clock cycles.

This package never changes a result of the functional layer (``tlm.kernels``); it turns
the work the kernels report into cycles. The seam is :mod:`tlm.arch.functional`; the
frame program :mod:`tlm.arch.frame_program` (Figs. 13 and 14 as stages, tiles and
phases, the work cut into packets of any size) prices its jobs with the PM programs'
instruction costs, :mod:`tlm.arch.costs` (the table ``programs.yaml``). The hardware:
:mod:`tlm.arch.pm` (the Vertex, Traversal, Intersection and Fragment PMs),
:mod:`tlm.arch.memory` (the DDR modules), :mod:`tlm.arch.crossbar` (swaps, block copies
and their arbiter) and :mod:`tlm.arch.fifo` (Traversal to Intersection), each made of
the components of :mod:`tlm.arch.units` (scoped units with eq. 5.1 accounting and
stalls by cause, the trace, and the run loop that names a deadlock instead of hanging).
:mod:`tlm.arch.events` names the order of a cycle's events; :mod:`tlm.arch.schedulers`
hands a tiled stage's tiles to the pipelines; :mod:`tlm.arch.model` is the control unit
and the simulation.
"""
