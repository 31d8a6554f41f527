"""Sweep engines (pyroute_rel.batch.sweep): on dask and in the local pool each member's runs go to one worker and its
weather is read there, in the task (not as tasks of the cluster); option combinations that would do nothing are
one-line errors; local engines start at most one process per CPU."""

from __future__ import annotations

import importlib.util
import json
import math
import os
import time
import warnings
from collections import defaultdict
from pathlib import Path

import pytest
from dask_processes import free_port
from hypothesis import given, settings
from hypothesis import strategies as st

from pyroute_rel.analysis.ensemble import route_ensemble
from pyroute_rel.batch.sweep import READS_METADATA, BatchQueue, Run, SweepError, place_batches, run_sweep, task_batches
from pyroute_rel.cli.main import main
from pyroute_rel.errors import PyrouteWarning, ScenarioError

ROOT = Path(__file__).resolve().parents[1]
#: Columns that differ between two runs of the same sweep: the time it took.
TIMING = ("runtime_s",)


@pytest.fixture(scope="module")
def ensemble(tmp_path_factory) -> Path:
    """A 3-member ensemble (2 deg, 12-hourly, 40 days) and its scenario on 12 ranks."""
    spec = importlib.util.spec_from_file_location("make_ensemble", ROOT / "benchmarks" / "make_ensemble.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    folder = tmp_path_factory.mktemp("ensemble")
    return module.write_ensemble(folder, n_ranks=12, members=3, step_deg=2.0, step_h=12, days=40)


def _runs(scenario: Path, members=(0, 1, 2)) -> list[Run]:
    deps = ("2018-06-02T00:00:00Z", "2018-06-03T00:00:00Z")
    return [Run(str(scenario), departure=d, member=m, apf=a) for m in members for a in (1.0, 0.02) for d in deps]


def _comparable(table) -> list[dict]:
    return sorted(({k: v for k, v in r.items() if k not in TIMING} for r in table.to_pylist()), key=lambda r: r["key"])


@pytest.mark.slow
def test_on_dask_each_member_runs_on_one_worker_and_reads_its_weather_in_the_task(ensemble) -> None:
    """A LocalCluster of 2 workers: the task stream holds only the sweep's tasks (the weather's dask chunks were
    once read as tasks of the cluster: tasks seceded and ran all at once on a one-thread worker), a worker runs one
    task at a time, every task of a member ran on one worker unless the scheduler stole it (its stealing events),
    both workers routed, and the table equals the inline engine's."""
    from distributed import Client, LocalCluster, get_task_stream

    from pyroute_rel.batch.sweep import WORKER_ENV

    runs = _runs(ensemble, members=(0, 1))
    inline = run_sweep(runs, engine="inline")
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0", env=dict(WORKER_ENV)
        ) as cluster,
        Client(cluster) as client,
    ):
        with get_task_stream(client) as stream:
            table = run_sweep(runs, engine="dask", scheduler=cluster.scheduler_address)
        stolen = {msg[1] for _, msg in client.get_events("stealing") if msg[0] == "confirm"}
    assert _comparable(table) == _comparable(inline)
    member = {r["key"]: r["member"] for r in table.to_pylist()}
    assert stream.data and all(str(t["key"]).startswith("pyroute-rel-runs-") for t in stream.data)
    workers, spans = defaultdict(set), defaultdict(list)
    for t in stream.data:
        first_run = str(t["key"]).split("-")[3]
        if t["key"] not in stolen:
            workers[member[first_run]].add(t["worker"])
        spans[t["worker"]] += [(s["start"], s["stop"]) for s in t["startstops"] if s["action"] == "compute"]
    assert all(len(w) == 1 for w in workers.values()), dict(workers)
    assert len(set().union(*workers.values())) == 2 or stolen  # the two members were shared out
    for intervals in spans.values():  # one task at a time: no task's middle falls in another task
        middles = [(a + b) / 2 for a, b in intervals]
        assert all(sum(a < m < b for a, b in intervals) == 1 for m in middles), intervals


