"""``python -m stand`` is the ``stand`` command line."""

import sys

from stand.cli import main

sys.exit(main())
