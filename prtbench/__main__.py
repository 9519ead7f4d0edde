"""``python -m prtbench ...``: the same entry point as the ``prtbench`` script."""

import sys

from .cli import main

sys.exit(main())
