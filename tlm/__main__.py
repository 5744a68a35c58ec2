"""``python -m tlm`` is the ``tlm`` command."""

import sys

import tlm.cli_signals  # noqa: F401  (first: a signal during the imports below is the command's, early_signals)
from tlm.cli import main
from tlm.cli_signals import forget_lost_interrupt

status = main()
forget_lost_interrupt()  # else a SIGTERM's interrupt that left numba's exec'd source may end it by SIGINT (see there)
sys.exit(status)
