"""``python -m sim``: the ``aerostereo-render`` command line."""

import sys

from sim.cli import main

sys.exit(main())
