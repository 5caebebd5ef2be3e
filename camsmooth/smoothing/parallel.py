"""Independent rows on all cores, or on a Dask cluster, with the results of a serial run.

``RowPool(ctx).map(fn, tasks)`` returns ``[fn(ctx, task) for task in tasks]``, in order. ``fn``
must be a pure function of its arguments (camsmooth.smoothing.rows.solve_row is), so where it runs
cannot change what it returns; the shared context is sent to each worker once, not with every
task. Backends:

- serial (``workers=1``);
- processes on this machine (``workers > 1``; a forkserver pool, so the workers never inherit a
  parent's threads mid-flight). The fork server and the workers ignore SIGINT from their first
  instruction (a Ctrl-C reaches the whole process group): the parent decides, and terminates
  them when it is interrupted or fails;
- Dask (``dask="local"`` for a LocalCluster of ``workers`` single-threaded processes, or a
  scheduler address such as ``"tcp://10.0.0.5:8786"``). Dask is an optional extra:
  ``pip install camsmooth[dask]``.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

from camsmooth.errors import InputError

__all__ = ["RowPool", "default_workers"]

C = TypeVar("C")
T = TypeVar("T")
R = TypeVar("R")

_SHARED: dict[str, Any] = {}  # the context a pool worker received at start-up (one per process)


def default_workers() -> int:
    """All cores of this machine (os.process_cpu_count where available)."""
    count = getattr(os, "process_cpu_count", os.cpu_count)()
    return max(1, int(count or 1))


def _init(ctx: Any) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides (module docstring)
    _SHARED["ctx"] = ctx


def _start_forkserver(mpc: Any, preload: list[str]) -> None:
    """Start the fork server (if not running) with SIGINT ignored, a disposition it and every
    worker it forks inherit, so a Ctrl-C to the process group never interrupts them half-way
    (importing the preload, unpickling a task). SIGINT is held meanwhile, so one arriving
    now reaches this process's own handler afterwards."""
    from multiprocessing import forkserver

    mpc.set_forkserver_preload(preload)
    if threading.current_thread() is not threading.main_thread():
        forkserver.ensure_running()
        return
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, (signal.SIGINT,))
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        forkserver.ensure_running()
    finally:
        signal.signal(signal.SIGINT, old if old is not None else signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def _call(fn: Callable[[Any, Any], Any], task: Any) -> Any:
    return fn(_SHARED["ctx"], task)


def _progress(it: Any, total: int, desc: str | None) -> Any:
    if desc is None:
        return it
    from tqdm import tqdm

    return tqdm(it, total=total, desc=desc, unit="row")


class RowPool:
    """A backend (module docstring) holding one shared context; ``map(fn, tasks)`` returns
    ``[fn(ctx, t) for t in tasks]`` in order. Use as a context manager: workers start at the first
    parallel map and stop on exit."""

    def __init__(self, ctx: Any, *, workers: int = 1, dask: str | None = None) -> None:
        if workers < 1:
            raise InputError(f"workers must be >= 1, got {workers}")
        self.ctx, self.workers, self.dask = ctx, int(workers), dask
        self._pool: ProcessPoolExecutor | None = None
        self._client: Any = None
        self._cluster: Any = None
        self._shared: Any = None

    @property
    def parallel(self) -> bool:
        return self.dask is not None or self.workers > 1

    def __enter__(self) -> RowPool:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *exc: object) -> None:
        self.close(abort=exc_type is not None)

    def close(self, abort: bool = False) -> None:
        """Stop the workers: after the running tasks end, or at once when ``abort`` (an error or
        an interruption: nothing they compute is wanted)."""
        if self._pool is not None:
            if abort:
                for proc in list(getattr(self._pool, "_processes", {}).values()):
                    if proc.is_alive():
                        proc.terminate()
            self._pool.shutdown(cancel_futures=True)
            self._pool = None
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def map(self, fn: Callable[[C, T], R], tasks: Sequence[T], progress: str | None = None) -> list[R]:
        if self.dask is not None:
            return self._map_dask(fn, tasks, progress)
        if not self.parallel or len(tasks) <= 1:
            return [fn(self.ctx, t) for t in _progress(tasks, len(tasks), progress)]
        if self._pool is None:
            mpc = mp.get_context("forkserver")
            _start_forkserver(mpc, ["camsmooth.smoothing.rows"])
            self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=mpc, initializer=_init,
                                             initargs=(self.ctx,))
        futures = [self._pool.submit(_call, fn, t) for t in tasks]
        if progress is not None:
            from concurrent.futures import as_completed

            for f in _progress(as_completed(futures), len(futures), progress):
                if f.exception() is not None:  # the first failure ends the map (the rest is not wanted)
                    for g in futures:
                        g.cancel()
                    f.result()
        return [f.result() for f in futures]

    def _map_dask(self, fn: Callable[[C, T], R], tasks: Sequence[T], progress: str | None) -> list[R]:
        if self._client is None:
            try:
                from dask.distributed import Client, LocalCluster
            except ImportError:
                raise InputError("Dask is not installed: pip install 'camsmooth[dask]'") from None
            if self.dask == "local":
                self._cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                             dashboard_address=None)
                self._client = Client(self._cluster)
            else:
                try:
                    self._client = Client(self.dask, timeout=30)
                except OSError as exc:
                    raise InputError(f"cannot reach the Dask scheduler at {self.dask!r}: {exc}") from None
            self._shared = self._client.scatter(self.ctx, broadcast=True)
        futures = self._client.map(fn, [self._shared] * len(tasks), list(tasks), pure=False)
        if progress is not None:
            from dask.distributed import as_completed

            for _ in _progress(as_completed(futures), len(futures), progress):
                pass
        return self._client.gather(futures)
