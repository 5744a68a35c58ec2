"""``python -m tlm`` is the ``tlm`` command."""

import sys

from tlm.cli import main

sys.exit(main())
