"""Campaign execution: throughput, parallel efficiency, overhead and memory of the Dask executor.

    .venv/bin/python benches/bench_campaign.py [--run-seconds S] [--spin S] [--runs-per-worker N]

Every run is ``probe_run`` (sms_cli/campaign/probe.py), a CPU spin with no mission, so the
figures are the executor's own. It prints:

- runs per second on a local Dask cluster of 1 and 2 workers (``execute``: each attempt in the
  worker's sandbox) and the parallel efficiency from 1 to 2 (target >= 90 % for runs of >= 1 s);
- the same through a plain ``concurrent.futures.ProcessPoolExecutor`` (no sandbox) and the
  throughput ratio Dask / pool (issue #14: within 10 % on 2 cores → Dask serves both);
- the overhead per run of each (short runs: wall x workers / runs - spin), and the share of the
  workers' time spent in runs;
- the memory per Dask worker (RSS of the worker process and its sandbox child);
- the measured cost of one run of the shipped flagship campaign (missions/campaign_pulsar_dispersions.yaml:
  the 300 s tile transfer, 15 DoF + 10 modes, NDI + observer, dispersed), in-process after a warm-up;
- a projection of a 10^4-run flagship campaign on 1, 16 and 256 cores from that cost (``--run-seconds``
  replaces it; ``--no-flagship`` uses the measured wall time of one probe run instead).

The setups take turns over ``--trials`` rounds and the best round of each is kept; the load average
is printed before and after, as cores shared with other work lower every figure.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor

import psutil

from sms_cli.campaign.execute import connect, execute
from sms_cli.campaign.probe import probe_run, probe_task

SHORT_SPIN_S = 0.01
SHORT_RUNS_PER_WORKER = 100
PROJECTED_RUNS = 10_000
PROJECTED_CORES = (1, 16, 256)


def tasks(count: int, seconds: float, first: int = 0):
    return [probe_task(first + i, seconds=seconds) for i in range(count)]


def dask_campaign(pool, count: int, seconds: float) -> tuple[float, list]:
    """Wall time of ``count`` probe runs through ``execute``, and their outcomes."""
    outcomes = []
    started = time.perf_counter()
    execute(pool, tasks(count, seconds), probe_run, timeout_s=60 + 10 * seconds, retries=0,
            on_outcome=outcomes.append, progress=False)
    wall = time.perf_counter() - started
    bad = [o for o in outcomes if o.status != "ok"]
    if bad:
        raise SystemExit(f"bench runs failed: {bad[:3]}")
    return wall, outcomes


def pool_campaign(executor, count: int, seconds: float) -> float:
    """Wall time of ``count`` probe runs through a process pool, collected as they complete."""
    started = time.perf_counter()
    futures = [executor.submit(probe_run, t) for t in tasks(count, seconds)]
    for future in futures:
        assert future.result().status == "ok"
    return time.perf_counter() - started


def flagship_run_cost(runs: int = 2) -> float:
    """Mean wall time (s) of ``runs`` runs of the shipped flagship campaign, in this process after one
    warm-up run (kernels loaded), with the gains synthesized once on the nominal mission."""
    import tempfile
    from pathlib import Path

    from sms_cli.campaign.runner import execute_run
    from sms_cli.campaign.stage import define, nominal_gains
    from sms_cli.mission.load import load_mission

    mission = Path(__file__).resolve().parents[1] / "missions" / "campaign_pulsar_dispersions.yaml"
    campaign = define(load_mission(mission))
    with tempfile.TemporaryDirectory() as folder:
        nominal_gains(campaign, Path(folder))
    tasks_ = campaign.tasks(list(range(runs + 1)))
    execute_run(tasks_[0])
    started = time.perf_counter()
    for t in tasks_[1:]:
        outcome = execute_run(t)
        if outcome.status != "ok":
            raise SystemExit(f"flagship run {t.run}: {outcome.status} {outcome.message}")
    return (time.perf_counter() - started) / runs


def rss_of_tree(pid: int) -> int:
    """Resident memory of a process and its descendants (bytes)."""
    proc = psutil.Process(pid)
    total = proc.memory_info().rss
    for child in proc.children(recursive=True):
        try:
            total += child.memory_info().rss
        except psutil.NoSuchProcess:
            continue
    return total


class DaskSetup:
    """A local Dask cluster of ``workers``, warmed up (every worker's sandbox child started)."""

    def __init__(self, workers: int):
        self.workers = workers
        started = time.perf_counter()
        self.pool = connect(None, workers)
        self.startup_s = time.perf_counter() - started
        dask_campaign(self.pool, 2 * workers, SHORT_SPIN_S)

    def throughput(self, runs: int, spin: float) -> dict:
        wall, outcomes = dask_campaign(self.pool, runs, spin)
        busy = sum(o.wall_s for o in outcomes) / (wall * self.workers)
        return {"rate": runs / wall, "wall_s": wall, "run_wall_s": wall * self.workers / runs, "busy": busy}

    def overhead(self) -> float:
        runs = SHORT_RUNS_PER_WORKER * self.workers
        wall, _ = dask_campaign(self.pool, runs, SHORT_SPIN_S)
        return wall * self.workers / runs - SHORT_SPIN_S

    def rss_per_worker(self) -> float:
        memory = [rss_of_tree(pid) for pid in self.pool.client.run(os.getpid).values()]
        return sum(memory) / len(memory)

    def close(self) -> None:
        self.pool.close()


class PoolSetup:
    """A plain spawn-context process pool of ``workers`` (no sandbox, no timeout), warmed up."""

    def __init__(self, workers: int):
        self.workers = workers
        self.executor = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))
        pool_campaign(self.executor, 4 * workers, SHORT_SPIN_S)

    def throughput(self, runs: int, spin: float) -> dict:
        wall = pool_campaign(self.executor, runs, spin)
        return {"rate": runs / wall, "wall_s": wall, "run_wall_s": wall * self.workers / runs}

    def overhead(self) -> float:
        runs = SHORT_RUNS_PER_WORKER * self.workers
        return pool_campaign(self.executor, runs, SHORT_SPIN_S) * self.workers / runs - SHORT_SPIN_S

    def close(self) -> None:
        self.executor.shutdown()


