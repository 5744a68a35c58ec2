"""The timing layer: the thesis GPU's units as SimPy processes, in integer clock cycles.

This package never changes a result of the functional layer (``tlm.kernels``); it turns
the work the kernels report into cycles. It is built up in issue [3 of 7]; so far it
holds the programmable PMs' data cache model (:mod:`tlm.kernels.memory`) and the
components every unit is made of (:mod:`tlm.arch.units`: scoped units with eq. 5.1
accounting and stalls by cause, the controller's handshake semaphores, the trace, and
the run loop that names a deadlock instead of hanging), and the seam itself
(:mod:`tlm.arch.work`: a run's work cut into packets of any size).
"""
