"""The campaign executor: sandboxed attempts, retries, lost workers and Ctrl-C, on real Dask processes.

Every run here is ``probe_run`` (sms_cli/campaign/probe.py), the executor's test double. Each
subprocess wait is bounded, fixtures kill the process groups they start, a watchdog fails a test
that outlives ``TEST_LIMIT_S`` (and the fixtures still clean up), and the Dask processes end on
their own if the test process dies (scheduler idle timeout, worker death timeout).
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import textwrap
import time
from collections import Counter
from dataclasses import replace
from pathlib import Path

import psutil
import pytest
from conftest import EXCEPTION_TEXT, ROOT

from sms_cli.campaign.execute import CampaignInterrupted, connect, execute
from sms_cli.campaign.probe import probe_run, probe_task
from sms_cli.campaign.sandbox import Sandbox
from sms_cli.campaign.tasks import FINISHED
from sms_cli.errors import InputError

TEST_LIMIT_S = 60
DASK = str(Path(sys.executable).with_name("dask"))


class TookTooLong(Exception):
    pass


def _too_long(signum, frame):
    raise TookTooLong(f"the test ran for more than {TEST_LIMIT_S} s")


@pytest.fixture(autouse=True)
def watchdog():
    """Fail a test that hangs (SIGALRM raises in the main thread; fixtures then tear down)."""
    previous = signal.signal(signal.SIGALRM, _too_long)
    signal.setitimer(signal.ITIMER_REAL, TEST_LIMIT_S)
    yield
    signal.setitimer(signal.ITIMER_REAL, 0)
    signal.signal(signal.SIGALRM, previous)


# --------------------------------------------------------------------------------- helpers


def campaign(pool, tasks, *, timeout_s=20.0, retries=2, on_outcome=None):
    """Run ``tasks`` on ``pool``; returns (every outcome in delivery order, the summary)."""
    got = []

    def keep(outcome):
        got.append(outcome)
        if on_outcome is not None:
            on_outcome(outcome)

    summary = execute(pool, tasks, probe_run, timeout_s=timeout_s, retries=retries, on_outcome=keep)
    return got, summary


def finished_once(outcomes, runs):
    """Each run finished exactly once (and nothing else finished)."""
    counts = Counter(o.run for o in outcomes if o.status in FINISHED)
    return counts == Counter(runs)


def result_of(outcome):
    """What must not depend on where a run ran."""
    return outcome.status, outcome.exit_status, outcome.metrics, outcome.params, outcome.requirements


def attempts_by_run(outcomes):
    runs = {}
    for o in outcomes:
        runs.setdefault(o.run, []).append((o.attempt, o.status))
    return runs


def start_group(args, log: Path, env=None) -> subprocess.Popen:
    """A process in its own session (so the fixture can kill it with its children)."""
    with open(log, "wb") as out:
        return subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
                                cwd=ROOT, env=env)


def kill_group(proc: subprocess.Popen) -> None:
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(timeout=5)
            return
        except subprocess.TimeoutExpired:
            continue


def wait_for(condition, timeout: float, what: str):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def process_ended(pid: int) -> bool:
    """Whether ``pid`` is gone (or a zombie waiting for its parent)."""
    try:
        return psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True


def closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# -------------------------------------------------------------------------------- fixtures


class DaskProcesses:
    """A `dask scheduler` and `dask worker` processes on 127.0.0.1, started by the test."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.procs: list[subprocess.Popen] = []
        file = folder / "scheduler.json"
        env = {**os.environ, "DASK_DISTRIBUTED__SCHEDULER__IDLE_TIMEOUT": "120s"}
        self.procs.append(start_group([DASK, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                       "--scheduler-file", str(file)], folder / "scheduler.log", env=env))
        self.address = wait_for(lambda: file.exists() and json.loads(file.read_text() or "{}").get("address"),
                                30, "the scheduler file")

    def add_worker(self, name: str) -> subprocess.Popen:
        """One worker process (no nanny: killing it kills the worker) with one thread."""
        args = [DASK, "worker", self.address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                "--host", "127.0.0.1", "--name", name, "--death-timeout", "10"]
        proc = start_group(args, self.folder / f"{name}.log")
        self.procs.append(proc)
        return proc

    def close(self) -> None:
        for proc in reversed(self.procs):
            kill_group(proc)


