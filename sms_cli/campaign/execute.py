"""Runs of a campaign on Dask distributed: submitted at once, collected as they complete.

``connect`` gives a :class:`Pool` (a local cluster it started, or a client of a remote
scheduler); ``execute`` submits every run to it, each through the worker's sandbox
(``sandbox.run_in_sandbox``), and hands every attempt's :class:`RunOutcome` to ``on_outcome`` in
the client thread, in completion order. A run whose attempt ends in a retried status
(``failed``, ``timeout``, ``crashed``, ``lost``) is resubmitted with the next attempt number, at
most ``retries`` times. Dask reschedules the runs of a worker that dies; a run it gives up on
(``KilledWorker``) or loses to a broken connection is one ``lost`` attempt.

Ctrl-C (SIGINT, or SIGTERM under ``sms``): the outstanding runs are cancelled and
:class:`CampaignInterrupted` (a KeyboardInterrupt) is raised. A signal that arrives while an
outcome is being collected and delivered waits for that delivery to end, so every outcome
``on_outcome`` was given was given whole.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import logging
import os
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from typing import Self

from sms_cli.campaign.sandbox import RunFn, run_in_sandbox
from sms_cli.campaign.tasks import FINISHED, RETRIED, RunOutcome, RunTask, one_line
from sms_cli.errors import EXIT_INTERNAL, InputError, Problem

log = logging.getLogger(__name__)

#: How long connecting to a remote scheduler may take before it counts as unreachable.
CONNECT_TIMEOUT_S = 8.0
#: How long closing the client and stopping a local cluster may take.
CLOSE_TIMEOUT_S = 10.0
SCHEDULER_HINT = "start one with `dask scheduler`, or leave out --scheduler to run on a local cluster"


class CampaignInterrupted(KeyboardInterrupt):
    """Ctrl-C during ``execute``: the outcomes received so far were delivered, the rest cancelled."""

    def __init__(self, delivered: int, cancelled: int):
        super().__init__(f"interrupted after {delivered} attempts; {cancelled} runs cancelled")
        self.delivered = delivered
        self.cancelled = cancelled


# ----------------------------------------------------------------------------------------- pool


@dataclass
class Pool:
    """A Dask client, and the local cluster it runs on when ``connect`` started one."""

    client: object
    cluster: object | None = None

    @property
    def address(self) -> str:
        return self.client.scheduler.address

    def worker_count(self) -> int:
        """Workers the scheduler knows of now."""
        return len(self.client.scheduler_info()["workers"])

    def close(self) -> None:
        """Close the client, then stop the local cluster (if this pool started it), each bounded in time."""
        for closable in (self.client, self.cluster):
            if closable is None:
                continue
            try:
                closable.close(timeout=CLOSE_TIMEOUT_S)
            except Exception as exc:  # noqa: BLE001 - closing must not hide the campaign's own outcome
                log.debug("closing %s: %s", type(closable).__name__, exc)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def quiet_dask_logs() -> None:
    """Keep distributed's informational logging off stderr (warnings and errors still show)."""
    for name in ("distributed", "distributed.client", "distributed.scheduler", "distributed.worker",
                 "distributed.nanny", "distributed.core", "distributed.comm"):
        logger = logging.getLogger(name)
        if logger.getEffectiveLevel() < logging.WARNING:
            logger.setLevel(logging.WARNING)


def connect(scheduler: str | None, workers: int | None) -> Pool:
    """A pool on ``scheduler`` (``tcp://HOST:PORT``), or on a local cluster of ``workers`` processes
    (default: one per core) when ``scheduler`` is None. An unreachable scheduler is an InputError."""
    quiet_dask_logs()
    if scheduler is None:
        return _local_pool(workers or os.cpu_count() or 1)
    return _remote_pool(scheduler)


def _local_pool(workers: int) -> Pool:
    from distributed import Client, LocalCluster

    if workers < 1:
        raise InputError(problems=[Problem(f"--workers must be at least 1, not {workers}", field=None)])
    # No dashboard; the scheduler's HTTP server (health routes) on a free port, not 8787 (which
    # may be taken, and distributed would warn about it).
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                           silence_logs=logging.WARNING)
    try:
        return Pool(Client(cluster, set_as_default=False), cluster)
    except BaseException:
        cluster.close(timeout=CLOSE_TIMEOUT_S)
        raise


def _remote_pool(address: str) -> Pool:
    from distributed import Client
    from distributed.comm import parse_address, parse_host_port

    try:
        protocol, location = parse_address(address)
        host, port = parse_host_port(location)
    except ValueError as exc:
        raise _unreachable(address, f"not an address of the form tcp://HOST:PORT ({exc})") from None
    if protocol == "tcp":
        _check_tcp(address, host, port)
    _check_scheduler(address)
    try:
        return Pool(Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False))
    except (OSError, TimeoutError, ValueError) as exc:
        raise _unreachable(address, _reason(exc)) from None


