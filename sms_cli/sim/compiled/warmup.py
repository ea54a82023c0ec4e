"""Load the numba kernels a run needs before it starts, compiling them in parallel on a cold cache.

numba compiles a kernel the first time it is called after an install (or after its source
changed) and caches the machine code: in the package's ``__pycache__`` when that is writable,
else in numba's per-user cache directory (``NUMBA_CACHE_DIR`` overrides both); later runs load it
in milliseconds. A run lists the kernel calls it will make (:class:`KernelCall`, on throw-away
arrays of the same types as the real calls, so the compiled signatures are the ones the run uses)
and :func:`warm` makes them: on a warm cache in this process, on a cold one split into lanes
(this process and one worker process per further core, longest first) and with the pause
shown on stderr. Only the kernels of the run's engine are listed (``CompiledSimulation``,
``Simulation``), so a mission compiles what it needs and nothing else.

Run as ``python -m sms_cli.sim.compiled.warmup``: the worker, which reads pickled calls on
stdin, makes them and prints one line per kernel compiled.
"""

from __future__ import annotations

import importlib
import os
import pickle
import subprocess
import sys
import threading
import time
from dataclasses import dataclass


@dataclass(frozen=True)
class KernelCall:
    """One call of a compiled kernel: ``kernel`` is "module:function"; ``cost`` its relative
    compile cost on a cold cache (orders the lanes; seconds on the reference 2-core machine)."""

    kernel: str
    args: tuple
    cost: float = 1.0

    def dispatcher(self):
        module, name = self.kernel.split(":")
        return getattr(importlib.import_module(module), name)

    def __call__(self) -> None:
        self.dispatcher()(*self.args)


def cached(call: KernelCall) -> bool:
    """Whether numba's cache holds machine code of this kernel for the current source (any
    signature: a cache that holds the kernel for other argument types still compiles the call,
    in this process). False when the cache cannot be read."""
    try:
        cache = call.dispatcher()._cache
        return bool(cache._cache_file._load_index())  # {} when absent or written for another source
    except Exception:  # noqa: BLE001 - private numba API: treat as not cached
        return False


def lanes_available() -> int:
    """Cores this process may use (the CPU affinity mask), at least 1; ``SMS_COMPILE_LANES`` sets
    the number of lanes instead (1: compile in this process only)."""
    env = os.environ.get("SMS_COMPILE_LANES", "").strip()
    if env.isdigit() and int(env) > 0:
        return int(env)
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def split(groups: list[list[KernelCall]], lanes: int) -> list[list[KernelCall]]:
    """Longest-processing-time-first assignment of the groups to ``lanes`` lanes (lane 0: this
    process). A group is compiled in its order in one lane: list a kernel before its callers so
    that they find it compiled (numba compiles a callee with its first caller otherwise)."""
    load = [0.0] * lanes
    plan: list[list[KernelCall]] = [[] for _ in range(lanes)]
    for g in sorted(groups, key=lambda g: -sum(c.cost for c in g)):
        lane = min(range(lanes), key=lambda k: load[k])
        plan[lane] += g
        load[lane] += sum(c.cost for c in g)
    return plan


def warm(groups: list[list[KernelCall]], *, lanes: int | None = None, stream=None, what: str = "simulation") -> dict:
    """Make every call of every group (see the module docstring and :func:`split`). Returns
    {"compiled": kernels not in the cache, "lanes": lanes used (0: all cached), "seconds": wall time}."""
    stream = sys.stderr if stream is None else stream
    t0 = time.perf_counter()
    calls = [c for g in groups for c in g]
    cold_groups = [[c for c in g if not cached(c)] for g in groups]
    cold_groups = [g for g in cold_groups if g]
    n_cold = sum(len(g) for g in cold_groups)
    if not n_cold:
        for c in calls:
            c()
        return {"compiled": 0, "lanes": 0, "seconds": time.perf_counter() - t0}
    n_lanes = max(1, min(lanes or lanes_available(), len(cold_groups)))
    stream.write(f"  compiling {n_cold} {what} kernel{'s' * (n_cold > 1)} on {n_lanes} core"
                 f"{'s' * (n_lanes > 1)} (first run after an install only; cached for later runs)...\n")
    stream.flush()
    plan = split(cold_groups, n_lanes)
    workers = [_Worker(lane, stream, t0) for lane in plan[1:] if lane]
    try:
        for c in plan[0]:
            c()
            _done(stream, c.kernel, t0)
        for w in workers:
            w.wait()
    finally:
        for w in workers:
            w.stop()
    for c in calls:  # the worker lanes' kernels load from the cache here (or compile, if a worker failed)
        c()
    seconds = time.perf_counter() - t0
    stream.write(f"  kernels ready in {seconds:.1f} s\n")
    stream.flush()
    return {"compiled": n_cold, "lanes": n_lanes, "seconds": seconds}


def _done(stream, kernel: str, t0: float) -> None:
    stream.write(f"    {kernel.split(':')[1]:<28} compiled  [{time.perf_counter() - t0:5.1f} s]\n")
    stream.flush()


class _Worker:
    """A worker process compiling one lane (``python -m sms_cli.sim.compiled.warmup``)."""

    TIMEOUT_S = 600.0

    def __init__(self, calls: list[KernelCall], stream, t0: float):
        self.proc = subprocess.Popen([sys.executable, "-m", "sms_cli.sim.compiled.warmup"], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        self.proc.stdin.write(pickle.dumps(calls))
        self.proc.stdin.close()
        self._reader = threading.Thread(target=self._relay, args=(stream, t0), daemon=True)
        self._reader.start()

    def _relay(self, stream, t0: float) -> None:
        for line in self.proc.stdout:
            kernel = line.decode(errors="replace").strip()
            if kernel:
                _done(stream, kernel, t0)

    def wait(self) -> None:
        try:
            self.proc.wait(timeout=self.TIMEOUT_S)
        except subprocess.TimeoutExpired:
            pass  # stop() ends it; this process compiles what it did not
        self._reader.join(timeout=1.0)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def _worker_main() -> int:
    """Make the pickled calls read on stdin, one line per kernel on stdout."""
    calls: list[KernelCall] = pickle.loads(sys.stdin.buffer.read())
    for c in calls:
        c()
        sys.stdout.write(c.kernel + "\n")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(_worker_main())