def best_of(setups: dict, trials: int, runs_per_worker: int, spin: float) -> tuple[dict, dict]:
    """The best throughput and the lowest overhead of each setup over ``trials`` rounds, the setups
    taking turns (so a burst of load elsewhere on the machine does not hit one setup only)."""
    best: dict = {}
    overhead: dict = {}
    for _ in range(trials):
        for name, setup in setups.items():
            row = setup.throughput(runs_per_worker * setup.workers, spin)
            if name not in best or row["rate"] > best[name]["rate"]:
                best[name] = row
            overhead[name] = min(overhead.get(name, float("inf")), setup.overhead())
    return best, overhead


def projection(run_cost: float, efficiency: float) -> list[tuple[int, float]]:
    """Wall time of PROJECTED_RUNS runs on n cores: ceil(runs / n) rounds of ``run_cost``, slowed
    by the measured efficiency beyond one core."""
    rows = []
    for cores in PROJECTED_CORES:
        rounds = math.ceil(PROJECTED_RUNS / cores)
        rows.append((cores, rounds * run_cost / (1.0 if cores == 1 else efficiency)))
    return rows


def clock(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 2 * 3600:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run-seconds", type=float, default=None,
                        help="per-run cost for the projection (default: the measured wall time of a probe run)")
    parser.add_argument("--spin", type=float, default=1.0, help="CPU seconds of each throughput run (default 1)")
    parser.add_argument("--runs-per-worker", type=int, default=4, help="throughput runs per worker (default 4)")
    parser.add_argument("--trials", type=int, default=3, help="rounds; the best of each is kept (default 3)")
    parser.add_argument("--no-flagship", action="store_true",
                        help="project from a probe run instead of measuring a flagship campaign run")
    args = parser.parse_args()
    if args.run_seconds is None and not args.no_flagship:
        print("measuring a run of missions/campaign_pulsar_dispersions.yaml (synthesis once, a warm-up run, 2 runs)...")
        args.flagship_s = flagship_run_cost()
        print(f"flagship campaign run: {args.flagship_s:.2f} s wall (300 s simulated: "
              f"{300 / args.flagship_s:.0f}x real time); memory of a process that ran it: "
              f"{psutil.Process().memory_info().rss / 2**20:.0f} MiB RSS (a worker's sandbox holds as much)\n")

    print(f"cores: {os.cpu_count()}   load average: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"throughput runs: {args.runs_per_worker} per worker of {args.spin:g} s CPU spin; overhead runs: "
          f"{SHORT_RUNS_PER_WORKER} per worker of {SHORT_SPIN_S:g} s; best of {args.trials} trials\n")
    setups = {("dask", 1): DaskSetup(1), ("dask", 2): DaskSetup(2), ("pool", 1): PoolSetup(1), ("pool", 2): PoolSetup(2)}
    try:
        best, overhead = best_of(setups, args.trials, args.runs_per_worker, args.spin)
        memory = {n: setups[("dask", n)].rss_per_worker() for n in (1, 2)}
    finally:
        for setup in setups.values():
            setup.close()
    report(args, setups, best, overhead, memory)
    print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


