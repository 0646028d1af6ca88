"""``python -m pathpref``: the ``pathpref`` command line (:mod:`pathpref.apps.cli`)."""

import sys

from .apps.cli import console_main

sys.exit(console_main())
