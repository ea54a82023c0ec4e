"""Load the numba kernels a run needs before it starts, compiling them in parallel on a cold cache.

numba compiles a kernel the first time it is called after an install (or after its source
changed) and caches the machine code: in the package's ``__pycache__`` when that is writable,
else in numba's per-user cache directory (``NUMBA_CACHE_DIR`` overrides both); later runs load it
in milliseconds. A run lists the kernel calls it will make (:class:`KernelCall`, on throw-away
arrays of the same types as the real calls, so the compiled signatures are the ones the run uses)
and :func:`warm` makes them: on a warm cache in this process, on a cold one in parallel lanes
(groups of calls on ``sms_cli.workers.WorkerPool``: this process and a worker process per further
core) with the pause shown on stderr. Only the kernels of the run's engine are listed
(``kernels.kernel_groups``), so a mission compiles what it needs and nothing else.
"""

from __future__ import annotations

import importlib
import inspect
import sys
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
    in this process). False when the cache cannot be read. A kernel this process already holds
    machine code of is cached without reading the index (its files: ~0.3 ms a kernel, 7-10 ms a run,
    which every run of a campaign or a benchmark's repeat would pay again)."""
    try:
        dispatcher = inspect.unwrap(call.dispatcher(), stop=lambda f: hasattr(f, "overloads"))  # past a timer (a benchmark)
        if dispatcher.overloads:
            return True
        cache = dispatcher._cache
        return bool(cache._cache_file._load_index())  # {} when absent or written for another source
    except Exception:  # noqa: BLE001 - private numba API: treat as not cached
        return False


def lanes_available() -> int:
    """Cores this process may use (the CPU affinity mask), at least 1; ``SMS_COMPILE_LANES`` sets
    the number of lanes instead (1: compile in this process only)."""
    from sms_cli.workers import usable_cores

    return usable_cores("SMS_COMPILE_LANES")


def warm(groups: list[list[KernelCall]], *, lanes: int | None = None, stream=None, what: str = "simulation") -> dict:
    """Make every call of every group. A group is compiled in its order in one lane: list a kernel
    before its callers so that they find it compiled (numba compiles a callee with its first caller
    otherwise). The costliest groups go to the workers, the caller takes the others. Returns
    {"compiled": kernels not in the cache, "lanes": lanes used (0: all cached), "seconds": wall time}."""
    from sms_cli.workers import WorkerPool

    stream = sys.stderr if stream is None else stream
    t0 = time.perf_counter()
    calls = [c for g in groups for c in g]
    cold = sorted((g for g in ([c for c in g if not cached(c)] for g in groups) if g), key=lambda g: -sum(c.cost for c in g))
    n_cold = sum(len(g) for g in cold)
    if not n_cold:
        for c in calls:
            c()
        return {"compiled": 0, "lanes": 0, "seconds": time.perf_counter() - t0}
    n_lanes = max(1, min(lanes or lanes_available(), len(cold)))
    stream.write(f"  compiling {n_cold} {what} kernel{'s' * (n_cold > 1)} on {n_lanes} core"
                 f"{'s' * (n_lanes > 1)} (first run after an install only; cached for later runs; "
                 "`sms warmup` does it ahead)...\n")
    stream.flush()
    progress = stream is sys.stderr  # the workers share this process's stderr
    with WorkerPool(n_lanes - 1) as pool:
        pool.run([(_make_calls, (g, t0, progress)) for g in cold])
    for c in calls:  # the worker lanes' kernels load from the cache here
        c()
    seconds = time.perf_counter() - t0
    stream.write(f"  kernels ready in {seconds:.1f} s\n")
    stream.flush()
    return {"compiled": n_cold, "lanes": n_lanes, "seconds": seconds}


def _make_calls(calls: list[KernelCall], t0: float, progress: bool) -> list[str]:
    """A lane's job: the calls in order, each kernel reported on stderr when ``progress`` (t0: the
    warm-up's start on ``time.perf_counter``, a system-wide clock, so worker lines share its origin)."""
    import warnings

    from numba.core.errors import NumbaPerformanceWarning

    for c in calls:
        with warnings.catch_warnings():  # numba's hints on array layouts are for sms's developers, not its users
            warnings.simplefilter("ignore", NumbaPerformanceWarning)
            c()
        if progress:
            sys.stderr.write(f"    [{time.perf_counter() - t0:5.1f} s] compiled {c.kernel.split(':')[1]}\n")
            sys.stderr.flush()
    return [c.kernel for c in calls]