@pytest.fixture(scope="module")
def dask_processes(tmp_path_factory):
    cluster = DaskProcesses(tmp_path_factory.mktemp("dask"))
    try:
        cluster.add_worker("w1")
        cluster.add_worker("w2")
        yield cluster
    finally:
        cluster.close()


@pytest.fixture(scope="module")
def remote(dask_processes):
    with connect(dask_processes.address, None) as pool:
        pool.client.wait_for_workers(2, timeout=30)
        yield pool


@pytest.fixture(scope="module")
def local2():
    with connect(None, 2) as pool:
        yield pool


@pytest.fixture(scope="module")
def local1():
    with connect(None, 1) as pool:
        yield pool


# --------------------------------------------------------------------------------- sandbox


def test_sandbox_reuses_its_child_and_replaces_a_dead_one():
    box = Sandbox()
    try:
        first = box.run(probe_task(0), probe_run)
        child = box.pid
        second = box.run(probe_task(1), probe_run)
        assert (first.status, second.status) == ("ok", "ok")
        assert box.pid == child, "the child must serve every attempt until it dies"
        assert first.worker == f"{socket.gethostname()}:{os.getpid()}" and first.wall_s > 0

        crashed = box.run(probe_task(2, crash=True), probe_run)
        assert (crashed.status, crashed.exit_status) == ("crashed", 4) and "SIGSEGV" in crashed.message
        assert process_ended(child)
        exited = box.run(probe_task(3, crash="exit"), probe_run)
        assert exited.status == "crashed" and "139" in exited.message
        after = box.run(probe_task(4), probe_run)
        assert after.status == "ok" and box.pid not in (None, child)
    finally:
        box.close()


def test_sandbox_kills_a_hung_run_and_reports_an_exception_in_one_line():
    box = Sandbox()
    try:
        started = time.monotonic()
        hung = box.run(replace(probe_task(0, hang=True), timeout_s=0.5), probe_run)
        assert hung.status == "timeout" and time.monotonic() - started < 5
        raised = box.run(probe_task(1, **{"raise": True}), probe_run)
        assert (raised.status, raised.exit_status) == ("failed", 4)
        assert "planned error of run 1" in raised.message and "\n" not in raised.message
        assert "Traceback" not in raised.message
    finally:
        box.close()


# ---------------------------------------------------------------------- real dask processes


def test_a_campaign_on_dask_processes_finishes_every_run_once(remote):
    tasks = [probe_task(i, seconds=0.3) for i in range(12)]
    outcomes, summary = campaign(remote, tasks)
    assert finished_once(outcomes, range(12))
    assert all(o.status == "ok" for o in outcomes) and summary.attempts == 12
    assert len({o.worker for o in outcomes}) == 2, "both workers took runs"


def test_killing_a_worker_mid_campaign_still_finishes_every_run_once(dask_processes, remote):
    victim = dask_processes.add_worker("victim")
    remote.client.wait_for_workers(3, timeout=30)
    victim_name = f"{socket.gethostname()}:{victim.pid}"
    sandboxes = []

    def kill_the_victim(outcome):
        if outcome.worker == victim_name and victim.poll() is None:
            sandboxes.extend(psutil.Process(victim.pid).children())
            os.kill(victim.pid, signal.SIGKILL)

    outcomes, _ = campaign(remote, [probe_task(i, seconds=0.3) for i in range(12)], on_outcome=kill_the_victim)
    assert victim.wait(timeout=5) == -signal.SIGKILL
    assert finished_once(outcomes, range(12))
    assert len([o for o in outcomes if o.worker == victim_name]) == 1
    assert sandboxes, "the victim ran its runs in a sandbox child"
    _, alive = psutil.wait_procs(sandboxes, timeout=5)
    assert not alive, "a sandbox child outlived its worker"


def test_same_tasks_give_the_same_results_on_one_or_two_local_workers_and_on_dask(local1, local2, remote):
    tasks = [probe_task(i, seconds=0.02) for i in range(6)]
    results = []
    for pool in (local1, local2, remote):
        outcomes, _ = campaign(pool, tasks)
        results.append({o.run: result_of(o) for o in outcomes})
    assert results[0] == results[1] == results[2]
    assert len(results[0]) == 6 and len({r[2]["probe.value"] for r in results[0].values()}) == 6


