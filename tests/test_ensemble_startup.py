"""The ensemble's local worker processes start without holding up the caller (issue 19's benchmark): the fork server
imports what routing needs while the caller counts the members, and the processes are forked at the first task.
Before session 11, creating the workers forked them at once, so the caller waited for the server's imports (about
2 s) before it even counted the members."""

from __future__ import annotations

import multiprocessing
import os

import pytest

from pyroute_rel.analysis.ensemble import _Workers


def _pid() -> int:
    return os.getpid()


@pytest.mark.slow  # the fork server's imports, when no earlier test started it
def test_workers_fork_at_the_first_task_not_when_created():
    """Right after the workers are created no worker process exists (the old code had forked both); the first
    task forks its worker, a child of this process."""
    before = {p.pid for p in multiprocessing.active_children()}
    pool = _Workers(2)
    try:
        assert {p.pid for p in multiprocessing.active_children()} == before  # nothing forked yet
        pids = pool.each([(), ()], _pid)
        assert len(set(pids)) == 2 and os.getpid() not in pids
        assert {p.pid for p in multiprocessing.active_children()} - before == set(pids)
    finally:
        pool.close()
