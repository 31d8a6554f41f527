"""Ensemble members on a dask.distributed cluster: the engine of ``pyroute-rel ensemble --scheduler`` and
``--engine dask``.

:func:`~pyroute_rel.analysis.ensemble.route_ensemble` runs two kinds of task: routing one member (each task sent to the
next free worker), then sailing every candidate route in the members a worker routed, on that worker (which keeps their
weather). :class:`DaskWorkers` runs them on a cluster: a running scheduler's (``tcp://HOST:PORT``, e.g. ``dask
scheduler`` and ``dask worker`` processes, one thread each), or a ``LocalCluster`` of worker processes, one thread each,
started for the call (:func:`dask_client`, with the environment of a sweep's workers,
:data:`pyroute_rel.batch.cluster.WORKER_ENV`).

A worker keeps each member's weather it read in its process from the member's routing to its sailing, as the local
processes do; the weather is dropped on every worker when the call ends (and when the next call starts: a worker
routing for two calls at once only reads some members twice). A sailing task goes to the worker holding its
members; it may run elsewhere (the members' weather is then read there) if that worker has left the cluster. The
results do not depend on where a task runs: they equal the local engine's.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from typing import Any

from pyroute_rel.batch.cluster import close_client, dask_client, synchronous_reads, watching_scheduler
from pyroute_rel.errors import ScenarioError

__all__ = ["dask_client", "DaskWorkers"]


def _located(fn: Callable[..., Any], *args: Any) -> tuple[Any, str]:
    """``fn(*args)`` on a dask worker (:func:`_synchronous`), with the worker's address."""
    from distributed import get_worker

    return _synchronous(fn, *args), str(get_worker().address)


def _synchronous(fn: Callable[..., Any], *args: Any) -> Any:
    """``fn(*args)`` with the weather files' dask arrays read by dask's synchronous scheduler, in this thread: in a
    dask worker the default would be the cluster itself (:func:`pyroute_rel.batch.cluster.synchronous_reads`)."""
    with synchronous_reads():
        return fn(*args)


def _prepare_worker(setup: Callable[[], Any]) -> None:
    """One thread in this worker process (:data:`pyroute_rel.batch.cluster.WORKER_ENV`, for a ``dask worker`` started
    without it), then ``setup()``."""
    from pyroute_rel.batch.cluster import WORKER_ENV

    os.environ.update(WORKER_ENV)
    setup()


class DaskWorkers:
    """The workers of a dask cluster, as :func:`~pyroute_rel.analysis.ensemble.route_ensemble` uses its processes: tasks
    sent to the next free worker (:meth:`balanced`), then one task on each worker that ran some (:meth:`each`).

    Parameters
    ----------
    client : A client of the cluster (:func:`dask_client`); closed by :meth:`close`.
    setup : Run on every worker first (clears what the workers keep for a call).
    teardown : Run on every worker last (drops what they kept; default ``setup``).
    """

    def __init__(self, client: Any, setup: Callable[[], Any], teardown: Callable[[], Any] | None = None) -> None:
        self.client = client
        self.setup = setup
        self.teardown = setup if teardown is None else teardown
        self.addresses: list[str] = sorted(client.scheduler_info().get("workers", {}))
        client.run(_prepare_worker, setup)

    @property
    def size(self) -> int:
        """Workers known: the cluster's at the start, and any that ran a task since."""
        return max(len(self.addresses), 1)

    def _index(self, address: str) -> int:
        if address not in self.addresses:
            self.addresses.append(address)
        return self.addresses.index(address)

    def balanced(
        self, tasks: Sequence[tuple[Any, ...]], fn: Callable[..., Any], bar: Any
    ) -> tuple[list[Any], list[int]]:
        """``[fn(*t) for t in tasks]``, each task run by the next free worker (the first task first), with the
        index of the worker each ran on."""
        from distributed import as_completed

        futures = {
            self.client.submit(_located, fn, *t, pure=False, priority=len(tasks) - i): i for i, t in enumerate(tasks)
        }
        results: list[Any] = [None] * len(tasks)
        where = [0] * len(tasks)
        with self._watched():
            for f in as_completed(futures, loop=self.client.loop):
                i = futures[f]
                results[i], address = f.result()
                where[i] = self._index(address)
                bar.update(1)
        return results, where

    def each(self, tasks: Sequence[tuple[Any, ...] | None], fn: Callable[..., Any]) -> list[Any]:
        """``fn(*tasks[w])`` on worker ``w`` (None: nothing there), all at once; on another worker if ``w`` has
        left the cluster."""
        futures = [
            None
            if t is None
            else self.client.submit(
                _synchronous, fn, *t, pure=False, workers=[self.addresses[w]], allow_other_workers=True
            )
            for w, t in enumerate(tasks)
        ]
        with self._watched():
            return [None if f is None else f.result() for f in futures]

    def _watched(self) -> AbstractContextManager[None]:
        """A scheduler lost mid-call is one line (exit 2), not distributed's traceback
        (:func:`~pyroute_rel.batch.cluster.watching_scheduler`)."""
        return watching_scheduler(self.client, ScenarioError, "nothing was written; start a scheduler and run again")

    def close(self) -> None:
        """Drop what the workers keep (``teardown``), then close the client (and its ``LocalCluster``)."""
        if self.client.status != "running":  # its scheduler went away (said by the call that found it)
            with contextlib.suppress(Exception), self._watched():
                close_client(self.client)
            return
        try:
            self.client.run(self.teardown)
        except Exception:  # noqa: BLE001 - a worker gone or the cluster closing: nothing left to drop there
            pass
        close_client(self.client)
