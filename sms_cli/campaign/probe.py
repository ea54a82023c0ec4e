"""The executor's test double: a synthetic run function with planned faults and no mission.

``probe_run`` stands in for the real runner in the tests of ``sandbox`` and ``execute`` and in
``benches/bench_campaign.py``. It reads ``task.tree["probe"]``::

    seconds:       CPU time to spin (busy work, not a sleep), default 0
    crash:         true → the process dies of SIGSEGV; "exit" → ``os._exit(139)``
    hang:          true → never returns (sleeps forever)
    kill_worker:   true → SIGKILL to the parent process (the Dask worker hosting the sandbox)
    raise:         true → raises RuntimeError
    pid_file:      a path → the process id of the attempt is appended to it (one line)
    fail_attempts: N → the faults above apply only while ``task.attempt <= N``; with no fault
                   named, those attempts return status ``failed``

Its metrics depend on ``task.samples`` only (``probe.value`` = the sum of the sample values), so
identical tasks give identical outcomes on any worker.
"""

from __future__ import annotations

import os
import signal
import time
from typing import Any

from sms_cli.campaign.tasks import RunOutcome, RunTask
from sms_cli.errors import EXIT_INTERNAL


def spin(cpu_seconds: float) -> None:
    """Busy work for ``cpu_seconds`` of this thread's CPU time."""
    end = time.thread_time() + cpu_seconds
    while time.thread_time() < end:
        pass


def _faulty(probe: dict[str, Any], attempt: int) -> bool:
    """Whether this attempt suffers the planned faults."""
    return "fail_attempts" not in probe or attempt <= int(probe["fail_attempts"])


def _fault(probe: dict[str, Any], task: RunTask) -> RunOutcome | None:
    """Commit the planned fault of this attempt: die, hang, raise, or a failed outcome (None: none)."""
    if not _faulty(probe, task.attempt):
        return None
    crash = probe.get("crash")
    if crash == "exit":
        os._exit(139)
    if crash:
        os.kill(os.getpid(), signal.SIGSEGV)
    if probe.get("kill_worker"):
        os.kill(os.getppid(), signal.SIGKILL)
        time.sleep(60)  # the sandbox child ends once it sees its parent gone
    if probe.get("hang"):
        while True:
            time.sleep(0.05)
    if probe.get("raise"):
        raise RuntimeError(f"probe: planned error of run {task.run}, attempt {task.attempt}")
    if "fail_attempts" in probe:
        return RunOutcome(run=task.run, status="failed", exit_status=EXIT_INTERNAL, attempt=task.attempt,
                          message=f"probe: planned failure of attempt {task.attempt}")
    return None


def probe_metrics(task: RunTask) -> dict[str, float]:
    """The deterministic metrics of a probe run: a function of its samples only."""
    values = [float(value) for _, (_, value) in sorted(task.samples.items())]
    return {"probe.value": float(sum(values)), "probe.samples": float(len(values)), "probe.run": float(task.run)}


def probe_run(task: RunTask) -> RunOutcome:
    """A synthetic run: spin, commit the planned fault if any, else report the probe metrics (ok)."""
    probe = dict(task.tree.get("probe") or {})
    if probe.get("pid_file"):
        with open(probe["pid_file"], "a") as pids:
            pids.write(f"{os.getpid()}\n")
    spin(float(probe.get("seconds", 0.0)))
    failed = _fault(probe, task)
    if failed is not None:
        return failed
    metrics = probe_metrics(task)
    params = {name: float(value) for name, (_, value) in task.samples.items()}
    return RunOutcome(run=task.run, status="ok", exit_status=0, metrics=metrics, params=params,
                      requirements={"probe.value_nonnegative": metrics["probe.value"] >= 0}, attempt=task.attempt)


def probe_task(run: int, **probe: Any) -> RunTask:
    """A RunTask for ``probe_run``: samples derived from the run index, ``probe`` as given."""
    samples = {"mass": ("robot.mass", 10.0 + 0.5 * run), "gain": ("control.gain", 1.0 / (run + 2))}
    return RunTask(run=run, tree={"probe": probe}, base_dir=".", name=f"probe-{run}", stages=("probe",), samples=samples)
