"""The dask.distributed clusters the sweep and the ensemble run on: a client of a running scheduler's cluster
(``tcp://HOST:PORT``), or of a ``LocalCluster`` started for the call, whose worker processes run one thread each
(:data:`WORKER_ENV`), and the environment every worker process of the product runs with.
"""

from __future__ import annotations

import logging
import warnings
from typing import Any

from .errors import ScenarioError

__all__ = ["WORKER_ENV", "dask_client", "close_client"]

#: Environment of worker processes (a process pool, a dask ``LocalCluster``): one thread each, also in the BLAS,
#: OpenMP and numba thread pools, since the workers already use every core.
WORKER_ENV = {
    "PYROUTE_REL_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1",
}


def dask_client(
    scheduler: str | None = None,
    *,
    workers: int | None = None,
    timeout_s: float = 10.0,
    error: type[Exception] = ScenarioError,
) -> Any:
    """A :class:`distributed.Client` of ``scheduler``'s cluster (``tcp://HOST:PORT``), or of a new
    ``LocalCluster`` of ``workers`` processes (default 1), one thread each, with
    :data:`WORKER_ENV`; closing the client (:func:`close_client`) closes that cluster.

    Raises
    ------
    error
        One line: distributed is not installed, the scheduler cannot be reached in ``timeout_s`` [s], or it has no
        worker after that time.
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:  # pragma: no cover - a dependency
        raise error(f"the dask engine needs distributed: pip install distributed ({exc})") from None
    if scheduler is None:
        with warnings.catch_warnings():  # without a dashboard the scheduler still serves /metrics, by default on 8787
            warnings.filterwarnings("ignore", message="Port .* is already in use", category=UserWarning)
            cluster = LocalCluster(
                n_workers=workers or 1,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                env=dict(WORKER_ENV),
                silence_logs=logging.ERROR,  # not the nannies' warnings when the cluster closes
            )
        return Client(cluster, set_as_default=False)
    try:
        client = Client(scheduler, timeout=f"{timeout_s}s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise error(
            f"--scheduler {scheduler}: cannot reach the dask scheduler ({' '.join(str(exc).split())})"
        ) from None
    try:
        client.wait_for_workers(1, timeout=timeout_s)
    except (OSError, TimeoutError) as exc:
        client.close()
        raise error(
            f"--scheduler {scheduler}: the dask scheduler has no worker after {timeout_s:g} s ({exc})"
        ) from None
    return client


def close_client(client: Any) -> None:
    """Close a client of :func:`dask_client` and, when it started one, its ``LocalCluster``."""
    cluster = client.cluster
    client.close()
    if cluster is not None:
        cluster.close()
