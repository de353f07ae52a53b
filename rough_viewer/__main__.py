"""``python -m rough_viewer`` runs the command line."""

import sys

from rough_viewer.cli import main

sys.exit(main())