def report(args, setups, best, overhead, memory) -> None:
    print(f"{'':24}{'runs/s':>8}{'wall':>8}{'busy':>7}{'overhead/run':>14}")
    for (kind, n), row in best.items():
        label = f"{'dask local' if kind == 'dask' else 'process pool'} {n} worker{'s' if n > 1 else ''}"
        busy = f"{100 * row['busy']:5.0f}%" if "busy" in row else "     -"
        print(f"{label:24}{row['rate']:8.3f}{row['wall_s']:7.1f}s{busy:>7}{1000 * overhead[(kind, n)]:12.1f}ms")
    print("  busy: the share of the workers' time spent in runs (what the executor wastes is the rest)")
    dask_eff = best[("dask", 2)]["rate"] / (2 * best[("dask", 1)]["rate"])
    pool_eff = best[("pool", 2)]["rate"] / (2 * best[("pool", 1)]["rate"])
    ratio = best[("dask", 2)]["rate"] / best[("pool", 2)]["rate"]
    print(f"\nparallel efficiency 1 → 2 workers: dask {100 * dask_eff:.1f} %, pool {100 * pool_eff:.1f} % "
          f"(target >= 90 %)")
    verdict = "within 10 %: Dask serves both" if ratio >= 0.9 else "NOT within 10 % of the pool"
    print(f"throughput dask / pool, 2 workers: {ratio:.3f} ({verdict})")
    print(f"dask overhead per run beyond the pool's: {1000 * (overhead[('dask', 2)] - overhead[('pool', 2)]):.1f} ms "
          f"(2 workers)")
    print(f"local cluster start-up: {setups[('dask', 1)].startup_s:.1f} s (1 worker), "
          f"{setups[('dask', 2)].startup_s:.1f} s (2 workers)")
    print(f"memory per dask worker (worker + sandbox RSS): {memory[1] / 2**20:.0f} MiB (1 worker), "
          f"{memory[2] / 2**20:.0f} MiB (2 workers)")

    efficiency = min(dask_eff, 1.0)
    if args.run_seconds is not None or getattr(args, "flagship_s", None) is not None:
        given = args.run_seconds if args.run_seconds is not None else args.flagship_s
        what = "--run-seconds" if args.run_seconds is not None else "measured flagship campaign run"
        run_cost, source = given + max(overhead[("dask", 2)], 0.0), f"{what} + dask overhead"
    else:
        run_cost, source = best[("dask", 1)]["run_wall_s"], f"measured wall of a {args.spin:g} s probe run, 1 worker"
    print(f"\nprojection of a {PROJECTED_RUNS}-run campaign at {run_cost:.3f} s per run ({source}), "
          f"efficiency {100 * efficiency:.0f} % beyond one core:")
    for cores, seconds in projection(run_cost, efficiency):
        print(f"  {cores:>4} cores: {clock(seconds)}")


if __name__ == "__main__":
    main()