def test_members_are_placed_whole_on_the_least_loaded_worker() -> None:
    """Against a brute force over every assignment of whole members to workers: the greedy placement (largest
    member first, LPT) is within its published bound of the best makespan (4/3 - 1/(3m) on m equal workers, Graham
    1969; 2m/(m + 1) on m workers of different speeds, Gonzalez, Ibarra and Sahni 1977: both <= 4/3 here), keeps
    every batch of a member on one worker and keeps the batches' order."""
    import itertools

    sizes = [7, 5, 5, 4, 3, 3, 2]  # runs per member
    todo = [(f"m{m}r{i}", Run("s.toml", member=m, apf=i / 10)) for m, n in enumerate(sizes) for i in range(n)]
    for threads in ({"a": 1, "b": 1}, {"a": 1, "b": 1, "c": 1}, {"a": 2, "b": 1}):
        batches = task_batches(todo, sum(threads.values()))
        placed = place_batches(batches, threads)
        assert [b for b, _ in placed] == batches
        where = {b[0][1].member: w for b, w in placed}
        assert all(w == where[b[0][1].member] for b, w in placed)  # a member on one worker
        load = defaultdict(int)
        for m, w in where.items():
            load[w] += sizes[m]
        got = max(load[w] / n for w, n in threads.items())
        best = min(
            max(sum(s for s, w in zip(sizes, assign, strict=True) if w == k) / n for k, n in threads.items())
            for assign in itertools.product(list(threads), repeat=len(sizes))
        )
        assert got <= best * 4 / 3, (threads, got, best)
    assert {w for _, w in place_batches(batches, {})} == {None}  # no worker yet: no restriction


