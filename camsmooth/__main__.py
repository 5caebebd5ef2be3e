"""``python -m camsmooth``: the command line (signal handlers first: camsmooth.cli.entry)."""

import sys

from camsmooth.cli.entry import entry

if __name__ == "__main__":
    sys.exit(entry())
