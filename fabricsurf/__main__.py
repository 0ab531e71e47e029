"""``python -m fabricsurf``: the command line (:mod:`fabricsurf.cli`)."""

import sys

from fabricsurf.cli import main

sys.exit(main())