@pytest.mark.parametrize(
    ("options", "named"),
    [
        (["--engine", "inline", "--workers", "2"], "--workers needs the processes, dask or auto engine"),
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:9"], "--workers starts a LocalCluster"),
        (["--batch", "4"], "--batch sets how often --out is written: it needs --out"),
        (["--connect-timeout", "3"], "--connect-timeout is how long to try reaching --scheduler"),
        (["--engine", "processes", "--scheduler", "tcp://127.0.0.1:9"], "--scheduler needs the dask engine"),
    ],
)
def test_options_that_would_do_nothing_are_one_line_errors(tmp_path, capsys, options, named) -> None:
    control = ROOT / "examples" / "microtransat_control.toml"
    assert main(["sweep", str(control), "--quiet", "--plot", str(tmp_path / "sweep.png"), *options]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and named in err, err
    assert not any(tmp_path.iterdir())  # nothing written


def test_the_library_refuses_the_same_combinations(ensemble) -> None:
    runs = _runs(ensemble)[:1]
    with pytest.raises(SweepError, match="--workers needs the processes, dask or auto engine"):
        run_sweep(runs, engine="inline", workers=2)
    with pytest.raises(SweepError, match="--workers starts a LocalCluster"):
        run_sweep(runs, engine="dask", workers=2, scheduler="tcp://127.0.0.1:9")


@pytest.mark.slow
def test_a_local_pool_starts_at_most_one_process_per_cpu(ensemble) -> None:
    """More workers than CPUs: one warning naming --workers and the CPUs, and the rows of the inline engine."""
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    runs = _runs(ensemble, members=(2,))
    with pytest.warns(PyrouteWarning, match=rf"--workers {cpus + 1} is more than the {cpus} CPUs") as caught:
        pooled = run_sweep(runs, engine="processes", workers=cpus + 1)
    assert len([w for w in caught if issubclass(w.category, PyrouteWarning)]) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _comparable(pooled) == _comparable(run_sweep(runs, engine="inline"))


# --- the local pool: each member's runs on one worker ----------------------------------------------------------


def _simulate(batches, workers: int, run_s: float, read_s: float):
    """The pool's dispatch (:class:`BatchQueue`) on ``workers`` workers, simulated: each worker asks for its next
    batch when it finishes one, a batch takes ``run_s`` per run plus ``read_s`` when its worker has not read that
    member before. Returns the makespan, the (worker, member) pairs read and the batches each worker ran, in order."""
    import heapq

    queue = BatchQueue(batches)
    free = [(0.0, w) for w in range(workers)]
    heapq.heapify(free)
    read, ran = set(), defaultdict(list)
    makespan = 0.0
    while free:
        t, w = heapq.heappop(free)
        i = queue.take(w)
        if i is None:
            makespan = max(makespan, t)
            continue
        member = batches[i][0][1].member
        t += run_s * len(batches[i]) + (read_s if (w, member) not in read else 0.0)
        read.add((w, member))
        ran[w].append(i)
        heapq.heappush(free, (t, w))
    return makespan, read, ran


def _best_makespan(batches, workers: int, run_s: float, read_s: float) -> float:
    """Brute force over every assignment of the batches to the workers: the least makespan, each worker paying
    ``read_s`` once per member it runs batches of."""
    import itertools

    best = math.inf
    for assign in itertools.product(range(workers), repeat=len(batches)):
        loads = [0.0] * workers
        members = [set() for _ in range(workers)]
        for b, w in zip(batches, assign, strict=True):
            loads[w] += run_s * len(b)
            members[w].add(b[0][1].member)
        best = min(best, max(load + read_s * len(m) for load, m in zip(loads, members, strict=True)))
    return best


def _member_runs(sizes) -> list:
    return [(f"m{m}r{i}", Run("s.toml", member=m, apf=i / 100)) for m, n in enumerate(sizes) for i in range(n)]


def test_the_pool_queue_keeps_members_whole_on_the_brief_s_cases() -> None:
    """10 members of 24 runs on 2 workers: 5 members each, each member read once, the makespan equal to the even
    split's (a closed form); 3 members of 24 on 2 workers: the third member shared (4 reads), the makespan equal to
    the brute-force optimum over every assignment of its 9 batches."""
    run_s, read_s = 0.5, 1.5  # the figures: a route about 0.45 s, opening the weather about 1.4 s
    batches = task_batches(_member_runs([24] * 10), 2)
    makespan, read, ran = _simulate(batches, 2, run_s, read_s)
    assert len(read) == 10 and sorted(i for w in ran.values() for i in w) == list(range(len(batches)))
    assert makespan == (240 * run_s + 10 * read_s) / 2
    batches = task_batches(_member_runs([24] * 3), 2)
    makespan, read, _ = _simulate(batches, 2, run_s, read_s)
    assert len(read) == 4
    assert makespan == _best_makespan(batches, 2, run_s, read_s)


@settings(max_examples=40, deadline=None)
@given(
    sizes=st.lists(st.integers(1, 24), min_size=1, max_size=4),
    read_s=st.sampled_from([0.0, 0.5, 1.5, 4.0]),
)
def test_the_pool_queue_hands_out_every_batch_once_and_stays_near_the_best(sizes, read_s) -> None:
    """On 2 workers: every batch runs once, a member's batches run in their order on the worker that started it
    (another takes only its last ones), at most one member is read by both workers, and the makespan is within
    ``read_s + largest batch / 2`` of the brute-force optimum (list scheduling: no worker idles while a batch
    waits; the optimum pays each member's read at least once)."""
    run_s = 1.0
    batches = task_batches(_member_runs(sizes), 2)
    makespan, read, ran = _simulate(batches, 2, run_s, read_s)
    assert sorted(i for w in ran.values() for i in w) == list(range(len(batches)))
    assert len(read) <= len(sizes) + 1
    for order in ran.values():
        for m in {batches[i][0][1].member for i in order}:
            mine = [i for i in order if batches[i][0][1].member == m]
            assert mine == sorted(mine) or mine == sorted(mine, reverse=True)
    largest = max(len(b) for b in batches) * run_s
    assert makespan <= _best_makespan(batches, 2, run_s, read_s) + read_s + largest / 2 + 1e-9


def test_a_batch_put_back_runs_next_on_its_worker() -> None:
    batches = task_batches(_member_runs([24, 24]), 2)
    queue = BatchQueue(batches)
    first = queue.take("w1")
    assert queue.take("w2") is not None
    queue.put_back(first)  # w1 died running it: its new process runs it again, first
    assert queue.take("w1") == first


@pytest.mark.slow
def test_a_local_pool_reads_each_member_in_one_worker(ensemble) -> None:
    """A pool of 2 processes, 3 members: the rows equal the inline engine's, and, counted in the workers (the
    weather cache's misses, in the table's metadata), each worker read a member's weather at most once, both
    worked, and only one member was read by both (the last one, shared out so that neither idles). The pool of
    session 9, where any idle worker took the next batch, read most members in both workers."""
    if (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()) < 2:
        pytest.skip("needs 2 CPUs")
    runs = _runs(ensemble)
    pooled = run_sweep(runs, engine="processes", workers=2)
    assert _comparable(pooled) == _comparable(run_sweep(runs, engine="inline"))
    reads = json.loads(pooled.schema.metadata[READS_METADATA.encode()])
    assert all(r["reads"] <= 1 for r in reads), reads
    pairs = [(r["worker"], r["member"]) for r in reads if r["reads"]]
    assert {m for _, m in pairs} == {0, 1, 2} and len({w for w, _ in pairs}) == 2
    assert len(pairs) <= 3 + 1, reads


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: run_sweep([], engine="gpu"), "engine must be one of auto, inline, processes, dask (got 'gpu')"),
        (
            lambda: run_sweep([], engine="auto", scheduler="tcp://127.0.0.1:9"),
            "--scheduler needs the dask engine (got engine 'auto')",
        ),
        (
            lambda: run_sweep([], engine="inline", workers=1),
            "--workers needs the processes, dask or auto engine (engine 'inline' routes in this process)",
        ),
        (
            lambda: route_ensemble("s.toml", engine="inline", workers=3),
            "--workers 3 needs the processes or dask engine (got engine 'inline')",
        ),
        (
            lambda: route_ensemble("s.toml", engine="dask", workers=2, scheduler="tcp://127.0.0.1:9"),
            "--workers sets a LocalCluster's processes: give it or --scheduler, not both",
        ),
    ],
)
def test_the_shared_engine_checks_keep_each_command_s_meaning_of_workers(call, message) -> None:
    """pyroute_rel.batch.cluster checks both commands' engine options: the sweep's ``--workers`` is a pool or a
    LocalCluster (never with ``inline``, even 1; ``--scheduler`` only with ``dask``), the ensemble's is its
    processes (``inline`` accepts 1; ``--scheduler`` with ``auto``); the messages are those of session 9, whole."""
    with pytest.raises(ScenarioError) as caught:
        call()
    assert str(caught.value) == message


