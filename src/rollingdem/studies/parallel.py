"""Run independent simulations side by side on Dask.

A runner is a context manager that yields a :class:`Mapper` (in order, or as the runs finish): in
this process, on a ``LocalCluster`` of cores // threads workers (the default), or on an existing
Dask cluster. docs/studies.md, "Running side by side"."""

from __future__ import annotations

import logging
import os
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Iterator

import numba

from rollingdem.errors import ParameterError

__all__ = ["Execution", "Mapper", "completed", "default_workers", "runner"]


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
        numba.set_num_threads(min(self.threads, numba.config.NUMBA_NUM_THREADS))
        return self.func(item)


class Mapper:
    """What :func:`runner` yields. ``mapper(func, items)``: results in the order of ``items``;
    ``mapper.as_completed(func, items)``: ``(index, result)`` pairs as the runs finish, where a run
    Dask itself could not finish (its worker died ``allowed-failures`` times, default 3) comes as
    ``(index, exception)``. A run whose worker dies once is rerun on another worker by the scheduler."""

    def __init__(self, client=None, threads: int = 1):
        self.client = client
        self.threads = threads

    @property
    def workers(self) -> int:
        """Worker processes the runs are spread over (1 without Dask)."""
        if self.client is None:
            return 1
        return max(1, len(self.client.scheduler_info().get("workers", {})))

    def __call__(self, func: Callable, items: Iterable[Any]) -> Iterator[Any]:
        task = _Task(func, self.threads)
        if self.client is None:
            return map(task, items)
        futures = self.client.map(task, list(items), pure=False)
        return (fut.result() for fut in futures)

    def as_completed(self, func: Callable, items: Iterable[Any]) -> Iterator[tuple[int, Any]]:
        task = _Task(func, self.threads)
        items = list(items)
        if self.client is None:
            for i, item in enumerate(items):
                yield i, task(item)
            return
        from dask.distributed import as_completed  # deferred: runs side by side only

        futures = self.client.map(task, items, pure=False)
        index = {fut.key: i for i, fut in enumerate(futures)}
        for fut in as_completed(futures):
            try:
                result = fut.result()
            except Exception as err:  # KilledWorker, a lost scheduler: the run did not finish
                result = err
            yield index[fut.key], result


def completed(mapper, func: Callable, items: Iterable[Any]) -> Iterator[tuple[int, Any]]:
    """``(index, result)`` as runs finish, for a :class:`Mapper` or any plain ``map``-like callable."""
    if hasattr(mapper, "as_completed"):
        return mapper.as_completed(func, items)
    return enumerate(mapper(func, list(items)))


def check_workers(workers: int | None, threads: int) -> None:
    """ParameterError unless ``workers`` (None: the default) and ``threads`` are integers >= 1."""
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ParameterError(f"workers = {workers!r} is not allowed: must be an integer >= 1")
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ParameterError(f"threads = {threads!r} is not allowed: must be an integer >= 1")


@contextmanager
def runner(workers: int | None = None, scheduler: str | None = None, threads: int = 1) -> Iterator[Mapper]:
    """Context manager yielding a :class:`Mapper` over Dask workers (or here, for one worker)."""
    check_workers(workers, threads)
    workers = workers or max(1, default_workers() // threads)  # fill the cores, no oversubscription
    if scheduler is None and workers == 1:
        yield Mapper(None, threads)
        return
    try:
        from dask.distributed import Client, LocalCluster  # deferred: runs side by side only
    except ImportError as err:  # pragma: no cover - dask is a dependency
        raise ParameterError("parallel runs need dask.distributed: pip install 'dask[distributed]'") from err
    cluster = None
    if scheduler is None:
        import dask  # deferred: runs side by side only

        # a worker that goes quiet for minutes (a laptop asleep, a stopped job) is not dead: the
        # default 5-minute time-to-live would restart its run from the beginning; a dead worker
        # process is seen by its nanny at once anyway
        with dask.config.set({"distributed.scheduler.worker-ttl": "2h"}):
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=":0", silence_logs=logging.ERROR)
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as err:
            raise ParameterError(f"scheduler = {scheduler!r}: no Dask scheduler answers there ({err})") from None
    try:
        yield Mapper(client, threads)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


@dataclass(frozen=True)
class Execution:
    """Where a study's runs go: the arguments of :func:`runner`. ``workers`` processes here (None:
    cores // ``threads``; 1 and no ``scheduler``: in this process), or the Dask cluster at
    ``scheduler`` (``"tcp://host:port"``); each run on ``threads`` Numba threads. Checked when the
    runner starts (:func:`check_workers`)."""

    workers: int | None = None
    scheduler: str | None = None
    threads: int = 1

    def runner(self):
        """:func:`runner` with these settings (a context manager yielding a :class:`Mapper`)."""
        return runner(self.workers, self.scheduler, self.threads)
