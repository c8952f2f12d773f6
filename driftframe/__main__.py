"""``python -m driftframe``: the command line (see :mod:`driftframe.cli`)."""
import sys

from driftframe.cli import main

sys.exit(main())
