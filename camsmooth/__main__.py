"""``python -m camsmooth``: the command line."""

import sys

from camsmooth.cli.main import main

sys.exit(main())
