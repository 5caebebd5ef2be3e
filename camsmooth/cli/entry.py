"""The ``camsmooth`` command's entry (``python -m camsmooth`` and the installed script).

SIGINT and SIGTERM handlers are installed here before anything heavy is imported (numpy, numba's
cache, CasADi); a signal before, from camsmooth.__main__'s first statement on, was noted there
and ends the command here. So a signal at any moment from start-up to the final rename becomes one exception
in this process (camsmooth.io.atomic.install_signal_handlers), one message and exit status 130
(SIGINT) or 143 (SIGTERM). This module imports only the standard library and camsmooth.io.atomic.
``camsmooth --version`` is answered here, from the installed package's metadata, before the
command line's heavy imports.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Sequence

from camsmooth.io.atomic import Terminated, install_signal_handlers, signal_received

EXIT_SIGINT, EXIT_SIGTERM = 130, 143


def package_version() -> str:
    """The installed camsmooth's version (its package metadata, as pip installed it), or a note
    that it is not installed (run from a source tree)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("camsmooth")
    except PackageNotFoundError:
        return "unknown (not installed: pip install -e .)"


def version_line() -> str:
    """What ``camsmooth --version`` prints."""
    return f"camsmooth {package_version()}"


def interrupted(signum: int | None) -> int:
    """Print the one message of an interrupted command; return its exit status."""
    if signum == signal.SIGTERM:
        print("camsmooth: terminated (SIGTERM); outputs not completed were removed", file=sys.stderr)
        return EXIT_SIGTERM
    print("camsmooth: interrupted (Ctrl-C); outputs not completed were removed", file=sys.stderr)
    return EXIT_SIGINT


def signum_of(exc: BaseException) -> int:
    """The signal an interruption stands for (camsmooth.io.atomic.interruption)."""
    return signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT


def entry(argv: Sequence[str] | None = None, early: Sequence[int] = ()) -> int:
    """Install the signal handlers, then import and run the command line; after a signal, leave
    without the interpreter's finalisation (half-initialised extension state must not crash
    the exit). ``early``: the signals noted before (camsmooth.__main__), which end the command
    before it starts."""
    args = list(sys.argv[1:] if argv is None else argv)
    if [a for a in args if a != "--debug"] == ["--version"]:  # without importing the command line
        print(version_line())
        return 0
    install_signal_handlers()
    code: int | None = None
    try:
        if early:
            raise KeyboardInterrupt
        from camsmooth.cli.main import main

        code = main(argv)
    except KeyboardInterrupt as exc:  # during the imports (main() handles its own)
        code = interrupted(signal_received() or (early[0] if early else signum_of(exc)))
    # the command is over (its outputs committed or removed): a signal from here on is ignored;
    # left to the interpreter's finalisation (which resets Python's handlers to the default
    # action) it would kill the process with the outputs in place
    signal.setitimer(signal.ITIMER_REAL, 0)
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGALRM):
        signal.signal(sig, signal.SIG_IGN)
    if code not in (EXIT_SIGINT, EXIT_SIGTERM):
        return int(code or 0)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)
