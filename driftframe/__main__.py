"""``python -m driftframe``: the command line (see :mod:`driftframe.cli`)."""
import sys

from driftframe.cli import main

if __name__ == "__main__":
    sys.exit(main())
