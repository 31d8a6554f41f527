"""A dask cluster of separate processes for the engine tests: ``dask scheduler`` and ``dask worker`` started as
command-line processes on the loopback interface, as a user would start them on a cluster."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager


def _listening(port: int, proc: subprocess.Popen, timeout_s: float = 60.0) -> None:
    """Wait until something listens on ``port`` of the loopback interface (the scheduler ``proc`` started)."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1.0).close()
            return
        except OSError:
            if proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"the dask scheduler did not start on port {port}") from None
            time.sleep(0.05)


def free_port() -> int:
    """A TCP port nothing listens on now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextmanager
def dask_processes(env: Mapping[str, str], workers: int = 2) -> Iterator[tuple[str, list[subprocess.Popen]]]:
    """A scheduler and ``workers`` one-thread workers (no nanny, no dashboard): yields the scheduler's address and
    the processes (scheduler first), killed on exit."""
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    quiet = {"env": dict(env), "stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    # ``python -m dask``, not the ``dask`` command: a venv that is not activated has it off PATH (issue 34); the HTTP
    # server a scheduler keeps without its dashboard on a free port, not 8787 (another process may hold it)
    dask = [sys.executable, "-m", "dask"]
    scheduler = [*dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard",
                 "--dashboard-address", "127.0.0.1:0"]  # fmt: skip
    procs = [subprocess.Popen(scheduler, **quiet)]
    try:
        _listening(port, procs[0])
        for _ in range(workers):
            worker = [*dask, "worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard"]
            procs.append(subprocess.Popen(worker, **quiet))
        yield address, procs
    finally:
        for p in procs:
            p.kill()
            p.wait()