# ----------------------------------------------------------------- faults on a local cluster


def test_faults_cost_attempts_of_their_run_only(local2):
    tasks = [probe_task(i, seconds=0.1) for i in range(4)] + [
        probe_task(4, hang=True, fail_attempts=1),  # a timeout, then ok
        probe_task(5, crash=True),  # crashes on every attempt
        probe_task(6, **{"raise": True}),  # raises on every attempt
        probe_task(7, fail_attempts=2),  # failed twice, then ok on the last allowed attempt
        probe_task(8, fail_attempts=3),  # one failure too many
    ]
    outcomes, summary = campaign(local2, tasks, timeout_s=1.5, retries=2)
    runs = attempts_by_run(outcomes)
    for i in range(4):
        assert runs[i] == [(1, "ok")]
    assert runs[4] == [(1, "timeout"), (2, "ok")]
    assert runs[5] == [(1, "crashed"), (2, "crashed"), (3, "crashed")]
    assert runs[6] == [(1, "failed"), (2, "failed"), (3, "failed")]
    assert runs[7] == [(1, "failed"), (2, "failed"), (3, "ok")]
    assert runs[8] == [(1, "failed"), (2, "failed"), (3, "failed")]
    assert sorted(summary.gave_up) == [5, 6, 8] and summary.attempts == len(outcomes) == 18
    raised = [o for o in outcomes if o.run == 6]
    assert all(o.exit_status == 4 and "\n" not in o.message and "planned error" in o.message for o in raised)
    assert all(o.worker and o.wall_s > 0 for o in outcomes)


def test_no_retries_means_one_attempt(local2):
    outcomes, summary = campaign(local2, [probe_task(0, fail_attempts=1)], retries=0)
    assert [(o.attempt, o.status) for o in outcomes] == [(1, "failed")] and summary.gave_up == [0]


def test_a_run_that_dask_gives_up_on_is_a_lost_attempt_and_resubmitted(tmp_path):
    import dask

    pid_file = tmp_path / "pids"
    killer = probe_task(0, kill_worker=True, fail_attempts=1, pid_file=str(pid_file))
    # allowed-failures 0: the first death of a worker running the run is a KilledWorker
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), connect(None, 1) as pool:
        outcomes, summary = campaign(pool, [killer, probe_task(1), probe_task(2)], retries=1)
        orphan = int(pid_file.read_text().split()[0])  # the sandbox child whose worker died
        wait_for(lambda: process_ended(orphan), 3, "the orphaned sandbox child to end")
    runs = attempts_by_run(outcomes)
    assert runs[0] == [(1, "lost"), (2, "ok")]
    assert finished_once(outcomes, range(3)) and summary.gave_up == []
    for attempts in runs.values():  # a run queued on the dead worker may be given up on too
        assert attempts in ([(1, "ok")], [(1, "lost"), (2, "ok")])
    lost = [o for o in outcomes if o.status == "lost"]
    assert all(o.exit_status == 4 and "\n" not in o.message and not EXCEPTION_TEXT.search(o.message) for o in lost)


def test_the_progress_line_shows_runs_done_failures_and_eta(local2, capsys):
    tasks = [probe_task(0, fail_attempts=1), probe_task(1), probe_task(2)]
    execute(local2, tasks, probe_run, timeout_s=20, retries=1, on_outcome=lambda o: None, progress=True)
    shown = capsys.readouterr().err
    assert shown.startswith("\r  campaign") and shown.endswith("\n")
    last = shown.rstrip("\n").split("\r")[-1]
    assert "3 / 3 runs" in last and "100%" in last and "1 failed" in last and "ETA 0:00:00" in last
    execute(local2, tasks, probe_run, timeout_s=20, retries=1, on_outcome=lambda o: None, progress=False)
    assert capsys.readouterr().err == ""


# ------------------------------------------------------------------------------ connecting


def test_an_unreachable_scheduler_is_an_input_error_naming_the_address():
    address = f"tcp://127.0.0.1:{closed_port()}"
    started = time.monotonic()
    with pytest.raises(InputError) as caught:
        connect(address, None)
    assert time.monotonic() - started < 5, "a refused connection is known at once"
    text = caught.value.render()
    assert f"cannot reach the Dask scheduler at {address}: connection refused" in text and "dask scheduler" in text
    assert not EXCEPTION_TEXT.search(text), text


