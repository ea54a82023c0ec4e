"""The first `sms simulate` after an install: the kernel compilation pause, cold against warm.

For each mission, `sms simulate` runs as a fresh process twice with an empty numba cache
(NUMBA_CACHE_DIR pointing at a new temporary folder, so the install's own cache is not touched):
the first run compiles the kernels the mission needs (``sms_cli.sim.compiled.warmup``: in
parallel lanes, the pause printed on stderr), the second loads them. Printed per mission: the
whole command, cold and warm, the pause the warm-up reports ("kernels ready in ... s"), and the
CPU time of the cold run's process and its worker lanes. Missions that read synthesized gains
(the flagship's NDI law) get them from `sms synthesize` first, not timed.

Default missions: basilisk_rw_reference (the compiled loop) and pulsar_simple (the flagship: the
Python loop with the compiled plant, joint stops and recording). Target (issue #19): pause ≤ 10 s.

Usage: python benches/bench_cold_start.py [mission.yaml ...]
"""

from __future__ import annotations

import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SMS = [sys.executable, "-m", "sms_cli"]
DEFAULT = ["missions/basilisk_rw_reference.yaml", "missions/pulsar_simple.yaml"]


def timed(cmd: list[str], env: dict) -> tuple[float, float, str]:
    """(wall s, CPU s of the process and its children, stderr) of one command."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode not in (0, 1):  # 1: a requirement failed, the run itself completed
        raise SystemExit(f"{' '.join(cmd)} exited {out.returncode}:\n{out.stderr[-3000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, out.stderr


def pause(stderr: str) -> float:
    m = re.search(r"kernels ready in ([0-9.]+) s", stderr)
    return float(m.group(1)) if m else 0.0


def main() -> None:
    missions = sys.argv[1:] or DEFAULT
    print(f"{'mission':<26}{'cold [s]':>10}{'warm [s]':>10}{'pause [s]':>11}{'cold CPU [s]':>14}{'lanes':>7}")
    for m in missions:
        with tempfile.TemporaryDirectory(prefix="sms_cold_") as tmp:
            env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(tmp) / "numba"))
            out = Path(tmp) / "out"
            subprocess.run(SMS + ["synthesize", m, "-o", str(out), "--no-plots"], cwd=ROOT, env=env, capture_output=True)
            cmd = SMS + ["simulate", m, "-o", str(out), "--no-progress"]
            cold, cpu, err = timed(cmd, env)
            lanes = re.search(r"on (\d+) cores?", err)
            warm, _, _ = timed(cmd, env)
            print(f"{Path(m).stem:<26}{cold:>10.1f}{warm:>10.1f}{pause(err):>11.1f}{cpu:>14.1f}"
                  f"{lanes.group(1) if lanes else '-':>7}")
    print("pause: the warm-up's own figure (compilation of the kernels the mission needs); target ≤ 10 s")


if __name__ == "__main__":
    main()
