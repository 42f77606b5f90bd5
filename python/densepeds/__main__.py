"""``python -m densepeds``: see densepeds.cli."""

import sys

from densepeds.cli import main

sys.exit(main())
