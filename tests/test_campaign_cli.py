"""sms campaign through the CLI, on real runs of Basilisk's reference detumble (0.1 s each).

Behaviour held here: the same entropy gives the same per-run results on 1 and 2 local workers
and on a separate Dask cluster; Ctrl-C then --resume runs only what is missing; a rerun replays a
run to the last bit with its recording; bad input exits 2 and writes nothing; earlier results are
never deleted.
"""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from conftest import EXCEPTION_TEXT

ROOT = Path(__file__).resolve().parents[1]
SMS = str(ROOT / ".venv" / "bin" / "sms") if (ROOT / ".venv" / "bin" / "sms").exists() else "sms"
SMALL = ROOT / "tests" / "data" / "campaign" / "basilisk_small.yaml"
LIMIT_S = 240


def sms(*args, timeout: float = LIMIT_S, **kw) -> subprocess.CompletedProcess:
    env = {**os.environ, "COLUMNS": "200"}
    return subprocess.run([SMS, *map(str, args)], capture_output=True, text=True, timeout=timeout, env=env, **kw)


def table(folder: Path) -> pa.Table:
    parts = sorted((folder / "metrics").glob("part-*.parquet"))
    return pa.concat_tables([pq.read_table(p) for p in parts], promote_options="default").sort_by("run")


def manifest(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "manifest.jsonl").read_text().splitlines()]


def same_runs(a: pa.Table, b: pa.Table) -> None:
    assert a.column("run").to_pylist() == b.column("run").to_pylist()
    cols = [c for c in a.column_names if c.startswith(("param.", "metric.", "req."))]
    assert sorted(cols) == sorted(c for c in b.column_names if c.startswith(("param.", "metric.", "req.")))
    for c in cols:
        x, y = a.column(c).to_pylist(), b.column(c).to_pylist()
        same = [u == v or (isinstance(u, float) and math.isnan(u) and math.isnan(v)) for u, v in zip(x, y)]
        assert all(same), c


def assert_clean(text: str) -> None:
    assert not EXCEPTION_TEXT.search(text), text


def wilson_low(k: int, n: int, z: float = 1.959963984540054) -> float:
    """Wilson (1927) score interval, lower bound, written out (independent of scipy's)."""
    p = k / n
    return (p + z * z / (2 * n) - z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))) / (1 + z * z / n)


