"""The dask.distributed clusters the sweep and the ensemble run on: a client of a running scheduler's cluster
(``tcp://HOST:PORT``), or of a ``LocalCluster`` started for the call, whose worker processes run one thread each
(:data:`WORKER_ENV`), and the environment every worker process of the product runs with; the weather read in a
task without the cluster's help (:func:`synchronous_reads`); the checks of the engine options both commands share
(:func:`check_engine_name`, :func:`check_engine_combinations`, each command saying what its ``--workers`` means
with a :class:`WorkersOption`).
"""

from __future__ import annotations

import logging
import re
import socket
import time
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from pyroute_rel.errors import ScenarioError, brief

__all__ = [
    "WORKER_ENV",
    "dask_client",
    "check_scheduler_address",
    "close_client",
    "scheduler_lost",
    "watching_scheduler",
    "synchronous_reads",
    "WorkersOption",
    "check_engine_name",
    "check_engine_combinations",
]

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
    scheduler = check_scheduler_address(scheduler, error)
    _answers(scheduler, timeout_s, error)
    try:
        client = Client(scheduler, timeout=f"{timeout_s}s", set_as_default=False)
    except MemoryError:  # (a frame length read from another protocol's bytes, e.g. an HTTP server's answer)
        raise error(f"--scheduler {scheduler}: what answers there is not a dask scheduler") from None
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


#: A scheduler address: ``tcp://HOST:PORT`` or ``HOST:PORT`` (an IPv6 host in brackets).
_ADDRESS = re.compile(r"(?:tcp://)?(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+):([0-9]{1,5})")


def check_scheduler_address(scheduler: Any, error: type[Exception] = ScenarioError) -> str:
    """``scheduler`` as a dask scheduler address over plain TCP (``tcp://HOST:PORT``), or ``error`` at once: a
    malformed address used to wait for the full connect timeout and end in a traceback, and ``tls://`` or ``ucx://``
    need a security or transport setup pyroute-rel does not make (issue 34). The scheduler must be trusted: dask's
    protocol unpickles what it sends.

    >>> check_scheduler_address("127.0.0.1:8786"), check_scheduler_address("tcp://node7:8786")
    ('tcp://127.0.0.1:8786', 'tcp://node7:8786')
    """
    text = scheduler.strip() if isinstance(scheduler, str) else None
    m = _ADDRESS.fullmatch(text) if text else None
    if text is None or m is None or not 0 < int(m.group(1)) < 65536:
        scheme = text.split("://", 1)[0] if text and "://" in text else None
        hint = f": {scheme}:// is not supported, only plain tcp://" if scheme and scheme != "tcp" else ""
        raise error(f"--scheduler must be a dask scheduler address tcp://HOST:PORT (got {brief(scheduler)}){hint}")
    return text if text.startswith("tcp://") else f"tcp://{text}"


def _answers(scheduler: str, timeout_s: float, error: type[Exception]) -> None:
    """Connect to ``tcp://HOST:PORT`` and wait for its first bytes, within ``timeout_s`` [s] in all: a dask scheduler
    greets a new connection at once; a peer that accepts and stays silent (an HTTP server waits for a request) is an
    error within the timeout, where dask's client would wait for ever (issue 34). A refused connection is tried again
    until then, as dask's client does (a scheduler started beside the command may not listen yet)."""
    host, _, port = scheduler.removeprefix("tcp://").rpartition(":")
    deadline = time.monotonic() + timeout_s
    while True:
        left = max(deadline - time.monotonic(), 0.01)
        try:
            with socket.create_connection((host.strip("[]"), int(port)), timeout=left) as sock:
                sock.settimeout(max(deadline - time.monotonic(), 0.01))
                if not sock.recv(1):
                    raise ConnectionError("it closed the connection")
            return
        except ConnectionRefusedError as exc:
            if time.monotonic() + 0.1 >= deadline:
                raise error(
                    f"--scheduler {scheduler}: cannot reach the dask scheduler within {timeout_s:g} s "
                    f"({exc.strerror or exc})"
                ) from None
            time.sleep(0.1)
        except TimeoutError:
            raise error(
                f"--scheduler {scheduler}: no dask scheduler answers there within {timeout_s:g} s (something accepts "
                "the connection but says nothing, or nothing answers at all; a dask scheduler greets at once)"
            ) from None
        except OSError as exc:
            raise error(f"--scheduler {scheduler}: cannot reach the dask scheduler ({exc.strerror or exc})") from None


