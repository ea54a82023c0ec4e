"""One attempt of a run in a child process, so a crash or a hang costs one attempt, not a worker.

Each thread that runs attempts (one per Dask worker process with ``--nthreads 1``) keeps one
child process, started with multiprocessing's ``spawn`` context and reused across attempts, so
the mission code and its numba kernels load once (a fresh child imports the run function's
module before the first attempt's clock starts). The parent sends ``(run_fn, task)`` down a
pipe and waits at most ``task.timeout_s``:

- the child answers with the run function's RunOutcome → that outcome;
- the run function raises → status ``failed``, exit status 4, a one-line message (the traceback
  goes to this module's debug log);
- nothing within the timeout → the child is killed, status ``timeout``;
- the child dies (segfault, ``os._exit``, SIGKILL) → status ``crashed``.

After a timeout or a crash the next attempt starts a fresh child. The child ignores SIGINT (the
client decides what Ctrl-C stops) and exits when its parent does.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import signal
import socket
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from sms_cli.campaign.tasks import RunOutcome, RunTask, one_line
from sms_cli.errors import EXIT_INTERNAL

log = logging.getLogger(__name__)

RunFn = Callable[[RunTask], RunOutcome]

#: How long a killed or finished child may take to be reaped before it is given up on.
REAP_TIMEOUT_S = 5.0
#: How long a fresh child may take to import the run function (not counted in any attempt's timeout).
LOAD_TIMEOUT_S = 300.0
#: How often the child checks that its parent is still alive.
PARENT_CHECK_S = 0.5


def worker_name() -> str:
    """``host:pid`` of this process (the Dask worker that runs the attempt)."""
    return f"{socket.gethostname()}:{os.getpid()}"


def _one_line(exc: BaseException) -> str:
    """An unexpected exception (a bug) as one line: its class and its first line."""
    text = one_line(exc)
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _exit_when_orphaned(parent_pid: int) -> None:
    """Child-side watchdog: end this process once its parent is gone (even mid-run)."""
    while True:
        time.sleep(PARENT_CHECK_S)
        if os.getppid() != parent_pid:
            os._exit(0)


def _child_main(conn, parent_pid: int) -> None:
    """The child's loop: answer ``("load", run_fn)`` once the function's module is imported, and
    ``("run", (run_fn, task))`` with the run's outcome or its error."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_exit_when_orphaned, args=(parent_pid,), daemon=True).start()
    while True:
        try:
            kind, payload = conn.recv()
        except (EOFError, OSError):  # the parent closed the pipe
            return
        except Exception as exc:  # noqa: BLE001 - the run function's module does not import here
            conn.send(("error", (f"the run function cannot be loaded: {_one_line(exc)}", traceback.format_exc())))
            continue
        if kind == "load":
            conn.send(("loaded", None))
            continue
        run_fn, task = payload
        try:
            reply: tuple[str, Any] = ("outcome", run_fn(task))
        except Exception as exc:  # noqa: BLE001 - any error of the run function is one failed attempt
            reply = ("error", (_one_line(exc), traceback.format_exc()))
        try:
            conn.send(reply)
        except Exception as exc:  # noqa: BLE001 - an outcome that does not pickle
            conn.send(("error", (f"the run's outcome cannot be sent back: {_one_line(exc)}", traceback.format_exc())))


_DAEMON_FLAG = threading.Lock()


@contextlib.contextmanager
def _children_allowed():
    """Let a daemonic process start the sandbox child.

    Dask's nanny starts worker processes as daemons, and multiprocessing refuses children of a
    daemon. The sandbox child is itself a daemon and watches its parent, so it never outlives
    the worker; the worker's flag is restored at once (under a lock: a worker may have threads)."""
    me = multiprocessing.current_process()
    with _DAEMON_FLAG:
        was_daemon = me.daemon
        if was_daemon:
            me.daemon = False
        try:
            yield
        finally:
            if was_daemon:
                me.daemon = True