def _check_tcp(address: str, host: str, port: int) -> None:
    """Fail at once on a refused connection or an unknown host (distributed would retry until its timeout)."""
    try:
        socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S).close()
    except OSError as exc:
        raise _unreachable(address, _reason(exc)) from None


async def _identity(address: str) -> dict:
    from distributed.comm import connect as open_comm

    comm = await open_comm(address, timeout=CONNECT_TIMEOUT_S)
    try:
        await comm.write({"op": "identity", "reply": True})
        return await comm.read()
    finally:
        comm.abort()


def _check_scheduler(address: str) -> None:
    """Ask the server who it is, within CONNECT_TIMEOUT_S in all: a port that accepts connections
    but never speaks Dask would otherwise keep the client waiting for ever."""
    import asyncio

    try:
        identity = asyncio.run(asyncio.wait_for(_identity(address), CONNECT_TIMEOUT_S))
    except (OSError, TimeoutError, ValueError) as exc:
        raise _unreachable(address, _reason(exc)) from None
    if not isinstance(identity, dict) or identity.get("type") != "Scheduler":
        raise _unreachable(address, "the server there is not a Dask scheduler")


def _reason(exc: BaseException) -> str:
    """Why a connection failed, in words (no exception class names)."""
    if isinstance(exc, (TimeoutError, socket.timeout)):
        return f"nothing answered within {CONNECT_TIMEOUT_S:g} s"
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror.lower()
    text = str(exc).strip()
    if text.lower().startswith("timed out"):
        return f"nothing answered within {CONNECT_TIMEOUT_S:g} s"
    return text.splitlines()[0] if text else "the connection failed"


def _unreachable(address: str, reason: str) -> InputError:
    return InputError(problems=[Problem(f"cannot reach the Dask scheduler at {address}: {reason}", field=None,
                                        hint=SCHEDULER_HINT)])


# ------------------------------------------------------------------------------------- progress


def _clock(seconds: float) -> str:
    seconds = round(seconds)
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


class CampaignProgress:
    """A one-line progress display on stderr: runs done / total, failed attempts, ETA.

    ``enabled=None``: only when stderr is a terminal. Redrawn at most ten times a second, and
    once more by ``close``."""

    def __init__(self, total: int, enabled: bool | None = None):
        self.total = total
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.done = 0
        self.failures = 0
        self._start = time.monotonic()
        self._drawn_at = float("-inf")

    def update(self, done: int, failures: int) -> None:
        self.done, self.failures = done, failures
        if self.enabled and time.monotonic() - self._drawn_at >= 0.1:
            self._draw()

    def line(self) -> str:
        pct = 100 if self.total <= 0 else int(100 * self.done / self.total)
        elapsed = time.monotonic() - self._start
        eta = _clock(elapsed / self.done * (self.total - self.done)) if self.done else "-:--:--"
        return (f"  campaign {self.done:>{len(str(self.total))}} / {self.total} runs  [{'#' * (pct // 4):<25}] "
                f"{pct:3d}%  {self.failures} failed  ETA {eta}")

    def _draw(self) -> None:
        self._drawn_at = time.monotonic()
        sys.stderr.write("\r" + self.line())
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            self._draw()
            sys.stderr.write("\n")
            sys.stderr.flush()


# ------------------------------------------------------------------------------------- execute


@dataclass
class ExecutionSummary:
    """What ``execute`` did: ``outcomes`` holds the last attempt of each run; ``gave_up`` the runs
    whose every allowed attempt ended in a retried status."""

    total: int
    attempts: int = 0
    failures: int = 0
    outcomes: dict[int, RunOutcome] = field(default_factory=dict)
    gave_up: list[int] = field(default_factory=list)
    wall_s: float = 0.0

    @property
    def finished(self) -> int:
        return sum(1 for o in self.outcomes.values() if o.status in FINISHED)


