"""Host-side progress for the experiments: :class:`Timer`, :func:`progress_bar` and
:class:`Ticking`, as the experiments, the API and notebooks import them.

They live in :mod:`tlm.progress`, in the base layer, since the render's batch loop
(:mod:`tlm.render.batches`) books its stages and draws its bar with them too.
"""

from __future__ import annotations

from tlm.progress import Ticking, Timer, progress_bar

__all__ = ["Ticking", "Timer", "progress_bar"]
