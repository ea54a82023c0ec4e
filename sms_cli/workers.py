"""Jobs run on worker processes while the caller runs jobs too: the one process pool of ``sms``
(figures of ``sms analyze``, ``sms_cli.report.figpool``; the kernel warm-up's lanes,
``sms_cli.sim.compiled.warmup``).

A job is ``(function, args)``: a module-level function of plain data that returns what the caller
needs (PNG bytes, the names of the kernels compiled). Workers write no file: the caller writes
(atomically, under its results-folder lock) in its own order, so the output is the same bytes
whichever process ran a job, and the same as with no worker at all.

Each worker is ``python -m sms_cli.workers`` (a fresh interpreter, so nothing of the caller
is forked and no ``__main__`` module is imported again), started when the pool is created so its
imports (numpy, matplotlib) overlap the caller's own work; jobs and results travel pickled over
its stdin and stdout. A worker runs in its own session (Ctrl-C and SIGTERM reach the caller only),
is killed when the caller is interrupted (it has nothing half-written: it writes no file) and exits
when its stdin closes, so also when the caller dies.

How many: the caller says (:func:`default_workers`: one less than the usable cores, at most
:data:`MAX_WORKERS`, or what an environment variable says).
"""

from __future__ import annotations

import os
import pickle
import struct
import subprocess
import sys
import threading
from collections import deque
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, BinaryIO

MAX_WORKERS = 3
_HEADER = struct.Struct(">Q")


def usable_cores(env_var: str | None = None) -> int:
    """``env_var``'s value when it is a positive integer, else the cores this process may use (its
    CPU affinity mask), at least 1."""
    env = os.environ.get(env_var, "").strip() if env_var else ""
    if env.isdigit() and int(env) > 0:
        return int(env)
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def default_workers(env_var: str | None = None) -> int:
    """Worker processes to start: ``env_var``'s value when set (0: every job in the caller), else one
    less than the usable cores, at most :data:`MAX_WORKERS`."""
    env = os.environ.get(env_var, "").strip() if env_var else ""
    if env:
        try:
            return max(0, int(env))
        except ValueError:
            pass
    return max(0, min(usable_cores() - 1, MAX_WORKERS))


def _send(fh: BinaryIO, obj: Any) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    fh.write(_HEADER.pack(len(data)) + data)
    fh.flush()


def _recv(fh: BinaryIO) -> Any:
    """The next message, or EOFError when the other end closed."""
    head = fh.read(_HEADER.size)
    if len(head) < _HEADER.size:
        raise EOFError
    n = _HEADER.unpack(head)[0]
    data = fh.read(n)
    if len(data) < n:
        raise EOFError
    return pickle.loads(data)


class WorkerPool:
    """Run jobs ``(function, args)`` on ``workers`` processes and in the caller; see the module.

    :meth:`run` hands the jobs to the workers from the front of the list while the caller draws
    them from the back, so the costly jobs should come first; results come back in job order. A
    job whose worker fails or dies is run again in the caller (where an error raises with its
    traceback). Use as a context manager: the workers stop at its end."""

    def __init__(self, workers: int | None = None, preload: Sequence[str] = ()):
        """``preload``: "module" or "module:function" a worker imports (and calls) as soon as it starts,
        while the caller prepares the jobs."""
        n = default_workers() if workers is None else max(0, workers)
        root = str(Path(__file__).resolve().parents[2])  # the folder holding this sms_cli
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, *filter(None, [os.environ.get("PYTHONPATH")])])}
        self._procs: list[subprocess.Popen] = []
        self._used = False
        for _ in range(n):
            try:
                self._procs.append(subprocess.Popen(
                    [sys.executable, "-m", "sms_cli.workers", *preload], stdin=subprocess.PIPE,
                    stdout=subprocess.PIPE, env=env, start_new_session=True))
            except OSError:  # no process to spare: the caller draws everything
                break

    @property
    def workers(self) -> int:
        return len(self._procs)

    def run(self, jobs: Sequence[tuple[Callable[..., Any], tuple]]) -> list[Any]:
        """Each job's result, in job order."""
        self._used = True
        pending = deque(range(len(jobs)))
        lock = threading.Lock()
        results: list[Any] = [None] * len(jobs)
        done = [False] * len(jobs)

        def take(front: bool) -> int | None:
            with lock:
                if not pending:
                    return None
                return pending.popleft() if front else pending.pop()

        def serve(proc: subprocess.Popen) -> None:
            while (i := take(True)) is not None:
                try:
                    _send(proc.stdin, jobs[i])
                    kind, value = _recv(proc.stdout)
                except Exception:  # noqa: BLE001 - a job that does not pickle, a worker that died
                    kind = "lost"
                if kind != "ok":  # give the job back to the caller and stop using this worker
                    with lock:
                        pending.append(i)
                    return
                results[i], done[i] = value, True

        threads = [threading.Thread(target=serve, args=(p,), daemon=True, name="sms-worker")
                   for p in self._procs if p.poll() is None]
        for t in threads:
            t.start()
        try:
            while True:
                while (i := take(False)) is not None:
                    fn, args = jobs[i]
                    results[i], done[i] = fn(*args), True
                if not any(t.is_alive() for t in threads):
                    break
                for t in threads:
                    t.join(0.05)
            if (i := take(False)) is not None or not all(done):  # pragma: no cover - cannot happen
                raise RuntimeError(f"job {i} was not run")
        except BaseException:
            self._kill()  # the workers write nothing: stopping them mid-job loses nothing
            raise
        return results

    def _kill(self) -> None:
        for p in self._procs:
            p.kill()
        for p in self._procs:
            p.wait()
            for fh in (p.stdin, p.stdout):
                try:
                    fh.close()
                except OSError:
                    pass
        self._procs = []

    def close(self) -> None:
        """Stop the workers (each ends when its stdin closes; one never given a job is killed: it
        may still be importing)."""
        if not self._used:
            self._kill()
            return
        for p in self._procs:
            try:
                p.stdin.close()
            except OSError:
                pass
        for p in self._procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
            p.stdout.close()
        self._procs = []

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, exc_type, *exc) -> None:
        if exc_type is None:
            self.close()
        else:
            self._kill()


def _worker(preload: Sequence[str]) -> None:
    """A worker's loop: import ``preload``, then answer each job read from stdin on stdout."""
    import importlib
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    channel = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # a stray print goes to stderr, not into the results
    sys.stdout = sys.stderr
    jobs = sys.stdin.buffer
    for m in preload:  # now, while the caller computes what the figures show
        module, _, fn = m.partition(":")
        mod = importlib.import_module(module)
        if fn:
            getattr(mod, fn)()
    while True:
        try:
            fn, args = _recv(jobs)
        except EOFError:
            break
        try:
            reply = ("ok", fn(*args))
        except Exception:  # noqa: BLE001 - the caller runs the job again and raises its error
            reply = ("error", None)
        try:
            _send(channel, reply)
        except BrokenPipeError:
            break
    sys.stderr.flush()
    os._exit(0)  # nothing to finish (no file written): skip the interpreter's teardown, the caller waits for it


if __name__ == "__main__":
    _worker(sys.argv[1:])