class Sandbox:
    """A persistent child process that runs attempts one at a time, with a timeout each."""

    def __init__(self) -> None:
        self._ctx = multiprocessing.get_context("spawn")
        self._process = None
        self._conn = None

    @property
    def pid(self) -> int | None:
        """The child's pid (None before the first attempt or after a kill)."""
        return self._process.pid if self._process is not None else None

    def _start(self) -> None:
        parent_end, child_end = self._ctx.Pipe(duplex=True)
        process = self._ctx.Process(target=_child_main, args=(child_end, os.getpid()),
                                    name="sms-campaign-sandbox", daemon=True)
        with _children_allowed():
            process.start()
        child_end.close()
        self._process, self._conn = process, parent_end

    def _alive(self) -> bool:
        return self._process is not None and self._process.is_alive()

    def _exchange(self, message: tuple[str, Any], timeout: float | None) -> tuple[bool, tuple | None]:
        """Send a message, wait for the reply: (answered in time, the reply or None if the child died)."""
        try:
            self._conn.send(message)
            if not self._conn.poll(timeout):
                return False, None
            return True, self._conn.recv()
        except (EOFError, OSError):  # the pipe broke: the child died
            return True, None

    def _ask(self, task: RunTask, message: tuple, timeout: float | None, late: str) -> tuple[RunOutcome | None, Any, float]:
        """Send ``message`` to the child and wait up to ``timeout``: (the faulted attempt or None,
        the reply, wall s). No answer in time kills the child (``timeout``, message ``late``); a dead
        child is ``crashed``."""
        started = time.perf_counter()
        answered, reply = self._exchange(message, timeout)
        wall = time.perf_counter() - started
        if not answered:
            self.close()
            return self._fault(task, "timeout", late, wall), None, wall
        if reply is None:
            return self._fault(task, "crashed", self._death_note(), wall), None, wall
        return None, reply, wall

    def _load(self, task: RunTask, run_fn: RunFn) -> RunOutcome | None:
        """Start a child and import the run function in it, outside any attempt's timeout
        (None: ready; else the attempt this cost)."""
        self.close()
        self._start()
        fault, reply, wall = self._ask(task, ("load", run_fn), LOAD_TIMEOUT_S,
                                       f"the run function did not load within {LOAD_TIMEOUT_S:g} s")
        if fault is not None:
            return fault
        return self._outcome(task, reply, wall) if reply[0] == "error" else None

    def run(self, task: RunTask, run_fn: RunFn) -> RunOutcome:
        """One attempt of ``task`` through ``run_fn`` in the child; never raises for the run's faults."""
        if not self._alive():
            failed = self._load(task, run_fn)
            if failed is not None:
                return failed
        fault, reply, wall = self._ask(task, ("run", (run_fn, task)), task.timeout_s,
                                       f"no result within {task.timeout_s or 0:g} s; the run's process was killed")
        return fault if fault is not None else self._outcome(task, reply, wall)

    def _outcome(self, task: RunTask, reply: tuple[str, Any], wall: float) -> RunOutcome:
        kind, payload = reply
        if kind == "error":
            message, trace = payload
            log.debug("run %d attempt %d raised:\n%s", task.run, task.attempt, trace)
            return self._fault(task, "failed", message, wall)
        if not isinstance(payload, RunOutcome):
            returned = type(payload).__name__
            return self._fault(task, "failed", f"the run function returned a {returned}, not a RunOutcome", wall)
        return replace(payload, run=task.run, attempt=task.attempt, wall_s=wall, worker=worker_name())

    def _fault(self, task: RunTask, status: str, message: str, wall: float) -> RunOutcome:
        return RunOutcome(run=task.run, status=status, exit_status=EXIT_INTERNAL, message=message,
                          wall_s=wall, worker=worker_name(), attempt=task.attempt)

    def _death_note(self) -> str:
        """Why the child ended, in words (it has died when this is asked)."""
        process = self._process
        process.join(REAP_TIMEOUT_S)
        code = process.exitcode
        self.close()
        if code is not None and code < 0:
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = f"signal {-code}"
            return f"the run's process died ({name})"
        return f"the run's process exited with status {code}"

    def close(self) -> None:
        """Kill the child (if any) and reap it within a bounded time."""
        process, conn = self._process, self._conn
        self._process = self._conn = None
        if conn is not None:
            conn.close()
        if process is not None:
            if process.is_alive():
                process.kill()
            process.join(REAP_TIMEOUT_S)


_local = threading.local()


def thread_sandbox() -> Sandbox:
    """The sandbox of the calling thread (one child per worker thread, created on first use)."""
    box = getattr(_local, "sandbox", None)
    if box is None:
        box = _local.sandbox = Sandbox()
    return box


def run_in_sandbox(task: RunTask, run_fn: RunFn) -> RunOutcome:
    """One attempt of ``task`` in this thread's sandbox: the function Dask runs on a worker."""
    return thread_sandbox().run(task, run_fn)
