"""The ``camsmooth`` command (``python -m camsmooth`` and the installed script, ``main``).

Importing this module means "this process is the camsmooth command": its first statements catch
SIGINT and SIGTERM, before anything else of camsmooth is imported, and only note them; the
command's entry (camsmooth.cli.entry) then installs the handlers that raise, and a signal noted
before that ends the command at once with its one message (exit 130 / 143). Before this module
runs, the interpreter's own start-up (about 40 ms here) is Python's, as for any Python program.
"""

import signal
import sys

#: SIGINT / SIGTERM received before camsmooth.cli.entry took over, in order
EARLY_SIGNALS: list[int] = []


def _note(signum: int, frame: object) -> None:
    EARLY_SIGNALS.append(signum)


signal.signal(signal.SIGINT, _note)
signal.signal(signal.SIGTERM, _note)


def main() -> int:
    """Run the command line on ``sys.argv``; its exit status."""
    from camsmooth.cli.entry import entry

    return entry(early=EARLY_SIGNALS)


if __name__ == "__main__":
    sys.exit(main())