def test_the_ensemble_accepts_one_worker_inline_and_a_scheduler_with_auto() -> None:
    from pyroute_rel.batch.cluster import WorkersOption, check_engine_combinations

    ensemble_meaning = WorkersOption(("auto", "dask"), "both", "{workers} inline", inline_allows=(1,))
    check_engine_combinations("inline", 1, None, ensemble_meaning)  # no error
    check_engine_combinations("auto", None, "tcp://127.0.0.1:9", ensemble_meaning)
    with pytest.raises(ScenarioError, match="^2 inline$"):
        check_engine_combinations("inline", 2, None, ensemble_meaning)


@pytest.mark.parametrize(
    ("address", "expected"),
    [
        ("garbage", "--scheduler must be a dask scheduler address tcp://HOST:PORT (got 'garbage')"),
        ("tls://127.0.0.1:9", "tls:// is not supported, only plain tcp://"),
        ("ucx://127.0.0.1:9", "ucx:// is not supported, only plain tcp://"),
        ("127.0.0.1:99999", "(got '127.0.0.1:99999')"),
        ("", "(got '')"),
    ],
)
def test_a_malformed_scheduler_address_is_refused_at_once(address, expected) -> None:
    """Issue 34: malformed addresses and tls:// or ucx:// schemes waited for the connect timeout and ended in a
    traceback (exit 3)."""
    from pyroute_rel.batch.cluster import check_scheduler_address
    from pyroute_rel.errors import ScenarioError

    t0 = time.perf_counter()
    with pytest.raises(ScenarioError) as info:
        check_scheduler_address(address)
    assert expected in str(info.value) and time.perf_counter() - t0 < 1.0


@pytest.mark.slow
def test_a_peer_that_accepts_and_stays_silent_is_an_error_within_the_timeout() -> None:
    """Issue 34: an address that accepts and never answers (an HTTP server waiting for its request) hung the sweep."""
    import socket
    import threading

    from pyroute_rel.batch.sweep import SweepError

    server = socket.create_server(("127.0.0.1", 0))
    held: list[socket.socket] = []
    threading.Thread(target=lambda: held.append(server.accept()[0]), daemon=True).start()
    port = server.getsockname()[1]
    runs = [Run(str(ROOT / "examples" / "microtransat_control.toml"))]
    t0 = time.perf_counter()
    try:
        with pytest.raises(SweepError, match=r"no dask scheduler answers there within 1 s"):
            run_sweep(runs, engine="dask", scheduler=f"tcp://127.0.0.1:{port}", connect_timeout_s=1.0)
    finally:
        for s in (*held, server):
            s.close()
    assert time.perf_counter() - t0 < 5.0


def test_a_scheduler_that_starts_listening_late_is_reached_within_the_timeout() -> None:
    """``--connect-timeout`` is how long to try reaching the scheduler: a refused connection is tried again until
    then (a scheduler started beside the command may not listen yet; the tests' own clusters met this), and a port
    that stays closed is one line after that time, not at once."""
    import socket
    import threading

    from pyroute_rel.batch.cluster import _answers

    port = free_port()
    greeted: list[bool] = []

    def late_greeter() -> None:
        time.sleep(0.5)
        with socket.create_server(("127.0.0.1", port)) as server:
            peer, _ = server.accept()
            with peer:
                peer.sendall(b"\0")  # a dask scheduler greets a new connection at once
                greeted.append(True)

    thread = threading.Thread(target=late_greeter, daemon=True)
    thread.start()
    t0 = time.perf_counter()
    _answers(f"tcp://127.0.0.1:{port}", 10.0, SweepError)
    assert 0.4 < time.perf_counter() - t0 < 5.0
    thread.join(5.0)
    assert greeted == [True]
    closed = free_port()
    t0 = time.perf_counter()
    with pytest.raises(SweepError, match=rf"tcp://127.0.0.1:{closed}: cannot reach the dask scheduler within 0.5 s"):
        _answers(f"tcp://127.0.0.1:{closed}", 0.5, SweepError)
    assert 0.4 < time.perf_counter() - t0 < 3.0
