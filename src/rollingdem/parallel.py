"""Run independent simulations side by side on Dask.

A runner is a context manager that yields ``map(func, items)``: an iterator over ``func(item)`` in
the order of ``items``. Each simulation is single-threaded in its worker (Numba threads per task
are set to ``threads``), so ``workers`` x ``threads`` should not exceed the cores: a run of a few
thousand spheres gains little from a second thread, and two runs side by side use both cores fully.

* ``workers=1`` and no scheduler: plain in-process ``map``, no Dask (tests, debugging).
* default: a ``dask.distributed.LocalCluster`` of one process per core.
* ``scheduler="tcp://host:port"``: an existing Dask cluster (dask-jobqueue, Kubernetes, ...).
"""

from __future__ import annotations

import logging
import os
from contextlib import contextmanager
from typing import Any, Callable, Iterable, Iterator

from .errors import ParameterError

__all__ = ["default_workers", "runner"]


def default_workers() -> int:
    """One worker per core this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


class _Task:
    """func(item) with Numba limited to ``threads`` threads in the worker (picklable)."""

    def __init__(self, func: Callable, threads: int):
        self.func = func
        self.threads = threads

    def __call__(self, item):
        import numba

        numba.set_num_threads(min(self.threads, numba.config.NUMBA_NUM_THREADS))
        return self.func(item)


@contextmanager
def runner(workers: int | None = None, scheduler: str | None = None, threads: int = 1) -> Iterator[Callable]:
    """Context manager yielding ``map(func, items)`` (results in input order) over Dask workers."""
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ParameterError(f"workers = {workers!r} is not allowed: must be an integer >= 1")
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ParameterError(f"threads = {threads!r} is not allowed: must be an integer >= 1")
    if scheduler is None and (workers or default_workers()) == 1:
        def serial(func: Callable, items: Iterable[Any]):
            return map(_Task(func, threads), items)
        yield serial
        return
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError as err:  # pragma: no cover - dask is a dependency
        raise ParameterError("parallel runs need dask.distributed: pip install 'dask[distributed]'") from err
    cluster = None
    if scheduler is None:
        cluster = LocalCluster(n_workers=workers or default_workers(), threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.ERROR)
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as err:
            raise ParameterError(f"scheduler = {scheduler!r}: no Dask scheduler answers there ({err})") from None

    def dask_map(func: Callable, items: Iterable[Any]):
        futures = client.map(_Task(func, threads), list(items), pure=False)
        for fut in futures:
            yield fut.result()

    try:
        yield dask_map
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
