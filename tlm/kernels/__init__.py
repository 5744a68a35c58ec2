"""The functional layer: pure numpy kernels (never SimPy) that return results and work.

Every kernel runs on any packet of rays, pixels or photons and returns, with its
results, the work it did (node visits, leaf visits, triangle tests, ...), so that the
timing layer can turn work into cycles per packet.
"""

from tlm.kernels import _malloc  # noqa: F401  (allocator tuning, speed only)
from tlm.kernels._malloc import trim as release_memory  # noqa: F401  (freed blocks back to the system)
