"""``python -m flightplan`` runs ``aerostereo-mission``."""

import sys

from flightplan.cli import main

sys.exit(main())