def close_client(client: Any) -> None:
    """Close a client of :func:`dask_client` and, when it started one, its ``LocalCluster``."""
    cluster = client.cluster
    client.close()
    if cluster is not None:
        cluster.close()


def scheduler_lost(client: Any, exc: BaseException) -> bool:
    """Whether ``exc``, raised by a future of ``client``, says the client lost its scheduler (the scheduler died or
    its machine went away): distributed cancels every pending future then, with the reason
    ``scheduler-connection-lost``, and the client stops running."""
    return client.status != "running" or "scheduler-connection-lost" in str(exc)


@contextmanager
def watching_scheduler(client: Any, error: type[Exception], what: str) -> Iterator[None]:
    """Inside the block, a scheduler that dies (:func:`scheduler_lost`) is ``error`` in one line saying ``what`` was
    kept, not distributed's traceback: its client's reconnection errors are not logged (the line says what happened)
    and a future cancelled by the loss ends the block. Other errors pass through as they are."""
    address = getattr(client.scheduler, "address", None)
    log = logging.getLogger("distributed.client")
    level = log.level
    log.setLevel(logging.CRITICAL)
    try:
        yield
    except Exception as exc:
        if not scheduler_lost(client, exc):
            raise
        raise error(f"the dask scheduler{f' {address}' if address else ''} went away mid-run: {what}") from None
    finally:
        log.setLevel(level)


@contextmanager
def synchronous_reads() -> Iterator[None]:
    """Inside the block, dask arrays (a weather file's) are computed by dask's synchronous scheduler, in this
    thread. In a dask worker the default would be the cluster itself: a task waiting there for its weather's chunks
    secedes from the worker's thread, so that the worker starts its next task, and the next, all at once.

    >>> import dask
    >>> with synchronous_reads():
    ...     dask.config.get("scheduler")
    'synchronous'
    """
    import dask

    with dask.config.set(scheduler="synchronous"):
        yield


@dataclass(frozen=True)
class WorkersOption:
    """What a command's ``--workers`` means, as its option errors say it (:func:`check_engine_combinations`).

    Attributes
    ----------
    scheduler_engines : The engines ``--scheduler`` goes with.
    with_scheduler : The error for ``--workers`` with ``--scheduler``.
    with_inline : The error for ``--workers`` with the engine ``"inline"`` (``{workers}``: the value given).
    inline_allows : Values of ``--workers`` the engine ``"inline"`` accepts (1: this process alone).
    """

    scheduler_engines: tuple[str, ...]
    with_scheduler: str
    with_inline: str
    inline_allows: tuple[int, ...] = ()


def check_engine_name(engine: Any, engines: Sequence[str], error: type[Exception] = ScenarioError) -> str:
    """``engine`` if it is one of ``engines``, else ``error`` naming them.

    >>> check_engine_name("dask", ("inline", "dask"))
    'dask'
    """
    if not isinstance(engine, str) or engine not in engines:
        raise error(f"engine must be one of {', '.join(engines)} (got {brief(engine)})")
    return engine


def check_engine_combinations(
    engine: str, workers: Any, scheduler: Any, option: WorkersOption, error: type[Exception] = ScenarioError
) -> None:
    """The combinations of ``engine``, ``--workers`` and ``--scheduler`` that would do nothing, refused (in this
    order): ``--scheduler`` without one of ``option.scheduler_engines``, ``--workers`` with the engine
    ``"inline"`` (but for ``option.inline_allows``), ``--workers`` with ``--scheduler``.

    Raises
    ------
    error
        The first of these, in one line.
    """
    if scheduler is not None and engine not in option.scheduler_engines:
        raise error(f"--scheduler needs the dask engine (got engine {engine!r})")
    if engine == "inline" and workers is not None and workers not in option.inline_allows:
        raise error(option.with_inline.format(workers=workers))
    if workers is not None and scheduler is not None:
        raise error(option.with_scheduler)
