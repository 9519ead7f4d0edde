"""``python -m prtbench ...``: the same entry point as the ``prtbench`` script."""

import sys

from prtbench.cli import main

if __name__ == "__main__":  # importing the module (package walks, docs) runs nothing
    sys.exit(main())