@contextlib.contextmanager
def _signals_deferred():
    """Hold SIGINT/SIGTERM (when Python's ``default_int_handler`` serves them) until the block ends,
    then raise KeyboardInterrupt: a delivery is never cut in half. Only the main thread gets signals."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    held = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(sig) is signal.default_int_handler:
            held[sig] = signal.signal(sig, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        for sig, handler in held.items():
            signal.signal(sig, handler)
    if caught:
        raise KeyboardInterrupt


def _error_of(future, result) -> BaseException:
    """The exception behind a future that did not bring a RunOutcome (``as_completed`` with
    ``raise_errors=False`` gives an erred future's (type, exception, traceback))."""
    if isinstance(result, tuple) and len(result) == 3 and isinstance(result[1], BaseException):
        return result[1]
    if isinstance(result, BaseException):
        return result
    if future.status == "finished":
        return TypeError(f"the run returned a {type(result).__name__}, not a RunOutcome")
    return concurrent.futures.CancelledError()


def _lost_reason(exc: BaseException) -> str:
    """Why a future's error means its worker or the connection was lost, in words ('' when it does not)."""
    from distributed import KilledWorker

    if isinstance(exc, KilledWorker):
        return "the worker running it died, and Dask gave up on the run"
    if isinstance(exc, concurrent.futures.CancelledError):
        return "Dask dropped the run (its scheduler or worker went away)"
    if isinstance(exc, OSError):
        return f"the connection to its worker was lost ({exc.strerror or one_line(exc) or 'closed'})"
    return ""


class _Execution:
    """The client side of one ``execute`` call: futures in flight, retry budget, deliveries."""

    def __init__(self, pool: Pool, run_fn: RunFn, timeout_s: float | None, retries: int,
                 on_outcome: Callable[[RunOutcome], None], progress: CampaignProgress):
        from distributed import as_completed

        self.client = pool.client
        self.run_fn = run_fn
        self.timeout_s = timeout_s
        self.retries = retries
        self.on_outcome = on_outcome
        self.progress = progress
        self.in_flight: dict[object, RunTask] = {}
        self.first_attempt: dict[int, int] = {}
        self.summary = ExecutionSummary(total=progress.total)
        self.done = 0
        self.queue = as_completed(loop=self.client.loop, with_results=True, raise_errors=False)

    def _prepared(self, task: RunTask) -> RunTask:
        return task if self.timeout_s is None else replace(task, timeout_s=self.timeout_s)

    def submit_all(self, tasks: list[RunTask]) -> None:
        tasks = [self._prepared(t) for t in tasks]
        for task in tasks:
            self.first_attempt.setdefault(task.run, task.attempt)
        futures = self.client.map(run_in_sandbox, tasks, run_fn=self.run_fn, pure=False)
        for future, task in zip(futures, tasks):
            self.in_flight[future] = task
        self.queue.update(futures)

    def resubmit(self, task: RunTask) -> None:
        task = replace(task, attempt=task.attempt + 1)
        future = self.client.submit(run_in_sandbox, task, run_fn=self.run_fn, pure=False)
        self.in_flight[future] = task
        self.queue.add(future)

    def collect(self, future, result) -> tuple[RunTask, RunOutcome]:
        """The outcome a finished future brought, or the lost/failed attempt its error means.
        (``as_completed`` fetched ``result`` in its own thread: nothing here waits on the network.)"""
        task = self.in_flight.pop(future)
        if future.status == "finished" and isinstance(result, RunOutcome):
            return task, result
        exc = _error_of(future, result)
        lost = _lost_reason(exc)
        status, message = ("lost", lost) if lost else ("failed", f"{type(exc).__name__}: {one_line(exc)}")
        return task, RunOutcome(run=task.run, status=status, exit_status=EXIT_INTERNAL, message=message,
                                attempt=task.attempt)

    def retry_allowed(self, task: RunTask) -> bool:
        return task.attempt - self.first_attempt[task.run] < self.retries

    def deliver(self, task: RunTask, outcome: RunOutcome) -> None:
        """Hand the outcome over, then resubmit its run or count the run done."""
        summary = self.summary
        summary.attempts += 1
        summary.outcomes[task.run] = outcome
        retried = outcome.status in RETRIED
        summary.failures += retried
        self.on_outcome(outcome)
        if retried and self.retry_allowed(task):
            self.resubmit(task)
        else:
            if retried:
                summary.gave_up.append(task.run)
            self.done += 1
        self.progress.update(self.done, summary.failures)

    def run(self) -> None:
        for future, result in self.queue:
            with _signals_deferred():
                self.deliver(*self.collect(future, result))

    def cancel_outstanding(self) -> int:
        futures = list(self.in_flight)
        self.in_flight.clear()
        if futures:
            try:
                self.client.cancel(futures)
            except Exception as exc:  # noqa: BLE001 - the campaign is stopping; a dead cluster cancels nothing
                log.debug("cancelling %d runs: %s", len(futures), exc)
        return len(futures)


def execute(pool: Pool, tasks: Iterable[RunTask], run_fn: RunFn, *, timeout_s: float | None, retries: int,
            on_outcome: Callable[[RunOutcome], None], progress: bool | None = None) -> ExecutionSummary:
    """Run every task on ``pool`` through ``run_fn`` (an importable module-level function), each
    attempt in a worker's sandbox with ``timeout_s``; retried statuses are resubmitted up to
    ``retries`` times. Every attempt's outcome goes to ``on_outcome`` in this thread as it completes.
    Ctrl-C cancels what is outstanding and raises CampaignInterrupted."""
    tasks = list(tasks)
    started = time.perf_counter()
    bar = CampaignProgress(len(tasks), progress)
    execution = _Execution(pool, run_fn, timeout_s, retries, on_outcome, bar)
    try:
        execution.submit_all(tasks)
        execution.run()
    except KeyboardInterrupt:
        cancelled = execution.cancel_outstanding()
        raise CampaignInterrupted(execution.summary.attempts, cancelled) from None
    finally:
        bar.close()
        execution.summary.wall_s = time.perf_counter() - started
    return execution.summary