def test_a_scheduler_that_never_answers_is_given_up_on_within_ten_seconds():
    with socket.socket() as silent:  # accepts TCP connections, never speaks Dask
        silent.bind(("127.0.0.1", 0))
        silent.listen(8)
        address = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
        started = time.monotonic()
        with pytest.raises(InputError) as caught:
            connect(address, None)
        assert time.monotonic() - started < 11
    text = caught.value.render()
    assert address in text and not EXCEPTION_TEXT.search(text), text


def test_closing_a_local_pool_stops_its_workers():
    pool = connect(None, 1)
    pids = pool.client.run(os.getpid)
    assert len(pids) == 1
    started = time.monotonic()
    pool.close()
    assert time.monotonic() - started < 15
    wait_for(lambda: all(process_ended(p) for p in pids.values()), 10, "the local workers to stop")


# ---------------------------------------------------------------------------------- Ctrl-C


def scheduled_states(pool):
    """The states of the tasks the scheduler still holds (cancelled runs are forgotten at once)."""
    return pool.client.run_on_scheduler(lambda dask_scheduler: [t.state for t in dask_scheduler.tasks.values()])


def test_an_interrupt_in_the_client_cancels_the_rest_after_whole_deliveries(local2):
    delivered = []

    def interrupt_after_three(outcome):
        delivered.append(outcome)
        if len(delivered) == 3:
            raise KeyboardInterrupt

    tasks = [probe_task(i, seconds=0.05) for i in range(3)] + [probe_task(i, seconds=1.0) for i in range(3, 10)]
    with pytest.raises(CampaignInterrupted) as caught:
        execute(local2, tasks, probe_run, timeout_s=20, retries=2, on_outcome=interrupt_after_three)
    assert caught.value.delivered == 3 and caught.value.cancelled == 7
    assert len(delivered) == 3 and all(o.status == "ok" and o.metrics for o in delivered)
    waiting = {"released", "waiting", "queued", "no-worker", "processing"}
    wait_for(lambda: not waiting & set(scheduled_states(local2)), 1.0, "the outstanding runs to be cancelled")


SIGINT_SCRIPT = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    from sms_cli.campaign.execute import CampaignInterrupted, connect, execute
    from sms_cli.campaign.probe import probe_run, probe_task

    def main(folder):
        lines = open(folder / "outcomes.jsonl", "a")

        def write_slowly(outcome):  # half a line, a pause a signal can land in, the rest
            text = '{"run": %d, "status": "%s", ' % (outcome.run, outcome.status)
            lines.write(text); lines.flush()
            (folder / f"delivering-{outcome.run}").touch()
            time.sleep(0.5)
            lines.write('"attempt": %d}\\n' % outcome.attempt); lines.flush()

        with connect(None, 1) as pool:
            (folder / "ready").touch()
            try:
                execute(pool, [probe_task(i, seconds=0.05) for i in range(20)], probe_run, timeout_s=20,
                        retries=0, on_outcome=write_slowly)
            except CampaignInterrupted as exc:
                print("interrupted", exc.delivered, exc.cancelled, flush=True)
                return 130
        return 0

    if __name__ == "__main__":
        sys.exit(main(Path(sys.argv[1])))
""")


def test_sigint_mid_delivery_finishes_that_delivery_then_stops(tmp_path):
    script = tmp_path / "campaign_script.py"
    script.write_text(SIGINT_SCRIPT)
    proc = start_group([sys.executable, str(script), str(tmp_path)], tmp_path / "script.log")
    try:
        wait_for(lambda: len(list(tmp_path.glob("delivering-*"))) >= 2 or proc.poll() is not None, 40,
                 "the second delivery")
        assert proc.poll() is None, (tmp_path / "script.log").read_text()
        os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C does: the whole process group
        assert proc.wait(timeout=20) == 130, (tmp_path / "script.log").read_text()
    finally:
        kill_group(proc)
    log = (tmp_path / "script.log").read_text()
    assert "interrupted 2 18" in log, log
    lines = (tmp_path / "outcomes.jsonl").read_text().splitlines()
    runs = [json.loads(line)["run"] for line in lines]  # a half-written line would not parse
    assert len(runs) == len(set(runs)) == 2, "two whole lines, the second finished after Ctrl-C"
