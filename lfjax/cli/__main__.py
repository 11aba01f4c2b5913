"""``python -m lfjax.cli``: the ``lfjax`` command line."""

import sys

from lfjax.cli import main

if __name__ == "__main__":  # importing the module (as a walk over the package does) runs nothing
    sys.exit(main())
