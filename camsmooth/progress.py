"""Progress on stderr for the steps of a command that can take more than a few seconds.

``Steps`` shows one tqdm line, 'camsmooth: 2/5 spline [00:14]', naming the step being run and
its elapsed time, refreshed every REFRESH_S while a step runs (a step gives no progress of its
own: the line shows it is alive and where). It is shown only when asked for (the commands ask
unless --quiet) and stderr is a terminal: a log or a pipe gets nothing from it, so a command's
stderr there stays its messages. The NLP's row bar (camsmooth.smoothing.parallel) is the one
progress output that also goes to a pipe: it is the long step, its rate is information in a log,
and the tests that interrupt a run wait for it.
"""

from __future__ import annotations

import contextlib
import shutil
import sys
import threading
from collections.abc import Iterator
from typing import Any

__all__ = ["REFRESH_S", "Steps", "shown"]

#: seconds between refreshes of the elapsed time of a running step
REFRESH_S = 0.5


def shown(enabled: bool, stream: Any = None) -> bool:
    """Whether progress is shown: asked for (``enabled``) and the stream (default stderr) is a
    terminal."""
    stream = sys.stderr if stream is None else stream
    try:
        return bool(enabled) and stream.isatty()
    except (AttributeError, ValueError):  # no isatty, or closed
        return False


class Steps:
    """A progress line through ``total`` named steps (module docstring); a no-op when not
    ``shown``. Use ``with steps.step(name): ...`` for each step and ``close()`` (or the object
    as a context manager) at the end."""

    def __init__(self, total: int, *, enabled: bool = True, desc: str = "camsmooth", stream: Any = None) -> None:
        self._bar = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        if not shown(enabled, stream):
            return
        from tqdm import tqdm

        self._desc, self._total, self._done = desc, int(total), 0
        # a terminal that reports no size (0 columns) would get an empty line from tqdm
        self._bar = tqdm(total=total, desc=desc, file=sys.stderr if stream is None else stream, leave=False,
                         bar_format="{desc} [{elapsed}]", ncols=shutil.get_terminal_size((100, 24)).columns)

    @property
    def active(self) -> bool:
        """True when the line is shown."""
        return self._bar is not None

    def _refresh(self) -> None:
        while not self._stop.wait(REFRESH_S):
            bar = self._bar
            if bar is None:
                return
            bar.refresh()

    @contextlib.contextmanager
    def step(self, name: str) -> Iterator[None]:
        """Run one step named ``name``: shown while it runs, counted when it ends."""
        bar = self._bar
        if bar is None:
            yield
            return
        bar.set_description_str(f"{self._desc}: {self._done + 1}/{self._total} {name}", refresh=True)
        self._stop.clear()
        self._thread = threading.Thread(target=self._refresh, name="camsmooth-progress", daemon=True)
        self._thread.start()
        try:
            yield
        except BaseException:
            self.close()  # the error's message then starts a clean line
            raise
        finally:
            self._stop.set()
            if self._thread is not None:
                self._thread.join()
                self._thread = None
            if self._bar is not None:
                self._done += 1
                bar.update(1)

    def close(self) -> None:
        """Remove the line (``leave=False``)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Steps:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