@pytest.fixture(scope="module")
def two_workers(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("campaign") / "two"
    r = sms("campaign", SMALL, "-o", out, "--workers", 2, "--no-progress")
    assert r.returncode in (0, 1), r.stderr
    return out


@pytest.mark.slow
def test_every_run_finishes_once_and_the_exit_code_follows_the_wilson_bound(two_workers):
    m = manifest(two_workers)
    assert sorted(x["run"] for x in m if x["status"] == "ok") == list(range(8))
    t = table(two_workers)
    final = np.array(t.column("metric.simulate.overall.attitude_error_deg.final").to_pylist(), float)
    k = int(np.sum(final <= 1.0))
    results = json.loads((two_workers / "results.json").read_text())
    verdict = results["campaign"]["requirements"][0]
    assert verdict["value"] == pytest.approx(wilson_low(k, 8), abs=1e-9)
    r = sms("check", two_workers)
    assert r.returncode == (0 if wilson_low(k, 8) >= 0.5 else 1), r.stdout
    assert {p.name for p in (two_workers / "plots").iterdir()}, "no campaign plots"


@pytest.mark.slow
def test_same_entropy_same_results_on_one_and_two_workers(two_workers, tmp_path):
    one = tmp_path / "one"
    r = sms("campaign", SMALL, "-o", one, "--workers", 1, "--no-progress")
    assert r.returncode in (0, 1), r.stderr
    same_runs(table(one), table(two_workers))


@pytest.mark.slow
def test_rerun_replays_a_run_to_the_last_bit_with_its_recording(two_workers):
    r = sms("campaign", "rerun", two_workers, "--run", 3)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "to the last bit" in r.stdout
    assert (two_workers / "runs" / "3" / "simulation.mcap").stat().st_size > 0


@pytest.mark.slow
def test_ctrl_c_then_resume_runs_only_the_missing_runs(tmp_path):
    longer = tmp_path / "longer.yaml"
    longer.write_text(f"extends: {SMALL}\ncampaign:\n  runs: 40\n")
    out = tmp_path / "out"
    env = {**os.environ}
    p = subprocess.Popen([SMS, "campaign", str(longer), "-o", str(out), "--workers", "1", "--no-progress"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.monotonic() + LIMIT_S
    try:
        while time.monotonic() < deadline and p.poll() is None:
            f = out / "manifest.jsonl"
            if f.exists() and len(f.read_text().splitlines()) >= 3:
                break
            time.sleep(0.05)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 130, err
    before = {x["run"] for x in manifest(out) if x["status"] == "ok"}
    assert 3 <= len(before) < 40
    r = sms("campaign", longer, "-o", out, "--resume", "--workers", 2, "--no-progress")
    assert r.returncode in (0, 1), r.stderr
    assert f"resuming: {len(before)} of 40 runs finished" in r.stderr
    runs = [x["run"] for x in manifest(out) if x["status"] == "ok"]
    assert sorted(runs) == list(range(40))  # each exactly once: the finished ones were not run again
    assert table(out).num_rows == 40


@pytest.mark.slow
def test_a_folder_with_results_needs_resume_or_restart_and_nothing_is_deleted(two_workers, tmp_path):
    before = (two_workers / "manifest.jsonl").read_bytes()
    r = sms("campaign", SMALL, "-o", two_workers, "--no-progress")
    assert r.returncode == 2 and "--resume" in r.stderr
    assert_clean(r.stderr)
    assert (two_workers / "manifest.jsonl").read_bytes() == before
    copy = tmp_path / "copy"
    subprocess.run(["cp", "-r", str(two_workers), str(copy)], check=True)
    r = sms("campaign", SMALL, "-o", copy, "--restart", "--workers", 2, "--no-progress")
    assert r.returncode in (0, 1), r.stderr
    kept = list((copy / "previous").glob("*/manifest.jsonl"))
    assert len(kept) == 1 and kept[0].read_bytes() == before


def test_resuming_another_campaign_is_refused(two_workers, tmp_path):
    other = tmp_path / "other.yaml"
    other.write_text(f"extends: {SMALL}\ncampaign:\n  entropy: 5\n")
    r = sms("campaign", other, "-o", two_workers, "--resume", "--no-progress")
    assert r.returncode == 2 and "another campaign" in r.stderr
    assert_clean(r.stderr)


def _closed_port() -> int:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def test_an_unreachable_scheduler_exits_2_and_writes_nothing(tmp_path):
    out = tmp_path / "never"
    t0 = time.monotonic()
    r = sms("campaign", SMALL, "-o", out, "--scheduler", f"tcp://127.0.0.1:{_closed_port()}", timeout=60)
    assert r.returncode == 2 and "cannot reach the Dask scheduler" in r.stderr
    assert_clean(r.stderr)
    assert not out.exists()
    assert time.monotonic() - t0 < 30


@pytest.mark.parametrize("dispersion, words", [
    ("{name: K, path: simulation.atitude.K, distribution: uniform, low: 0, high: 1}", "did you mean simulation.attitude"),
    ("{name: K, path: simulation.attitude.K, distribution: normal, std: -10 %}", "std must be positive"),
], ids=["path that does not exist", "distribution parameter out of range"])
def test_bad_campaign_input_exits_2_at_its_line_and_writes_nothing(tmp_path, dispersion, words):
    bad = tmp_path / "bad.yaml"
    bad.write_text(f"extends: {SMALL}\ncampaign:\n  dispersions:\n    - {dispersion}\n")
    out = tmp_path / "out"
    r = sms("campaign", bad, "-o", out)
    assert r.returncode == 2
    assert f"{bad}:4" in r.stderr and words in r.stderr
    assert_clean(r.stderr)
    assert not out.exists()


# ------------------------------------------------------------------ a real Dask cluster
@pytest.fixture
def dask_cluster(tmp_path):
    """A `dask scheduler` and two `dask worker` processes on 127.0.0.1, stopped at the end."""
    dask = str(Path(sys.executable).parent / "dask")
    sched_file = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(sched_file)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + 60
        while not sched_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(sched_file.read_text())["address"]
        for _ in range(2):
            procs.append(subprocess.Popen([dask, "worker", address, "--nthreads", "1", "--no-dashboard",
                                           "--host", "127.0.0.1"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        yield address
    finally:
        for p in procs[::-1]:
            p.terminate()
        for p in procs[::-1]:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.mark.slow
def test_a_campaign_on_a_dask_cluster_gives_the_local_results(dask_cluster, two_workers, tmp_path):
    out = tmp_path / "dask"
    r = sms("campaign", SMALL, "-o", out, "--scheduler", dask_cluster, "--no-progress")
    assert r.returncode in (0, 1), r.stderr
    same_runs(table(out), table(two_workers))
    workers = {x["worker"] for x in manifest(out)}
    assert len(workers) >= 1
