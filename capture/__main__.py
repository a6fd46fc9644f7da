"""``python -m capture`` runs the ``aerostereo-ingest`` command line."""

import sys

from capture.cli import main

sys.exit(main())
